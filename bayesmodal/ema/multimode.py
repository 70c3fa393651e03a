"""Multi-mode fit in the frequency domain with residual mass and flexibility (lecture 11c).

In a band ``[w_min, w_max]`` holding modes ``m1 .. m2`` the FRF is approximated by

    H(w) ~ a_1 f_1(w) + sum_k [(a_k3 + j a_k4) f_k2(w) + (a_k3 - j a_k4) f_k3(w)] + a_0 f_0(w)

with ``f_k2 = 1 / (j w - lambda_k)``, ``f_k3 = 1 / (j w - conj(lambda_k))``, and real
``a_0`` (residual flexibility ``s*``, the modes above the band) and ``a_1`` (residual mass
``1 / m*``, the modes below).  For a receptance (displacement per force)
``f_1 = 1 / (j w)^2 = -1 / w^2`` and ``f_0 = 1``; for a response differentiated ``p`` times
both are multiplied by ``(j w)^p``.  The model is linear in the ``a``'s and nonlinear in
``mu_k``, ``nu_k``.  Algorithm (lecture, part 1/2 and 2/2):

1. initial poles, by default from circle fits;
2. for each FRF: linear least squares for the ``a``'s, then nonlinear least squares for
   all parameters.  Here the nonlinear step uses variable projection: for trial poles the
   ``a``'s are eliminated by the linear solve, and ``scipy.optimize.least_squares``
   adjusts only ``mu_k, nu_k`` (same minimum, better conditioned);
3. average the poles over the FRFs (weighted by ``|A_k[i]|``, so that an FRF with a node
   of mode ``k`` hardly counts);
4. with the averaged poles, the linear solve once more gives the residues of every FRF,
   hence the mode shapes.

With ``shared=True`` step 2 fits all FRFs at once with common poles instead of averaging.

**Sampled data.**  A response sampled every ``dt`` under an input held over each
interval (a zero-order hold) has the exact discrete-time FRF ``D + sum_k B_k / (z -
exp(lambda_k dt)) + c.c.`` at ``z = exp(j w dt)``: the continuous ``1 / (j w - lambda)``
is only its limit for ``w dt`` small and a response that falls off with frequency.  An
accelerance does not fall off (its feedthrough aliases), and fitted with the continuous
basis its poles come out biased by several times their noise (two-cart hammer test,
noise-free: omega 0.07 % low, zeta 1.2 % high).  ``time_base="discrete"`` fits the
sampled-data basis ``dt / (z - exp(lambda dt))`` (divided by the hold's factor where the
FRF had it divided out, ``FRF.zoh_divided``), whose poles are still the continuous
``lambda``; an exponential window then shifts every pole by exactly ``-1/tau``.  The
default ``"auto"`` takes it for mobilities and accelerances of sampled data and keeps the
continuous basis for receptances, where the two agree to far below the noise.

**Stated errors.**  The estimate carries the covariance of each pole
(:func:`pole_covariance`: the FRF's errors Gaussian with the residuals' variance,
correlated from line to line as the residuals are), hence ``omega_se`` and ``zeta_se``.
They hold where the model is exact; the residual terms of modes outside the band, or a
mode missing from the fit, are error the residuals count as noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

from .._errors import DataError
from .circle import circle_fit_modes
from .frf import FRF, zoh_factor
from .peaks import pick_peaks
from .result import ModalEstimate, modal_estimate

__all__ = ["MultiModeFit", "multimode_fit", "modal_basis", "pole_covariance", "TIME_BASES"]


@dataclass(frozen=True)
class MultiModeFit:
    """Result of the multi-mode frequency-domain fit.

    Attributes
    ----------
    estimate : ModalEstimate
    residual_mass_coef : ndarray, shape (n_outputs,)
        ``a_1 = 1 / m*`` per FRF (0 if not fitted), 1/kg for a receptance in m/N.
    residual_flexibility : ndarray, shape (n_outputs,)
        ``a_0 = s*`` per FRF (0 if not fitted), FRF units.
    band : ndarray, shape (2,)
        Band fitted, rad/s.
    per_output_poles : ndarray of complex, shape (n_outputs, n_modes)
        Poles from each FRF's own nonlinear fit (NaN when ``shared``).
    derivative_order : int
    relative_error : float
        ``|H - H_fit| / |H|`` over the band and all FRFs.
    output_orders : tuple of int
        Each FRF's derivative order (``derivative_orders`` of the fit).
    sample_intervals : tuple of (float or None)
        Each FRF's sampled-data basis: its sample interval, s, or None for the continuous
        basis.
    zoh_divided : bool
        Whether the sampled-data basis was divided by the hold's factor (as the FRF was).
    """

    estimate: ModalEstimate
    residual_mass_coef: np.ndarray
    residual_flexibility: np.ndarray
    band: np.ndarray
    per_output_poles: np.ndarray
    derivative_order: int
    relative_error: float
    output_orders: tuple = ()
    sample_intervals: tuple = ()
    zoh_divided: bool = False

    def model(self, omega_rad_s) -> np.ndarray:
        """Fitted FRF, shape (n_freq, n_outputs)."""
        w = np.asarray(omega_rad_s, dtype=float)
        s = self.estimate.residues.shape[1]
        out = np.empty((w.size, s), complex)
        for i in range(s):
            G, _ = modal_basis(w, self.estimate.poles, self.output_orders[i], True, True,
                               dt=self.sample_intervals[i], zoh_divided=self.zoh_divided)
            R = self.estimate.residues[:, i]
            a = np.r_[self.residual_flexibility[i], self.residual_mass_coef[i],
                      np.column_stack([R.real, R.imag]).ravel()]
            out[:, i] = G @ a
        return out


def modal_basis(
    omega_rad_s: np.ndarray,
    poles: np.ndarray,
    derivative_order: int = 0,
    residual_flexibility: bool = True,
    residual_mass: bool = True,
    *,
    dt: float | None = None,
    zoh_divided: bool = False,
) -> tuple[np.ndarray, list[str]]:
    """Columns of the linear part of the multi-mode model.

    Parameters
    ----------
    omega_rad_s : ndarray, shape (n_freq,)
    poles : ndarray of complex, shape (n_modes,)
    derivative_order : int
        0 receptance, 1 mobility, 2 accelerance.
    residual_flexibility, residual_mass : bool
        Include the ``a_0`` and ``a_1`` columns (a column of zeros otherwise, so that the
        coefficient layout is fixed).
    dt : float, optional
        Sample interval, s: the modes' columns are the sampled-data terms
        ``dt / (exp(j w dt) - exp(lambda dt))`` instead of ``1 / (j w - lambda)`` (the
        same for ``w dt`` and ``lambda dt`` small).
    zoh_divided : bool
        With ``dt``: divide every column by the hold's factor, as the FRF was.

    Returns
    -------
    G : ndarray of complex, shape (n_freq, 2 + 2 n_modes)
        Columns for ``a_0, a_1, a_13, a_14, a_23, a_24, ...``: ``H = G @ a`` with real ``a``.
    names : list of str
    """
    jw = 1j * np.asarray(omega_rad_s, dtype=float)
    p = int(derivative_order)
    cols = [jw**p * (1.0 if residual_flexibility else 0.0),
            jw ** (p - 2) * (1.0 if residual_mass else 0.0)]
    names = ["s_star", "inv_m_star"]
    if dt is not None:
        z = np.exp(jw * dt)
    for k, lam in enumerate(np.atleast_1d(poles)):
        if dt is None:
            f2 = 1 / (jw - lam)
            f3 = 1 / (jw - np.conj(lam))
        else:
            f2 = dt / (z - np.exp(lam * dt))
            f3 = dt / (z - np.exp(np.conj(lam) * dt))
        cols += [f2 + f3, 1j * (f2 - f3)]
        names += [f"A{k + 1}_R", f"A{k + 1}_I"]
    G = np.column_stack(cols)
    if dt is not None and zoh_divided:
        G = G / zoh_factor(jw.imag, dt)[:, None]
    return G, names


def _linear(G: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # real least squares for real coefficients: stack real and imaginary parts
    Gr = np.vstack([G.real, G.imag])
    scale = np.linalg.norm(Gr, axis=0)
    scale[scale == 0] = 1.0
    Hr = np.concatenate([H.real, H.imag], axis=0)
    a = np.linalg.lstsq(Gr / scale, Hr, rcond=None)[0] / scale[:, None]
    resid = Hr - Gr @ a
    return a, resid


def pole_covariance(r: np.ndarray, J: np.ndarray, n_frf: int, n_lin: int,
                    nu_scale: np.ndarray) -> np.ndarray:
    """Covariance of the poles of a variable-projection fit, shape (n_modes, 2, 2), 1/s^2.

    The FRF's errors are taken as Gaussian, of one variance ``s^2 = RSS / dof`` (``dof``:
    the stacked residuals less the poles' and every FRF's linear coefficients), and
    correlated from one frequency line to the next as an AR(1) sequence of coefficient
    ``rho``, estimated from the residuals with Kendall's small-sample correction (a
    window smears each line's error over its neighbours).  The covariance of the pole
    parameters is then the sandwich ``A Sigma A^T`` with ``A = (J^T J)^-1 J^T`` (``J``:
    the projected residual's Jacobian, which to first order maps an error of the data
    onto the poles), ``s^2 (J^T J)^-1`` when ``rho = 0``.

    Parameters
    ----------
    r : ndarray, shape (2 n_freq n_frf,)
        Residuals at the optimum, the real then the imaginary parts of each line, FRFs
        innermost (``_linear``'s ``resid.ravel()``).
    J : ndarray, shape (2 n_freq n_frf, 2 n_modes)
        Their Jacobian in the scaled pole parameters ``(Re lambda, Im lambda) / nu_scale``.
    n_frf : int
        FRFs fitted together.
    n_lin : int
        Linear coefficients per FRF.
    nu_scale : ndarray, shape (n_modes,)
        The scale of each mode's parameters, 1/s.

    Returns
    -------
    ndarray, shape (n_modes, 2, 2)
        ``cov(Re lambda_k, Im lambda_k)``; NaN when the Jacobian is singular or no degree
        of freedom is left.
    """
    m = nu_scale.size
    n = r.size
    dof = n - 2 * m - n_lin * n_frf
    out = np.full((m, 2, 2), np.nan)
    if dof <= 0:
        return out
    seq = r.reshape(2, -1, n_frf)  # (part, line, FRF): each (part, FRF) a sequence
    s2 = float(r @ r) / dof
    n_f = seq.shape[1]
    rho = np.sum(seq[:, 1:] * seq[:, :-1]) / np.sum(seq**2)
    # Kendall's correction of the lag-1 estimate's small-sample bias, -(1 + 3 rho) / n
    rho = float(np.clip(rho + (1 + 3 * rho) / n_f, 0.0, 0.95))
    try:
        A = np.linalg.solve(J.T @ J, J.T)  # (2m, n)
    except np.linalg.LinAlgError:
        return out
    Ab = A.reshape(2 * m, 2, n_f, n_frf)
    # the AR(1) correlation matrix rho^|i - j| times each row, in O(n): a forward and a
    # backward recursion, less the diagonal counted twice
    fwd = lfilter([1.0], [1.0, -rho], Ab, axis=2)
    bwd = lfilter([1.0], [1.0, -rho], Ab[:, :, ::-1], axis=2)[:, :, ::-1]
    cov = s2 * np.einsum("apif,bpif->ab", Ab, fwd + bwd - Ab)
    for k in range(m):
        ij = [k, m + k]
        out[k] = cov[np.ix_(ij, ij)] * nu_scale[k] ** 2
    return out


def _initial_poles(frf: FRF, band, n_modes) -> np.ndarray:
    try:
        cf = circle_fit_modes(frf, n_modes, search_band=band)
        lam = cf.estimate.poles
        if np.all(np.isfinite(lam)) and np.all(lam.real < 0):
            return lam
    except DataError:
        pass
    pk = pick_peaks(frf, n_modes, band=band)
    if pk.omega_rad_s.size == 0:
        raise DataError("no resonance peak found to start the multi-mode fit")
    z = np.where(np.isfinite(pk.zeta), pk.zeta, 0.02)
    return -z * pk.omega_rad_s + 1j * pk.omega_rad_s


def multimode_fit(
    frf: FRF,
    poles0: np.ndarray | None = None,
    *,
    band: tuple[float, float] | None = None,
    n_modes: int | None = None,
    residual_mass: bool = True,
    residual_flexibility: bool = True,
    shared: bool = False,
    reference: int = 0,
    zeta_max: float = 0.5,
    time_base: str = "auto",
    derivative_orders=None,
) -> MultiModeFit:
    """Multi-mode frequency-domain fit of a column of FRFs.

    Parameters
    ----------
    frf : FRF
        One input, ``s`` outputs.
    poles0 : ndarray of complex, shape (n_modes,), optional
        Initial poles ``mu + j nu`` (1/s); by default from circle fits of the
        ``n_modes`` most prominent peaks in the band.
    band : (lo, hi), optional
        Band ``[w_min, w_max]``, rad/s (whole FRF by default).
    n_modes : int, optional
        Number of modes when ``poles0`` is not given.
    residual_mass, residual_flexibility : bool
        Include the residual terms of the modes below and above the band.
    shared : bool
        Fit all FRFs with common poles in one nonlinear problem instead of fitting each
        FRF and averaging.
    reference : int
        Output the mode shapes are normalised on.
    zeta_max : float
        Modes with larger damping ratio (or unstable) are marked not identified.
    time_base : {"auto", "continuous", "discrete"}
        The modes' basis: ``1 / (j w - lambda)``, or the sampled-data terms of a
        zero-order hold (needs ``frf.dt``; see the module docstring).  ``"auto"``:
        discrete for a mobility or accelerance with a sample interval, else continuous
        (decided per FRF with ``derivative_orders``).
    derivative_orders : sequence of int, optional
        The form of each FRF (0 receptance, 1 mobility, 2 accelerance) when the sensors
        differ, e.g. an encoder and an accelerometer (``forms.orders_of``); default every
        FRF of ``frf.derivative_order``.  Each FRF gets its own residual terms and basis;
        the residues stay in each FRF's units.

    Returns
    -------
    MultiModeFit

    Examples
    --------
    >>> lam = np.array([-0.5 + 20j, -0.8 + 45j])
    >>> w = np.linspace(10, 60, 500)
    >>> H = sum(-0.5j / (1j * w - l) + 0.5j / (1j * w - np.conj(l)) for l in lam)
    >>> fit = multimode_fit(FRF(w, H), lam * 1.02)
    >>> bool(np.allclose(fit.estimate.poles, lam, rtol=1e-6))
    True
    """
    sub = frf if band is None else frf.band(*band)
    w = sub.omega_rad_s
    if poles0 is None:
        poles0 = _initial_poles(sub, None, n_modes)
    lam0 = np.asarray(poles0, dtype=complex).ravel()
    lam0 = np.where(lam0.imag < 0, lam0.conj(), lam0)
    m = lam0.size
    if m < 1:
        raise DataError("at least one initial pole is needed")
    if w.size * 2 < 4 * m + 2:
        raise DataError(f"{w.size} frequencies cannot determine {m} modes (need 2N >= 4m + 2)")
    p = sub.derivative_order
    H = sub.H
    s = H.shape[1]
    orders = _orders(derivative_orders, p, s)
    dts = [_sample_interval(frf, time_base, q) for q in orders]
    zoh_div = bool(frf.zoh_divided) and any(d is not None for d in dts)
    nu_scale = np.abs(lam0.imag)

    def unpack(x):
        return x[:m] * nu_scale + 1j * x[m:] * nu_scale

    def solve(lam, cols):
        """Linear coefficients (n_lin, n_cols) and residuals (2 n_freq, n_cols) of the
        FRFs ``cols`` at poles ``lam``, each FRF in its own form and basis."""
        cols = list(cols)
        a = np.empty((2 + 2 * m, len(cols)))
        r = np.empty((2 * w.size, len(cols)))
        for key in dict.fromkeys((orders[c], dts[c]) for c in cols):
            idx = [j for j, c in enumerate(cols) if (orders[c], dts[c]) == key]
            G, _ = modal_basis(w, lam, key[0], residual_flexibility, residual_mass,
                               dt=key[1], zoh_divided=zoh_div)
            a[:, idx], r[:, idx] = _linear(G, H[:, [cols[j] for j in idx]])
        return a, r

    def resid(x, cols):
        return solve(unpack(x), cols)[1].ravel()

    x0 = np.r_[lam0.real / nu_scale, lam0.imag / nu_scale]
    lower = np.r_[np.full(m, -np.inf), np.zeros(m)]
    upper = np.r_[np.zeros(m), np.full(m, np.inf)]
    x0 = np.clip(x0, lower + 1e-12, upper - 1e-12)
    per_output = np.full((s, m), np.nan + 0j)
    n_lin = 2 * m + int(residual_flexibility) + int(residual_mass)  # per FRF
    if shared:
        sol = least_squares(resid, x0, args=(np.arange(s),), bounds=(lower, upper),
                            x_scale="jac", xtol=1e-12, ftol=1e-12)
        lam = unpack(sol.x)
        cov = pole_covariance(sol.fun, sol.jac, s, n_lin, nu_scale)
    else:
        covs = np.empty((s, m, 2, 2))
        for i in range(s):
            sol = least_squares(resid, x0, args=([i],), bounds=(lower, upper),
                                x_scale="jac", xtol=1e-12, ftol=1e-12)
            per_output[i] = unpack(sol.x)
            covs[i] = pole_covariance(sol.fun, sol.jac, 1, n_lin, nu_scale)
        # weights |A_k[i]| from each FRF's own fit
        wts = np.empty((s, m))
        for i in range(s):
            a, _ = solve(per_output[i], [i])
            wts[i] = np.hypot(a[2::2, 0], a[3::2, 0])
        wts = np.where(np.isfinite(wts), wts, 0.0) + 1e-300
        lam = np.sum(wts * per_output, axis=0) / np.sum(wts, axis=0)
        # the weighted mean of independent per-FRF estimates (weights held fixed)
        cov = np.einsum("ik,ikab->kab", wts**2, covs) / np.sum(wts, axis=0)[:, None, None] ** 2
    a, r = solve(lam, range(s))
    rel = float(np.linalg.norm(r) / np.linalg.norm(np.concatenate([H.real, H.imag])))
    residues = (a[2::2] + 1j * a[3::2])  # (m, s)
    omega = np.abs(lam)
    zeta = -lam.real / omega
    ident = (lam.real < 0) & (zeta < zeta_max) & (lam.imag >= w[0]) & (lam.imag <= w[-1])
    notes = [f"band [{w[0]:.4g}, {w[-1]:.4g}] rad/s, {m} mode(s), "
             f"{'shared poles' if shared else 'poles averaged over FRFs'}, "
             f"{_basis_words(dts)} basis"]
    for k in np.flatnonzero(~ident):
        notes.append(f"mode at {lam[k]:.4g} 1/s rejected (unstable, too damped or outside band)")
    est = modal_estimate("multimode", lam, residues, ident, reference=reference, notes=notes,
                         pole_cov=cov)
    order = np.lexsort((-lam.real, lam.imag))
    return MultiModeFit(est, a[1], a[0], np.array([w[0], w[-1]]), per_output[:, order], p, rel,
                        tuple(orders), tuple(dts), zoh_div)


TIME_BASES = ("auto", "continuous", "discrete")


def _orders(derivative_orders, default: int, n: int) -> list[int]:
    """Each FRF's derivative order, checked (one per FRF, 0, 1 or 2)."""
    if derivative_orders is None:
        return [int(default)] * n
    orders = [int(q) for q in np.ravel(derivative_orders)]
    if len(orders) != n or any(q not in (0, 1, 2) for q in orders):
        raise DataError(f"derivative_orders must give 0, 1 or 2 for each of the {n} FRFs, "
                        f"got {list(np.ravel(derivative_orders))}")
    return orders


def _basis_words(dts) -> str:
    """How the notes name the bases used."""
    kinds = {"continuous" if d is None else "sampled-data" for d in dts}
    return " and ".join(sorted(kinds))


def _sample_interval(frf: FRF, time_base: str, order: int) -> float | None:
    """The sample interval of the sampled-data basis for an FRF of derivative ``order``,
    or None for the continuous one."""
    if time_base not in TIME_BASES:
        raise DataError(f"time_base must be one of {TIME_BASES}, got {time_base!r}")
    if time_base == "continuous" or (time_base == "auto" and (
            frf.dt is None or order < 1)):
        return None
    if frf.dt is None:
        raise DataError("time_base 'discrete' needs the FRF's sample interval (FRF.dt); "
                        "give dt or use time_base 'continuous'")
    return float(frf.dt)
