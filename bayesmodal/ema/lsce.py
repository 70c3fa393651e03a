"""Least-squares complex exponential (LSCE) method (lecture 11d).

An impulse response function is a sum of damped complex exponentials,

    h[i](t_k) = sum_{r=1}^{2n} A_r[i] U_r^k,      U_r = exp(lambda_r dt),

so every ``U_r`` is a root of ``p(U) = sum_{k=0}^{2n} alpha_{2n-k} U^k`` (``alpha_0 = 1``)
and, for every shift ``m``, ``sum_k alpha_{2n-k} h(t_{k+m}) = sum_r A_r U_r^m p(U_r) = 0``.
Writing this for ``m = 0 .. M-1`` gives ``B alpha = R`` with the Hankel-type matrix

    B[m] = [h(t_{2n-1+m}), h(t_{2n-2+m}), ..., h(t_m)],    R[m] = -h(t_{2n+m}).

The coefficients are common to all IRFs of the column (same poles), so the blocks of ``s``
IRFs are stacked, ``B_tot alpha = R_tot``, and solved by least squares (``lstsq``, which is
the lecture's ``(B^T B)^-1 B^T R`` computed stably).  The roots of ``p`` give
``lambda_r = ln(U_r) / dt``; the residues follow from the Vandermonde system
``sum_r A_r U_r^k = h(t_k)``, ``k = 0 .. P-1``, solved per IRF.

Model order.  Too few modes leave a large error ``eps = |B alpha - R|^2``; too many add
computational modes that fit the noise.  The error curve ``eps(n)`` levels off at the
right order; computational modes are recognised here by being unstable, real or heavily
damped, above 90 % of the Nyquist frequency, or contributing little to the fitted
response; and, over several orders, by not being stable in the stabilisation diagram.

Free decays.  A free response ``y(t) = C e^{A t} x0`` is also a sum of the same
exponentials (with amplitudes set by ``x0`` instead of residues), so the records may be
the free decays after the pulses of a pulse test.  Amplitudes of different records then
differ by a factor per mode; the mode shape is taken as the leading singular vector of
the records' amplitudes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._errors import DataError
from .frf import FRF
from .irf import impulse_response
from .result import ModalEstimate, modal_estimate

__all__ = [
    "LSCEResult",
    "lsce",
    "lsce_frf",
    "StabilizationDiagram",
    "stabilization_diagram",
    "ErrorCurve",
    "error_curve",
]


@dataclass(frozen=True)
class LSCEResult:
    """Result of one LSCE fit.

    Attributes
    ----------
    estimate : ModalEstimate
        One entry per conjugate pole pair or real pole; computational modes have
        ``identified`` False.
    roots : ndarray of complex, shape (2 n,)
        All continuous-time poles ``ln(U_r) / dt``, 1/s.
    alpha : ndarray, shape (2 n + 1,)
        Polynomial coefficients ``alpha_0 = 1, alpha_1 .. alpha_2n``.
    error : float
        Relative least-squares error ``|B alpha - R|^2 / |R|^2`` of the coefficient fit.
    reconstruction_error : float
        ``|h - h_fit| / |h|`` over the P samples of all records.
    contribution : ndarray, shape (n_modes,)
        Norm of each mode's part of the fitted response divided by the norm of the data,
        in ``estimate`` order.
    n_modes : int
        Requested number of modes ``n`` (polynomial order ``2 n``).
    dt : float
        Sample interval used (after ``stride``), s.
    amplitudes : ndarray of complex, shape (n_records, 2 n, n_outputs)
        Amplitudes ``A_r[i]`` of every root in every record (at the record's first
        sample, divided by ``exp(lambda_r t0)``).
    """

    estimate: ModalEstimate
    roots: np.ndarray
    alpha: np.ndarray
    error: float
    reconstruction_error: float
    contribution: np.ndarray
    n_modes: int
    dt: float
    amplitudes: np.ndarray

    def reconstruct(self, n_samples: int, record: int = 0) -> np.ndarray:
        """Fitted response ``sum_r A_r U_r^k`` of one record, shape (n_samples, n_outputs)."""
        U = np.exp(self.roots * self.dt)
        k = np.arange(n_samples)[:, None]
        V = U[None, :] ** k
        return (V @ self.amplitudes[record]).real


def _records(records, stride: int) -> list[np.ndarray]:
    if isinstance(records, np.ndarray):
        records = [records]
    out = []
    for j, r in enumerate(records):
        a = np.asarray(r, dtype=float)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise DataError(f"record {j} must have shape (N,) or (N, n_outputs), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise DataError(f"record {j} contains NaN or inf")
        out.append(a[::stride])
    if not out:
        raise DataError("no records given")
    s = {a.shape[1] for a in out}
    if len(s) != 1:
        raise DataError(f"all records need the same number of outputs, got {sorted(s)}")
    return out


def _hankel_rows(h: np.ndarray, order: int, M: int) -> tuple[np.ndarray, np.ndarray]:
    # B[m, j] = h[order - 1 - j + m], R[m] = -h[order + m], m = 0 .. M-1
    idx = order - 1 - np.arange(order)[None, :] + np.arange(M)[:, None]
    return h[idx], -h[order + np.arange(M)]


def _polynomial(recs: list[np.ndarray], n_modes: int, M: int | None
                ) -> tuple[np.ndarray, float]:
    """The coefficients ``alpha`` (shape (2 n + 1,), leading 1) of the polynomial whose
    roots are ``exp(lambda dt)``, fitted by least squares to the Hankel equations of
    every output of every record, and the relative residual of that fit."""
    order = 2 * n_modes
    Bs, Rs = [], []
    for j, h in enumerate(recs):
        m_avail = h.shape[0] - order
        m = m_avail if M is None else int(M)
        if m < 1 or m > m_avail:
            raise DataError(
                f"record {j}: {h.shape[0]} samples allow M <= {m_avail} equations for "
                f"n = {n_modes} modes, got M = {m}"
            )
        for i in range(h.shape[1]):
            B, R = _hankel_rows(h[:, i], order, m)
            Bs.append(B)
            Rs.append(R)
    B = np.vstack(Bs)
    R = np.concatenate(Rs)
    if B.shape[0] < order:
        raise DataError(f"{B.shape[0]} equations for {order} coefficients; use longer records")
    scale = np.max(np.abs(B)) or 1.0
    a = np.linalg.lstsq(B / scale, R / scale, rcond=None)[0]
    rnorm = float(np.sum(R**2))
    err = float(np.sum((B @ a - R) ** 2) / rnorm) if rnorm > 0 else 0.0
    return np.r_[1.0, a], err


def _amplitudes(recs: list[np.ndarray], lam: np.ndarray, dt_eff: float, order: int,
                P: int | None, t0: float):
    """Amplitudes per record from the Vandermonde system (least squares over P samples).

    Returns the amplitudes of the ``order`` roots referred to ``t = 0``, shape
    (n_rec, order, s), the squared misfit and the squared data summed over the records,
    and each root's squared part of the fitted response, shape (order,).
    """
    amps = []
    fit_sq = 0.0
    data_sq = 0.0
    comp_sq = None
    for h in recs:
        p = h.shape[0] if P is None else min(int(P), h.shape[0])
        if p < order:
            raise DataError(f"P = {p} samples cannot determine {order} residues")
        k = np.arange(p)[:, None]
        V = np.exp(lam[None, :] * dt_eff * k)
        A = np.linalg.lstsq(V, h[:p].astype(complex), rcond=None)[0]  # (2n, s)
        fitted = (V @ A).real
        fit_sq += float(np.sum((h[:p] - fitted) ** 2))
        data_sq += float(np.sum(h[:p] ** 2))
        parts = np.abs(V[:, :, None] * A[None, :, :]) ** 2  # (p, 2n, s), per root
        c = np.sum(parts, axis=(0, 2))
        comp_sq = c if comp_sq is None else comp_sq + c
        amps.append(A * np.exp(-lam * t0)[:, None])
    return np.array(amps), fit_sq, data_sq, comp_sq  # amps (n_rec, 2n, s)


def _shapes(amps: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """One shape per selected root, shape (sel.size, s): the record's amplitudes for one
    record, else the dominant rank-one part of the records' amplitudes (SVD)."""
    shapes = []
    for r in sel:
        Ar = amps[:, r, :]
        if Ar.shape[0] == 1:
            shapes.append(Ar[0])
        else:
            u, s_, vh = np.linalg.svd(Ar, full_matrices=False)
            j = int(np.argmax(np.abs(u[:, 0])))
            shapes.append(u[j, 0] * s_[0] * vh[0])
    return np.array(shapes).reshape(sel.size, -1)


