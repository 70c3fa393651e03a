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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._errors import DataError
from .circle import circle_fit_modes
from .frf import FRF
from .peaks import pick_peaks
from .result import ModalEstimate, modal_estimate

__all__ = ["MultiModeFit", "multimode_fit", "modal_basis"]


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
    """

    estimate: ModalEstimate
    residual_mass_coef: np.ndarray
    residual_flexibility: np.ndarray
    band: np.ndarray
    per_output_poles: np.ndarray
    derivative_order: int
    relative_error: float

    def model(self, omega_rad_s) -> np.ndarray:
        """Fitted FRF, shape (n_freq, n_outputs)."""
        w = np.asarray(omega_rad_s, dtype=float)
        G, _ = modal_basis(w, self.estimate.poles, self.derivative_order, True, True)
        s = self.estimate.residues.shape[1]
        out = np.empty((w.size, s), complex)
        for i in range(s):
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
    for k, lam in enumerate(np.atleast_1d(poles)):
        f2 = 1 / (jw - lam)
        f3 = 1 / (jw - np.conj(lam))
        cols += [f2 + f3, 1j * (f2 - f3)]
        names += [f"A{k + 1}_R", f"A{k + 1}_I"]
    return np.column_stack(cols), names


def _linear(G: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # real least squares for real coefficients: stack real and imaginary parts
    Gr = np.vstack([G.real, G.imag])
    scale = np.linalg.norm(Gr, axis=0)
    scale[scale == 0] = 1.0
    Hr = np.concatenate([H.real, H.imag], axis=0)
    a = np.linalg.lstsq(Gr / scale, Hr, rcond=None)[0] / scale[:, None]
    resid = Hr - Gr @ a
    return a, resid


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
    nu_scale = np.abs(lam0.imag)

    def unpack(x):
        return x[:m] * nu_scale + 1j * x[m:] * nu_scale

    def resid(x, cols):
        G, _ = modal_basis(w, unpack(x), p, residual_flexibility, residual_mass)
        _, r = _linear(G, H[:, cols])
        return r.ravel()

    x0 = np.r_[lam0.real / nu_scale, lam0.imag / nu_scale]
    lower = np.r_[np.full(m, -np.inf), np.zeros(m)]
    upper = np.r_[np.zeros(m), np.full(m, np.inf)]
    x0 = np.clip(x0, lower + 1e-12, upper - 1e-12)
    per_output = np.full((s, m), np.nan + 0j)
    if shared:
        sol = least_squares(resid, x0, args=(np.arange(s),), bounds=(lower, upper),
                            x_scale="jac", xtol=1e-12, ftol=1e-12)
        lam = unpack(sol.x)
    else:
        for i in range(s):
            sol = least_squares(resid, x0, args=([i],), bounds=(lower, upper),
                                x_scale="jac", xtol=1e-12, ftol=1e-12)
            per_output[i] = unpack(sol.x)
        # weights |A_k[i]| from each FRF's own fit
        wts = np.empty((s, m))
        for i in range(s):
            G, _ = modal_basis(w, per_output[i], p, residual_flexibility, residual_mass)
            a, _ = _linear(G, H[:, [i]])
            wts[i] = np.hypot(a[2::2, 0], a[3::2, 0])
        wts = np.where(np.isfinite(wts), wts, 0.0) + 1e-300
        lam = np.sum(wts * per_output, axis=0) / np.sum(wts, axis=0)
    G, _ = modal_basis(w, lam, p, residual_flexibility, residual_mass)
    a, r = _linear(G, H)
    rel = float(np.linalg.norm(r) / np.linalg.norm(np.concatenate([H.real, H.imag])))
    residues = (a[2::2] + 1j * a[3::2])  # (m, s)
    omega = np.abs(lam)
    zeta = -lam.real / omega
    ident = (lam.real < 0) & (zeta < zeta_max) & (lam.imag >= w[0]) & (lam.imag <= w[-1])
    notes = [f"band [{w[0]:.4g}, {w[-1]:.4g}] rad/s, {m} mode(s), "
             f"{'shared poles' if shared else 'poles averaged over FRFs'}"]
    for k in np.flatnonzero(~ident):
        notes.append(f"mode at {lam[k]:.4g} 1/s rejected (unstable, too damped or outside band)")
    est = modal_estimate("multimode", lam, residues, ident, reference=reference, notes=notes)
    order = np.lexsort((-lam.real, lam.imag))
    return MultiModeFit(est, a[1], a[0], np.array([w[0], w[-1]]), per_output[:, order], p, rel)
