"""Modal decomposition and modal damping (report sections 3.3.1-3.3.2).

With the undamped mode shapes U as new coordinates, ``x = U q``, the equations of motion
become ``(U^T M U) q'' + (U^T C U) q' + (U^T K U) q = U^T b v`` (eq. 35-39).  The modal mass
and stiffness matrices are diagonal by M- and K-orthogonality; the modal damping matrix is
diagonal only for classical damping, e.g. proportional damping ``C = ca M + cb K`` (eq. 17),
for which each mode is a single-degree-of-freedom oscillator with

    2 zeta_i omega_i = ca + cb omega_i^2   =>   zeta_i = (ca + cb omega_i^2) / (2 omega_i)

(eq. 41a) and damped frequency ``omega_d = omega_i sqrt(1 - zeta_i^2)`` (eq. 41b with
errata 3: the report prints ``sqrt(1 - zeta)``, but its Table 9 values follow from
``sqrt(1 - zeta^2)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._errors import ModelError
from ._checks import diag, quad

__all__ = ["ModalMatrices", "modal_matrices", "ModalDamping", "proportional_modal_damping"]


@dataclass(frozen=True)
class ModalMatrices:
    """Mass, damping and stiffness matrices in modal coordinates.

    Attributes
    ----------
    mass : ndarray, shape (..., n, n)
        ``U^T M U``, kg (for shapes normalised on cart 1).
    damping : ndarray, shape (..., n, n)
        ``U^T C U``, N s/m.
    stiffness : ndarray, shape (..., n, n)
        ``U^T K U``, N/m.
    coupling : ndarray, shape (...,)
        Damping coupling ``max_{i != j} |C~_ij| / sqrt(C~_ii C~_jj)`` of the modal damping
        matrix C~; 0 for classical (e.g. proportional) damping.  Scale-free, independent
        of the shape normalisation.
    orthogonality : ndarray, shape (...,)
        The same measure for the larger of the mass and stiffness matrices (0 for exact
        modes).
    zeta : ndarray, shape (..., n)
        Modal damping ratios from the diagonal, ``C~_ii / (2 sqrt(K~_ii M~_ii))``; exact
        for classical damping, the "neglect the coupling" approximation otherwise.
    """

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    coupling: np.ndarray
    orthogonality: np.ndarray
    zeta: np.ndarray


def _offdiag(X):
    d = np.sqrt(np.abs(diag(X)))
    denom = d[..., :, None] * d[..., None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(denom > 0, np.abs(X) / denom, np.where(np.abs(X) > 0, np.inf, 0.0))
    n = X.shape[-1]
    rel = np.where(np.eye(n, dtype=bool), 0.0, rel)
    return np.max(rel, axis=(-2, -1)) if n > 1 else np.zeros(X.shape[:-2])


def modal_matrices(M, C, K, shapes) -> ModalMatrices:
    """Project M, C, K onto mode shapes (report eq. 35c-e).

    Parameters
    ----------
    M, C, K : array_like, shape (..., n, n)
        Mass (kg), damping (N s/m) and stiffness (N/m) matrices.
    shapes : array_like, shape (..., n, n)
        Undamped mode shapes as columns, e.g. ``undamped_modes(M, K).shapes``.

    Returns
    -------
    ModalMatrices

    Examples
    --------
    >>> import numpy as np
    >>> M, K = np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]])
    >>> U = np.array([[1.0, 1.0], [1.0, -1.0]])
    >>> mm = modal_matrices(M, 0.1 * M + 0.01 * K, K, U)
    >>> mm.stiffness
    array([[2., 0.],
           [0., 6.]])
    >>> float(mm.coupling)
    0.0
    """
    M, C, K, U = (np.asarray(a, dtype=float) for a in (M, C, K, shapes))
    for name, X in (("M", M), ("C", C), ("K", K), ("shapes", U)):
        if X.ndim < 2 or X.shape[-2] != M.shape[-1]:
            raise ModelError(f"{name} must have shape (..., {M.shape[-1]}, m), got {X.shape}")
    Mm, Cm, Km = quad(U, M), quad(U, C), quad(U, K)
    Mm, Cm, Km = (0.5 * (X + np.swapaxes(X, -1, -2)) for X in (Mm, Cm, Km))
    zeta = diag(Cm) / (2.0 * np.sqrt(diag(Km) * diag(Mm)))
    return ModalMatrices(
        mass=Mm,
        damping=Cm,
        stiffness=Km,
        coupling=_offdiag(Cm),
        orthogonality=np.maximum(_offdiag(Mm), _offdiag(Km)),
        zeta=zeta,
    )


@dataclass(frozen=True)
class ModalDamping:
    """Modal damping of proportionally damped modes.

    Attributes
    ----------
    zeta : ndarray, shape (..., n)
        Damping ratios, dimensionless.
    damped_rad_s : ndarray, shape (..., n)
        Damped natural frequencies ``omega sqrt(1 - zeta^2)``, rad/s; 0 for overdamped
        modes (``zeta >= 1``), which do not oscillate.
    """

    zeta: np.ndarray
    damped_rad_s: np.ndarray


def proportional_modal_damping(omega_rad_s, ca, cb) -> ModalDamping:
    """Damping ratios and damped frequencies for ``C = ca M + cb K`` (report eq. 41).

    Parameters
    ----------
    omega_rad_s : array_like, shape (..., n)
        Undamped natural frequencies, rad/s (> 0).
    ca : array_like, shape (...,)
        Mass-proportional coefficient, 1/s.
    cb : array_like, shape (...,)
        Stiffness-proportional coefficient, s.

    Returns
    -------
    ModalDamping
        ``zeta = (ca + cb omega^2) / (2 omega)`` and ``omega sqrt(1 - zeta^2)``.

    Examples
    --------
    >>> r = proportional_modal_damping([8.2709, 27.4019, 41.85], 1.528, 8.583e-05)
    >>> r.zeta.round(3), r.damped_rad_s.round(3)
    (array([0.093, 0.029, 0.02 ]), array([ 8.235, 27.39 , 41.842]))
    """
    w = np.asarray(omega_rad_s, dtype=float)
    ca = np.asarray(ca, dtype=float)[..., None]
    cb = np.asarray(cb, dtype=float)[..., None]
    if np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise ModelError(f"natural frequencies must be finite and > 0 rad/s, got {w}")
    zeta = (ca + cb * w**2) / (2.0 * w)
    damped = w * np.sqrt(np.clip(1.0 - zeta**2, 0.0, None))
    return ModalDamping(zeta=zeta, damped_rad_s=damped)