def lsce(
    records,
    dt: float,
    n_modes: int,
    *,
    M: int | None = None,
    P: int | None = None,
    stride: int = 1,
    t0: float = 0.0,
    reference: int = 0,
    zeta_max: float = 0.5,
    min_contribution: float = 0.02,
    method: str = "lsce",
) -> LSCEResult:
    """Least-squares complex exponential fit of impulse responses or free decays.

    Parameters
    ----------
    records : ndarray, shape (N,) or (N, s), or sequence of such arrays
        IRFs (one column per output) or free-decay records; all records share the poles.
    dt : float
        Sample interval of the records, s.
    n_modes : int
        Number of modes ``n``; the polynomial has ``2 n`` roots.
    M : int, optional
        Equations per IRF and record (lecture's M); by default all available,
        ``N - 2 n``.  Needs ``N >= 2 n + M``.
    P : int, optional
        Samples per IRF used for the residues (lecture's P); default all ``N``.
    stride : int
        Use every ``stride``-th sample (a longer effective ``dt`` conditions the
        polynomial better when the modes are far below the Nyquist frequency).
    t0 : float
        Time of the first sample of each record, s; residues are referred to ``t = 0``.
    reference : int
        Output the mode shapes are normalised on.
    zeta_max : float
        Modes with larger damping ratio are flagged computational.
    min_contribution : float
        Modes whose part of the fitted response is smaller than this fraction of the data
        norm are flagged computational.
    method : str
        Name stored in the estimate.

    Returns
    -------
    LSCEResult

    Examples
    --------
    >>> t = np.arange(200) * 0.1
    >>> h = np.exp(-0.1 * t) * np.sin(2.0 * t)
    >>> res = lsce(h, 0.1, 1)
    >>> np.round(res.estimate.poles, 6)
    array([-0.1+2.j])
    """
    if not (np.isfinite(dt) and dt > 0):
        raise DataError(f"dt must be finite and > 0 s, got {dt!r}")
    if int(n_modes) < 1:
        raise DataError(f"n_modes must be >= 1, got {n_modes}")
    if int(stride) < 1:
        raise DataError(f"stride must be >= 1, got {stride}")
    n_modes, stride = int(n_modes), int(stride)
    recs = _records(records, stride)
    dt_eff = dt * stride
    order = 2 * n_modes
    alpha, err = _polynomial(recs, n_modes, M)
    U = np.roots(alpha)
    with np.errstate(divide="ignore"):
        lam = np.log(U.astype(complex)) / dt_eff
    lam = np.where(np.isfinite(lam), lam, -1e3 / dt_eff)  # U = 0: infinitely fast decay
    amps, fit_sq, data_sq, comp_sq = _amplitudes(recs, lam, dt_eff, order, P, t0)
    recon = float(np.sqrt(fit_sq / data_sq)) if data_sq > 0 else 0.0
    # one entry per conjugate pair (positive imaginary part) or real root
    tol = 1e-9 / dt_eff
    modes = np.flatnonzero(lam.imag > tol)
    real = np.flatnonzero(np.abs(lam.imag) <= tol)
    sel = np.r_[modes, real].astype(int)
    # a conjugate pair contributes twice the energy of one root
    contrib = np.sqrt(np.where(lam[sel].imag > tol, 2.0, 1.0) * comp_sq[sel] / data_sq) \
        if data_sq > 0 else np.zeros(sel.size)
    shapes = _shapes(amps, sel)
    lam_sel = lam[sel]
    omega = np.abs(lam_sel)
    zeta = -lam_sel.real / np.where(omega > 0, omega, 1.0)
    nyq = np.pi / dt_eff
    ident = (
        (lam_sel.real < 0)
        & (lam_sel.imag > tol)
        & (zeta < zeta_max)
        & (lam_sel.imag < 0.9 * nyq)
        & (contrib >= min_contribution)
    )
    notes = [f"n = {n_modes}, M = {M or 'all'}, P = {P or 'all'}, dt = {dt_eff:g} s, "
             f"{len(recs)} record(s) x {recs[0].shape[1]} output(s)"]
    for r, ok, z, c in zip(lam_sel, ident, zeta, contrib, strict=True):
        if not ok:
            why = []
            if r.real >= 0:
                why.append("unstable")
            if abs(r.imag) <= tol:
                why.append("real pole")
            elif z >= zeta_max:
                why.append(f"zeta {z:.3g} >= {zeta_max}")
            if r.imag >= 0.9 * nyq:
                why.append("near Nyquist")
            if c < min_contribution:
                why.append(f"contribution {c:.3g} < {min_contribution}")
            notes.append(f"computational mode at {r:.4g} 1/s: {', '.join(why)}")
    est = modal_estimate(method, lam_sel, shapes, ident, reference=reference, notes=notes)
    # put contributions in estimate order (modal_estimate sorts by damped frequency)
    order_idx = np.lexsort((-lam_sel.real, np.abs(lam_sel.imag)))
    return LSCEResult(est, lam, alpha, err, recon, contrib[order_idx], n_modes, dt_eff, amps)


