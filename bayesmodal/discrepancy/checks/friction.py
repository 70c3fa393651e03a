"""Dry-friction signature: the force residual steps with the sign of the velocity.

If the rig obeys ``M x'' + C x' + K x = b v + f`` with an unmodelled force ``f``, the
residual ``r = y - yhat`` of the linear model with the same ``M, C, K`` satisfies

    M r'' + C r' + K r = f,

so the *force residual* ``f = M r'' + C r' + K r`` (derivatives by Savitzky-Golay
smoothing) recovers the missing force on each cart.  Coulomb friction is
``f_i = -Fc_i sign(x_i')``; the least-squares fit of the linear model absorbs part of it
into viscous damping, so ``f_i`` is regressed on ``[1, sign(v_i), v_i]`` (all smoothed by the
same filter) together with the cart's measured acceleration and, for driven carts, the
input (which take up the errors of the fitted mass, damping and gain); the least-squares
coefficient of ``sign(v_i)`` estimates ``-Fc_i`` (N); while a cart sticks friction holds
the net force instead, which biases the estimate somewhat low.  The standard error allows
for autocorrelated errors (Newey-West with the Andrews bandwidth, at least twice the
window).  The test is one-sided (friction opposes motion), Bonferroni over carts.

The ratio of the mean absolute residual within a few samples of a velocity reversal to its
overall mean is given per cart as well: friction and stick concentrate misfit there.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ..._errors import ConfigError
from ...model.effects import suggested_by
from ._result import Diagnostic
from ._stats import bonferroni, regress_hac
from .residuals import LinearResiduals, derivative_noise_gain, noise_level, smooth_derivative

__all__ = ["friction_signature", "force_residual"]


def force_residual(res: LinearResiduals, window: int) -> np.ndarray:
    """``M r'' + C r' + K r`` with Savitzky-Golay derivatives, N, shape (N, n)."""
    M, C, K, _ = res.matrices()
    dt = res.dt
    r0 = smooth_derivative(res.residual, dt, window, deriv=0)
    r1 = smooth_derivative(res.residual, dt, window, deriv=1)
    r2 = smooth_derivative(res.residual, dt, window, deriv=2)
    return r2 @ M.T + r1 @ C.T + r0 @ K.T


def _odd(k: int) -> int:
    return k if k % 2 else k + 1


def friction_signature(
    res: LinearResiduals,
    *,
    window: int | None = None,
    velocity: str = "measured",
    alpha: float = 0.01,
    min_force_n: float = 0.02,
    n_bins: int = 41,
) -> Diagnostic:
    """Estimate and test a Coulomb force ``-Fc_i sign(v_i)`` on every cart.

    Parameters
    ----------
    res : LinearResiduals
    window : int, optional
        Savitzky-Golay window for the force residual, samples (default about 0.05 s: a
        longer one smears the friction steps).
    velocity : {"measured", "predicted"}
        Velocity whose sign is the regressor: the smoothed derivative of the measurement
        (default; zero while a cart sticks, when its sign is undefined by a dead band of
        three noise standard deviations) or the noise-free linear prediction.
    alpha : float
        Family-wise significance level.
    min_force_n : float
        Smallest friction level reported as detected, N (effect-size guard).
    n_bins : int
        Velocity bins of the force-velocity curve kept for plotting.

    Returns
    -------
    Diagnostic
        ``statistic``: the largest one-sided t statistic ``-coef / stderr`` over carts;
        ``p_value``: Bonferroni.  Detail: ``fc_n`` (n,) estimated Coulomb levels, N;
        ``fc_stderr_n`` (n,); ``viscous_n_s_m`` (n,) the extra viscous coefficient;
        ``p_values``; ``reversal_ratio`` (n,); ``v_bins`` and ``f_bins`` (n, n_bins) the
        binned force residual against velocity; ``velocity_deadband`` (n,), m/s.
    """
    if velocity not in ("predicted", "measured"):
        raise ConfigError(f"velocity must be 'measured' or 'predicted', got {velocity!r}")
    dt = res.dt
    w = _odd(window if window is not None else max(res.smooth_window, int(round(0.05 / dt))))
    f = force_residual(res, w)
    v = res.v_pred if velocity == "predicted" else res.v_meas
    sigma = noise_level(res.residual, res.quantum_m)
    deadband = 3.0 * sigma * derivative_noise_gain(w, dt, deriv=1)
    s = np.sign(v) * (np.abs(v) > deadband)
    s_sm = smooth_derivative(s, dt, w, deriv=0)
    # the parameter errors of the fit act through the *true* motion: use the measured one
    v_sm = smooth_derivative(res.y, dt, w, deriv=1)
    a_sm = smooth_derivative(res.y, dt, w, deriv=2)
    u_sm = smooth_derivative(res.u, dt, w, deriv=0)
    drive = res.matrices()[3]
    n = res.n_outputs
    fc = np.empty(n)
    se = np.empty(n)
    visc = np.empty(n)
    tstat = np.empty(n)
    p = np.empty(n)
    ratio = np.empty(n)
    v_bins = np.full((n, n_bins), np.nan)
    f_bins = np.full((n, n_bins), np.nan)
    for i in range(n):
        cols = [np.ones_like(v_sm[:, i]), s_sm[:, i], v_sm[:, i], a_sm[:, i]]
        if drive[i] != 0:
            cols.append(u_sm)
        X = np.column_stack(cols)
        reg = regress_hac(f[:, i], X, min_lags=2 * w)
        fc[i], se[i], visc[i] = -reg.coef[1], reg.stderr[1], reg.coef[2]
        tstat[i] = -reg.t[1]
        p[i] = stats.norm.sf(tstat[i])
        rev = np.flatnonzero(np.diff(s[:, i]) != 0)
        near = np.zeros(v.shape[0], bool)
        for k in rev:
            near[max(k - w // 2, 0) : k + w // 2 + 1] = True
        a = np.abs(res.residual[:, i])
        ratio[i] = a[near].mean() / a.mean() if near.any() and a.mean() > 0 else np.nan
        edges = np.quantile(v[:, i], np.linspace(0, 1, n_bins + 1))
        idx = np.clip(np.searchsorted(edges, v[:, i], side="right") - 1, 0, n_bins - 1)
        for b in range(n_bins):
            sel = idx == b
            if sel.any():
                v_bins[i, b] = v[sel, i].mean()
                f_bins[i, b] = f[sel, i].mean()
    p_fw = bonferroni(p)
    j = int(np.argmax(tstat))
    detected = bool(p_fw < alpha and fc[j] > min_force_n)
    levels = ", ".join(f"{x:.3f}" for x in fc)
    summary = (
        f"Coulomb-like force residual {'found' if detected else 'not found'}: "
        f"Fc = [{levels}] N (cart {j + 1}: t = {tstat[j]:.1f}), p = {p_fw:.2g}"
    )
    return Diagnostic(
        name="friction_signature",
        statistic=float(tstat[j]),
        p_value=p_fw,
        threshold=None,
        detected=detected,
        suggests=suggested_by("friction") if detected else (),
        location=f"cart {j + 1}" if detected else None,
        summary=summary,
        detail={"fc_n": fc, "fc_stderr_n": se, "viscous_n_s_m": visc, "t": tstat,
                "p_values": p, "reversal_ratio": ratio, "v_bins": v_bins, "f_bins": f_bins,
                "velocity_deadband": deadband, "window": w, "velocity": velocity,
                "alpha": alpha},
    )
