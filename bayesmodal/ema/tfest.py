"""Parametric transfer-function estimation: a rational least-squares fit of FRFs.

The FRFs of one input are fitted by rational functions with a common denominator,

    H_i(s) ~ N_i(s) / D(s),   D(s) = s^na + d_{na-1} s^{na-1} + ... + d_0,
    deg N_i = nb <= na - 1,   s = j w,

which is the frequency-domain counterpart of MATLAB's ``tfest`` used in report section 5.
The output error ``sum |H_i - N_i / D|^2`` is minimised by Sanathanan-Koerner iteration:
each step solves the linear least-squares problem

    min sum_k sum_i |N_i(s_k) - H_i(s_k) D(s_k)|^2 / |D_prev(s_k)|^2

(Levy's linearisation, reweighted by the previous denominator, so that at convergence
the weights cancel the ``D`` factor).  Frequencies are scaled by the band centre for
conditioning.  The poles are the roots of ``D``; the residues of pole ``lambda_r`` are
``N_i(lambda_r) / D'(lambda_r)``, which gives the mode shapes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._errors import DataError
from .frf import FRF
from .result import ModalEstimate, modal_estimate

__all__ = ["TFEstimate", "tfest"]


@dataclass(frozen=True)
class TFEstimate:
    """A fitted rational transfer function and its modal parameters.

    Attributes
    ----------
    estimate : ModalEstimate
        One entry per complex pole pair (``Im > 0``) or real pole.
    numerator : ndarray, shape (n_outputs, nb + 1)
        Coefficients of ``N_i(s)`` (highest power first, s in rad/s).
    denominator : ndarray, shape (na + 1,)
        Coefficients of ``D(s)``, monic (highest power first).
    poles : ndarray of complex, shape (na,)
        All roots of ``D``, 1/s.
    relative_error : float
        ``|H - N/D| / |H|`` over the fitted band.
    n_iterations : int
        Sanathanan-Koerner iterations performed.
    """

    estimate: ModalEstimate
    numerator: np.ndarray
    denominator: np.ndarray
    poles: np.ndarray
    relative_error: float
    n_iterations: int

    def frf(self, omega_rad_s) -> np.ndarray:
        """Fitted FRF ``N_i(j w) / D(j w)``, shape (n_freq, n_outputs)."""
        s = 1j * np.asarray(omega_rad_s, dtype=float)
        D = np.polyval(self.denominator, s)
        return np.column_stack([np.polyval(b, s) / D for b in self.numerator])


def _solve(s, H, na, nb, wts):
    # unknowns: d_0 .. d_{na-1}, then for each output n_{i,0} .. n_{i,nb} (ascending powers)
    n_freq, n_out = H.shape
    Sd = s[:, None] ** np.arange(na)[None, :]
    Sn = s[:, None] ** np.arange(nb + 1)[None, :]
    n_unk = na + n_out * (nb + 1)
    rows = []
    rhs = []
    for i in range(n_out):
        A = np.zeros((n_freq, n_unk), complex)
        A[:, :na] = -H[:, [i]] * Sd
        A[:, na + i * (nb + 1) : na + (i + 1) * (nb + 1)] = Sn
        rows.append(A * wts[:, None])
        rhs.append(H[:, i] * s**na * wts)
    A = np.vstack(rows)
    b = np.concatenate(rhs)
    Ar = np.vstack([A.real, A.imag])
    br = np.concatenate([b.real, b.imag])
    scale = np.linalg.norm(Ar, axis=0)
    scale[scale == 0] = 1.0
    x = np.linalg.lstsq(Ar / scale, br, rcond=None)[0] / scale
    d = np.r_[x[:na], 1.0]  # ascending
    num = x[na:].reshape(n_out, nb + 1)
    return d, num


def tfest(
    frf: FRF,
    n_poles: int,
    *,
    n_zeros: int | None = None,
    band: tuple[float, float] | None = None,
    n_iter: int = 30,
    tol: float = 1e-10,
    reference: int = 0,
    zeta_max: float = 0.5,
    min_contribution: float = 0.05,
) -> TFEstimate:
    """Fit ``N_i(s) / D(s)`` of a chosen order to a column of FRFs.

    Parameters
    ----------
    frf : FRF
    n_poles : int
        Order ``na`` of the common denominator (twice the number of modes).
    n_zeros : int, optional
        Order ``nb`` of the numerators (default ``na - 1``).
    band : (lo, hi), optional
        Band fitted, rad/s.
    n_iter : int
        Maximum number of Sanathanan-Koerner iterations.
    tol : float
        Stop when the denominator coefficients change by less than this (relative).
    reference : int
        Output the mode shapes are normalised on.
    zeta_max : float
        Poles with a larger damping ratio, unstable poles and real poles are marked not
        identified ...
    min_contribution : float
        ... and so are modes whose peak ``|A| / |mu|`` is below this fraction of the
        largest ``|H|`` in the band (in every output), and modes outside the band.

    Returns
    -------
    TFEstimate

    Examples
    --------
    >>> w = np.linspace(1, 30, 300)
    >>> s = 1j * w
    >>> H = 2.0 / (s**2 + 0.4 * s + 100.0)
    >>> fit = tfest(FRF(w, H), 2)
    >>> np.round(fit.poles, 4)
    array([-0.2+9.998j, -0.2-9.998j])
    """
    sub = frf if band is None else frf.band(*band)
    na = int(n_poles)
    nb = na - 1 if n_zeros is None else int(n_zeros)
    if na < 1 or not 0 <= nb <= na:
        raise DataError(f"need n_poles >= 1 and 0 <= n_zeros <= n_poles, got {na}, {nb}")
    w = sub.omega_rad_s
    H = sub.H
    n_unk = na + H.shape[1] * (nb + 1)
    if 2 * w.size * H.shape[1] < n_unk:
        raise DataError(f"{w.size} frequencies are too few for {n_unk} coefficients")
    w0 = float(np.sqrt(w[0] * w[-1])) if w[0] > 0 else float(w[-1] / 2)
    s = 1j * w / w0
    wts = np.ones(w.size)
    d_prev = None
    n_done = 0
    while n_done < int(n_iter):
        d, num = _solve(s, H, na, nb, wts)
        n_done += 1
        Ds = np.polyval(d[::-1], s)
        wts = 1.0 / np.maximum(np.abs(Ds), 1e-300)
        if d_prev is not None and np.linalg.norm(d - d_prev) <= tol * np.linalg.norm(d):
            break
        d_prev = d
    # back to unscaled s: D(s) = sum d_k (s / w0)^k, monic after multiplying by w0^na
    den = (d * w0 ** (na - np.arange(na + 1)))[::-1]  # highest power first, monic
    numer = np.array([(b * w0 ** (na - np.arange(nb + 1)))[::-1] for b in num])
    poles = np.roots(den)
    jw = 1j * w
    fitted = np.column_stack([np.polyval(b, jw) for b in numer]) / np.polyval(den, jw)[:, None]
    rel = float(np.linalg.norm(H - fitted) / np.linalg.norm(H))
    # residues of each pole from the partial fractions of the fitted rational function
    dden = np.polyder(den)
    tol_im = 1e-9 * max(np.max(np.abs(poles)), 1.0)
    sel = np.flatnonzero(poles.imag >= -tol_im)
    sel = sel[(poles[sel].imag > tol_im) | (np.abs(poles[sel].imag) <= tol_im)]
    lam = poles[sel]
    R = np.array([[np.polyval(b, p) / np.polyval(dden, p) for b in numer] for p in lam])
    R = R.reshape(lam.size, H.shape[1])
    omega = np.abs(lam)
    zeta = -lam.real / np.where(omega > 0, omega, 1.0)
    hmax = np.max(np.abs(H), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        peak = np.abs(R) / np.abs(lam.real)[:, None]
    strong = np.any(peak >= min_contribution * hmax[None, :], axis=1)
    ident = (
        (lam.real < 0)
        & (lam.imag > tol_im)
        & (zeta < zeta_max)
        & (lam.imag >= w[0])
        & (lam.imag <= w[-1])
        & strong
    )
    notes = [f"n_poles = {na}, n_zeros = {nb}, band [{w[0]:.4g}, {w[-1]:.4g}] rad/s, "
             f"{n_done} iteration(s), relative error {rel:.3g}"]
    for k in np.flatnonzero(~ident):
        notes.append(f"pole {lam[k]:.4g} 1/s not a mode of the band (real, unstable, too "
                     "damped, outside the band or too weak)")
    est = modal_estimate("tfest", lam, R, ident, reference=reference, notes=notes)
    return TFEstimate(est, numer, den, poles, rel, n_done)