def lsce_frf(
    frf: FRF,
    n_modes: int,
    *,
    t_start: float = 0.0,
    duration: float | None = None,
    min_input_power: float | None = 0.01,
    **kwargs,
) -> LSCEResult:
    """LSCE on the impulse responses obtained from an FRF by inverse FFT.

    Parameters
    ----------
    frf : FRF
        On a full one-sided FFT grid (see ``impulse_response``).
    n_modes : int
    t_start : float
        First time used, s (skips the start of the IRF, where modes far above the band
        and the truncation of the FRF at the Nyquist frequency leave their mark).
    duration : float, optional
        Length of the IRF used, s (default: the rest of the period).
    min_input_power : float or None
        Where ``frf.input_power`` is below this the FRF is set to zero before the inverse
        FFT: there the estimate is noise divided by a vanishing input spectrum, and it
        would swamp the IRF.
    **kwargs
        Passed to ``lsce`` (``M``, ``P``, ``stride``, ...).

    Returns
    -------
    LSCEResult
        Residues in FRF units times rad/s, referred to ``t = 0``.
    """
    if min_input_power is not None and frf.input_power is not None:
        quiet = frf.input_power < min_input_power
        frf = replace(frf, H=np.where(quiet[:, None], 0.0, frf.H))
    irf = impulse_response(frf)
    k0 = int(round(t_start / irf.dt))
    k1 = irf.h.shape[0]
    if duration is not None:
        k1 = min(k1, k0 + int(round(duration / irf.dt)))
    return lsce(irf.h[k0:k1], irf.dt, n_modes, t0=k0 * irf.dt, **kwargs)


