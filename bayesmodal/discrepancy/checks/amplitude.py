"""Natural frequency and damping against amplitude in sliding windows.

A linear model has amplitude-independent modes.  Hardening (softening) springs raise
(lower) the frequency of large oscillations, about ``omega(A) = omega_0 (1 + kappa A^2)``
for a cubic term; dry friction makes the equivalent damping grow as the amplitude shrinks,
``zeta_eq ~ 2 Fc / (pi k A)``.

On every stretch of constant input the measured motion about the model's equilibrium is
projected on the mass-normalised mode shapes of the fitted model (``q = Phi^T M x``).  In
consecutive windows of a few periods, each modal coordinate is fitted by linear least
squares with the model's damped modes, ``e^{-sigma_k t} (a_k cos w_k t + b_k sin w_k t)``
for every mode ``k`` (which removes the leakage of the others) plus, for the mode ``m``
under study, the first-order terms ``t e^{-sigma_m t} (c cos w_m t + d sin w_m t)``.  With
``t`` centred in the window these give the local shifts of frequency and decay rate,
``c = b dw - a ds`` and ``d = -a dw - b ds``, without any filter transient.  Per mode,
the window frequencies are regressed on the squared amplitude by weighted least squares
(weights from each window's own standard errors, so that windows near the noise floor
count little): a significant slope
(two-sided, Bonferroni over modes) with a relative frequency change above
``min_relative_change`` over the observed amplitudes is reported as amplitude-dependent
stiffness.  The damping ratio is regressed on ``1/A``: damping that grows strongly
towards small amplitude is the mark of dry friction, which also bends the frequency near
stick; then friction is suggested and frequency trends are not attributed to the springs.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg, stats

from ...model.effects import suggested_by
from ._result import Diagnostic
from ._stats import bonferroni
from .residuals import LinearResiduals, constant_input_segments, noise_level

__all__ = ["amplitude_dependence"]


def _wls_slope(x: np.ndarray, y: np.ndarray, var: np.ndarray) -> tuple[float, float, float]:
    """Intercept, slope and slope standard error of ``y = c + s x`` by weighted least squares.

    Weights ``1 / var``; the standard error is inflated by the reduced chi-square when the
    scatter exceeds the stated variances (never deflated).
    """
    w = 1.0 / np.maximum(var, 1e-300)
    mx = np.sum(w * x) / np.sum(w)
    sx = np.sqrt(np.sum(w * (x - mx) ** 2) / np.sum(w))
    if sx == 0:
        return float(np.sum(w * y) / np.sum(w)), 0.0, np.inf
    z = (x - mx) / sx
    X = np.column_stack([np.ones_like(z), z]) * np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(X, y * np.sqrt(w), rcond=None)
    e = y * np.sqrt(w) - X @ coef
    dof = max(x.size - 2, 1)
    cov = np.linalg.pinv(X.T @ X) * max(1.0, (e @ e) / dof)
    slope = coef[1] / sx
    return float(coef[0] - slope * mx), float(slope), float(np.sqrt(cov[1, 1]) / sx)


def _damping_growth(e: dict) -> str:
    """Words for the damping change of one mode: a factor, with the two end values."""
    z_big, z_small = e["zeta_large_amplitude"], e["zeta_small_amplitude"]
    amps = np.asarray(e["amplitude_m"])
    ends = (f"from zeta {z_big:.3g} at {1e3 * amps.max():.2g} mm to {z_small:.3g} at "
            f"{1e3 * amps.min():.2g} mm amplitude")
    if z_big > 0 and np.isfinite(z_small):
        return f"x{z_small / z_big:.2g}, {ends}"
    return ends


def _window_basis(wd: np.ndarray, sd: np.ndarray, m: int, win: int, dt: float) -> np.ndarray:
    """Design matrix of a window for mode ``m`` (module docstring), shape (win, 2 n + 3).

    A constant, ``e^{-sd_k t} cos(wd_k t)`` and ``sin`` for every damped mode ``k``
    (``wd``, ``sd``: rad/s and 1/s, shape (n,)), and mode ``m``'s first-order terms ``t``
    times its own; ``t`` (s, step ``dt``) centred in the window of ``win`` samples.
    """
    tw = (np.arange(win) - (win - 1) / 2) * dt
    basis = [np.ones(win)]
    for k in range(wd.size):
        env = np.exp(-sd[k] * tw)
        basis += [env * np.cos(wd[k] * tw), env * np.sin(wd[k] * tw)]
    env = np.exp(-sd[m] * tw)
    basis += [tw * env * np.cos(wd[m] * tw), tw * env * np.sin(wd[m] * tw)]
    return np.column_stack(basis)


def _mode_windows(Q, m, segs, X, wd_m, sd_m, floor, max_shift, min_r2, peak):
    """Local frequency and damping of mode ``m`` in consecutive windows of the stretches
    ``segs`` of its modal coordinate ``Q[:, m]``, fitted with the design ``X``
    (:func:`_window_basis`) around the model's ``wd_m`` (rad/s) and ``sd_m`` (1/s).

    Windows whose modal amplitude is below ``floor``, whose relative frequency shift
    exceeds ``max_shift`` or whose fit explains less than ``min_r2`` are dropped.  Returns
    arrays over the windows kept: amplitude (the modal one times ``peak``, the mode shape's
    largest entry: m), frequency (rad/s), damping ratio, and the variances of the
    frequency and of the damping ratio.
    """
    win = X.shape[0]
    pinv = np.linalg.pinv(X)
    XtX_inv = np.linalg.pinv(X.T @ X)
    ia, ib = 1 + 2 * m, 2 + 2 * m
    amps, om, ze, var_w, var_z = [], [], [], [], []
    for a0, b0 in segs:
        for s0 in range(a0, b0 - win + 1, win):
            qw = Q[s0 : s0 + win, m]
            coef = pinv @ qw
            a, bb = coef[ia], coef[ib]
            c, d = coef[-2], coef[-1]
            amp2 = a * a + bb * bb
            if amp2 < floor ** 2:
                continue
            dw = (bb * c - a * d) / amp2
            ds = -(a * c + bb * d) / amp2
            # keep windows that look like the mode: first-order shifts small and the
            # local model explaining the window
            resid = qw - X @ coef
            r2 = 1.0 - (resid @ resid) / max(np.sum((qw - qw.mean()) ** 2), 1e-300)
            if abs(dw) > max_shift * wd_m or r2 < min_r2:
                continue
            # standard errors of the shifts from the local fit (c and d carry them)
            s2 = (resid @ resid) / max(win - X.shape[1], 1)
            vc, vd, cd = s2 * XtX_inv[-2, -2], s2 * XtX_inv[-1, -1], s2 * XtX_inv[-2, -1]
            var_w.append((bb * bb * vc + a * a * vd - 2 * a * bb * cd) / amp2**2)
            var_s = (a * a * vc + bb * bb * vd + 2 * a * bb * cd) / amp2**2
            om.append(wd_m + dw)
            ze.append((sd_m + ds) / np.hypot(wd_m + dw, sd_m + ds))
            var_z.append(var_s / (wd_m + dw) ** 2)
            amps.append(np.sqrt(amp2) * peak)
    return (np.array(amps), np.array(om), np.array(ze), np.array(var_w), np.array(var_z))


def _mode_trends(m, wd_m, amps, om, ze, var_w, var_z, min_windows) -> dict:
    """The entry of mode ``m`` in ``detail["modes"]`` (:func:`amplitude_dependence`): its
    windows (:func:`_mode_windows`) and, with at least ``min_windows`` of different
    amplitudes, the regressions of frequency on the squared amplitude and of damping on
    its inverse."""
    entry = {"mode": m + 1, "omega_model": float(wd_m), "amplitude_m": amps,
             "omega": om, "zeta": ze, "slope": np.nan, "t": 0.0, "p": np.nan,
             "relative_change": 0.0, "damping_slope": np.nan, "damping_t": 0.0,
             "damping_p": np.nan, "damping_relative_change": 0.0,
             "zeta_large_amplitude": np.nan, "zeta_small_amplitude": np.nan}
    if amps.size >= min_windows and np.ptp(amps) > 0:
        c0, s, se = _wls_slope(amps**2, om, var_w)
        entry["slope"] = s
        entry["t"] = s / se if se > 0 else 0.0
        entry["p"] = float(2 * stats.t.sf(abs(entry["t"]), amps.size - 2))
        entry["relative_change"] = float(s * (amps.max() ** 2 - amps.min() ** 2) / c0)
        dz0, ds_, dse = _wls_slope(1.0 / amps, ze, var_z)
        entry["damping_slope"] = ds_
        # fitted damping ratio at the largest and the smallest amplitude
        entry["zeta_large_amplitude"] = float(dz0 + ds_ / amps.max())
        entry["zeta_small_amplitude"] = float(dz0 + ds_ / amps.min())
        entry["damping_t"] = ds_ / dse if dse > 0 else 0.0
        entry["damping_p"] = float(2 * stats.t.sf(abs(entry["damping_t"]), amps.size - 2))
        zeta_ref = np.sum(ze / var_z) / np.sum(1 / var_z)
        entry["damping_relative_change"] = float(
            ds_ * (1 / amps.min() - 1 / amps.max()) / max(abs(zeta_ref), 1e-12))
    return entry


def _summary(best, f, p_fw, p_damp, stiff, alpha) -> str:
    """The diagnostic's summary: the frequency trend of mode ``best`` and, when the mode
    ``f`` (or None) shows dry friction, its damping growth."""
    kind = "hardening" if best["slope"] > 0 else "softening"
    summary = (
        f"mode {best['mode']} frequency changes by {100 * best['relative_change']:+.2f} % over "
        f"its amplitude range (t = {best['t']:.1f}, p = {p_fw:.2g}"
        + (f": {kind} stiffness)" if stiff else
           f", {'significant' if p_fw < alpha else 'not significant'})")
    )
    if f is not None:
        summary += (f"; mode {f['mode']} damping grows towards small amplitude "
                    + _damping_growth(f)
                    + f" (p = {p_damp:.2g}): dry friction")
    return summary


def amplitude_dependence(
    res: LinearResiduals,
    *,
    periods_per_window: float = 2.0,
    min_duration_s: float = 1.0,
    min_windows: int = 6,
    snr: float = 20.0,
    min_r2: float = 0.95,
    max_shift: float = 0.1,
    alpha: float = 0.01,
    min_relative_change: float = 0.003,
    max_damping_change: float = 0.5,
) -> Diagnostic:
    """Does the frequency of each mode change with its amplitude?

    Parameters
    ----------
    res : LinearResiduals
    periods_per_window : float
        Window length in periods of the mode.
    min_duration_s : float
        Shortest stretch of constant input analysed, s.
    min_windows : int
        Fewest windows needed to test a mode.
    snr : float
        Windows whose modal amplitude is below ``snr`` times the modal noise level are
        dropped.
    min_r2 : float
        Windows whose local modal fit explains less of the variance are dropped (a stuck
        or non-oscillating stretch).
    max_shift : float
        Windows whose estimated relative frequency shift exceeds this are dropped (the
        first-order expansion no longer holds).
    alpha : float
        Family-wise significance level.
    min_relative_change : float
        Smallest relative frequency change over the observed amplitude range reported as
        detected (effect-size guard).
    max_damping_change : float
        A mode whose damping ratio grows by more than this fraction from its largest to its
        smallest amplitude (significantly) is taken as dry friction: it suggests
        ``coulomb_friction``, and frequency trends are then not attributed to the springs
        (stick bends the frequencies near rest; a cubic spring hidden behind strong
        friction is left to a model comparison).

    Returns
    -------
    Diagnostic
        ``statistic``: the largest ``|t|`` of a frequency-amplitude slope; ``p_value``:
        Bonferroni over the tested modes.  Detail: ``modes`` (list of dict per mode with
        ``omega_model`` rad/s, ``amplitude_m`` (windows,) peak cart displacement, ``omega``
        rad/s, ``zeta``, ``slope`` (rad/s per m^2), ``t``, ``p``, ``relative_change``,
        ``damping_slope`` (zeta per 1/m), ``damping_t``, ``damping_p``,
        ``zeta_large_amplitude`` and ``zeta_small_amplitude`` (fitted damping ratio at the
        largest and smallest amplitude)).  ``p_value`` is that of the test that decided:
        the damping slope when only dry friction is detected, else the frequency slope.
        Suggests ``cubic_stiffness``;
        damping rising at small amplitude adds ``coulomb_friction`` to the detail only.
    """
    dt = res.dt
    M, C, K, b = res.matrices()
    w2, Phi = linalg.eigh(K, M)
    omega = np.sqrt(w2)
    n = omega.size
    proj = Phi.T @ M  # modal coordinate q = proj @ x
    # damped modes of the fitted model, matched to the undamped ones by frequency
    A_ss, _ = res.model.state_space(res.theta)
    lam = np.linalg.eigvals(A_ss)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(lam.imag)]
    wd = lam.imag if lam.size == n else omega
    sd = -lam.real if lam.size == n else np.zeros(n)
    sigma = noise_level(res.residual, res.quantum_m)
    segs = constant_input_segments(res.u, int(min_duration_s / dt))
    # motion about the equilibrium of the input held at each sample
    x_rel = res.y - np.linalg.solve(K, b)[None, :] * res.u[:, None]
    Q = x_rel @ proj.T
    modes = []
    for m in range(n):
        q_noise = np.sqrt(np.sum(proj[m] ** 2 * sigma**2))
        win = max(int(round(periods_per_window * 2 * np.pi / wd[m] / dt)), 8)
        X = _window_basis(wd, sd, m, win, dt)
        windows = _mode_windows(Q, m, segs, X, wd[m], sd[m], snr * q_noise, max_shift,
                                min_r2, np.max(np.abs(Phi[:, m])))
        modes.append(_mode_trends(m, wd[m], *windows, min_windows))
    tested = [e for e in modes if np.isfinite(e["p"])]
    if not tested:
        return Diagnostic(
            name="amplitude_dependence", statistic=0.0, p_value=None, threshold=None,
            detected=False, suggests=(), location=None,
            summary="too few free-oscillation windows to relate frequency and amplitude",
            detail={"modes": modes},
        )
    n_t = len(tested)
    # dry friction raises the equivalent damping at small amplitude and distorts the
    # frequency there too; a mode whose damping changes that much says "friction", and its
    # frequency trend is not evidence of a nonlinear spring
    friction_modes = [
        e for e in tested
        if e["damping_relative_change"] > max_damping_change and e["damping_p"] * n_t < alpha
    ]
    p_fw = bonferroni(np.array([e["p"] for e in tested]))
    best = max(tested, key=lambda e: abs(e["t"]))
    # stick also bends the frequencies of all modes near rest: with friction in sight a
    # frequency trend is not attributed to the springs
    stiff = bool(not friction_modes and p_fw < alpha
                 and abs(best["relative_change"]) > min_relative_change)
    detected = stiff or bool(friction_modes)
    # the p-value reported is that of the test that decided: the frequency slope when a
    # stiffness change is reported (or nothing is), the damping slope when dry friction is
    p_damp = (min(1.0, min(e["damping_p"] for e in friction_modes) * n_t)
              if friction_modes else None)
    p_report = p_damp if (friction_modes and not stiff) else p_fw
    suggests = (suggested_by("amplitude_frequency") if stiff else ()) + (
        suggested_by("amplitude_damping") if friction_modes else ())
    f = max(friction_modes, key=lambda e: e["damping_relative_change"]) if friction_modes \
        else None
    summary = _summary(best, f, p_fw, p_damp, stiff, alpha)
    location = f"mode {best['mode']}" if stiff else (
        f"mode {f['mode']}" if f is not None else None)
    return Diagnostic(
        name="amplitude_dependence",
        statistic=float(abs(best["t"])),
        p_value=p_report,
        threshold=None,
        detected=detected,
        suggests=suggests,
        location=location,
        summary=summary,
        detail={"modes": modes, "alpha": alpha},
    )