@dataclass(frozen=True)
class ErrorCurve:
    """LSCE least-squares error against the number of modes.

    Attributes
    ----------
    orders : ndarray of int, shape (n_orders,)
        Numbers of modes ``n``.
    error : ndarray, shape (n_orders,)
        Relative coefficient error ``|B alpha - R|^2 / |R|^2``.
    reconstruction_error : ndarray, shape (n_orders,)
        Relative reconstruction error of the records.
    """

    orders: np.ndarray
    error: np.ndarray
    reconstruction_error: np.ndarray


def error_curve(records, dt: float, orders: Sequence[int], **kwargs) -> ErrorCurve:
    """LSCE error for several model orders (same M for each, so the errors compare).

    Parameters
    ----------
    records, dt
        As in ``lsce``.
    orders : sequence of int
        Numbers of modes to try.
    **kwargs
        Passed to ``lsce``.

    Returns
    -------
    ErrorCurve
    """
    orders = np.asarray(list(orders), dtype=int)
    res = [lsce(records, dt, int(n), **kwargs) for n in orders]
    return ErrorCurve(
        orders,
        np.array([r.error for r in res]),
        np.array([r.reconstruction_error for r in res]),
    )


@dataclass(frozen=True)
class StabilizationDiagram:
    """Poles of LSCE fits of increasing order, with their stability labels.

    Attributes
    ----------
    orders : ndarray of int, shape (n_orders,)
    poles : tuple of ndarray of complex
        ``poles[j]``: one pole per mode (``Im >= 0``) of order ``orders[j]``, 1/s.
    status : tuple of ndarray of str
        Per pole: ``"new"`` (no pole of the previous order nearby), ``"freq"`` (frequency
        within ``tol_omega``), ``"stable"`` (frequency and damping ratio within tolerance).
    identified : tuple of ndarray of bool
        The computational-mode flags of each fit.
    error : ndarray, shape (n_orders,)
        Relative least-squares error of each order.
    """

    orders: np.ndarray
    poles: tuple
    status: tuple
    identified: tuple
    error: np.ndarray

    def stable_poles(self, min_orders: int = 3) -> np.ndarray:
        """Poles of the highest order that stayed ``"stable"`` over ``min_orders`` orders."""
        if len(self.poles) < min_orders:
            return np.empty(0, complex)
        last = self.poles[-1]
        ok = np.ones(last.size, bool)
        for j in range(1, min_orders):
            st = self.status[-j]
            ok &= st == "stable"
        return last[ok & self.identified[-1]]


def stabilization_diagram(
    records,
    dt: float,
    orders: Sequence[int] = tuple(range(1, 13)),
    *,
    tol_omega: float = 0.01,
    tol_zeta: float = 0.05,
    **kwargs,
) -> StabilizationDiagram:
    """Fit LSCE for several orders and label each pole against the previous order.

    Parameters
    ----------
    records, dt
        As in ``lsce``.
    orders : sequence of int
        Increasing numbers of modes.
    tol_omega : float
        Relative frequency tolerance for a pole to count as repeated.
    tol_zeta : float
        Relative damping-ratio tolerance (``"stable"`` label).
    **kwargs
        Passed to ``lsce``.

    Returns
    -------
    StabilizationDiagram
    """
    orders = np.asarray(list(orders), dtype=int)
    poles, status, ident, errs = [], [], [], []
    prev = None
    for n in orders:
        res = lsce(records, dt, int(n), **kwargs)
        est = res.estimate
        lab = np.full(est.n_modes, "new", dtype=object)
        if prev is not None and prev.n_modes:
            for k in range(est.n_modes):
                dw = np.abs(prev.omega_rad_s - est.omega_rad_s[k]) / est.omega_rad_s[k]
                j = int(np.argmin(dw))
                if dw[j] <= tol_omega:
                    dz = abs(prev.zeta[j] - est.zeta[k]) / max(abs(est.zeta[k]), 1e-12)
                    lab[k] = "stable" if dz <= tol_zeta else "freq"
        poles.append(est.poles)
        status.append(lab.astype(str))
        ident.append(est.identified)
        errs.append(res.error)
        prev = est
    return StabilizationDiagram(orders, tuple(poles), tuple(status), tuple(ident), np.array(errs))
