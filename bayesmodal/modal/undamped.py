"""Undamped normal modes from the generalised symmetric eigenproblem (report section 3.1).

The free undamped motion ``M x'' + K x = 0`` has solutions ``x = u sin(omega t)`` with

    (K - omega^2 M) u = 0,

a generalised symmetric-definite eigenproblem (report Box 3 and eq. 20-23, with errata 1
for K).  For one pair it is solved by ``scipy.linalg.eigh(K, M)``.  For a stack of pairs
(posterior samples) it is reduced to a standard symmetric problem, which
``numpy.linalg.eigh`` solves batched: with the Cholesky factor ``M = L L^T`` and
``u = L^-T y``,

    L^-1 K L^-T y = omega^2 y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ._checks import check_pencil, diag, normalise_on_cart1, quad

__all__ = ["UndampedModes", "undamped_modes", "orthogonality_error", "modes_from_shapes"]


@dataclass(frozen=True)
class UndampedModes:
    """Natural frequencies and mode shapes of an undamped system.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (..., n)
        Natural frequencies in ascending order, rad/s.
    shapes : ndarray, shape (..., n, n)
        Mode shapes as columns (``shapes[..., :, i]`` is mode ``i``), normalised so that
        the displacement of cart 1 (first row) is 1; dimensionless.
    modal_mass : ndarray, shape (..., n)
        ``diag(U^T M U)`` for these shapes, kg.
    modal_stiffness : ndarray, shape (..., n)
        ``diag(U^T K U)``, N/m; ``modal_stiffness / modal_mass = omega_rad_s**2``.
    """

    omega_rad_s: np.ndarray
    shapes: np.ndarray
    modal_mass: np.ndarray
    modal_stiffness: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of modes (= number of carts)."""
        return int(self.omega_rad_s.shape[-1])


def modes_from_shapes(M: np.ndarray, K: np.ndarray, shapes: np.ndarray, cls=UndampedModes,
                      **extra) -> UndampedModes:
    """Sort, normalise on cart 1 and build the result from raw eigenvectors.

    The frequencies are the Rayleigh quotients of the shapes, ``omega^2 = u^T K u / u^T M u``,
    which is exact for an exact eigenvector and second-order accurate otherwise.

    Parameters
    ----------
    M, K : ndarray, shape (..., n, n)
        Validated mass (kg) and stiffness (N/m) matrices.
    shapes : ndarray, shape (..., n, n)
        Eigenvectors as columns, any scaling and order.
    cls : type
        Result class (a subclass of UndampedModes).
    **extra : ndarray, shape (..., n)
        Per-mode extra fields of ``cls``, reordered with the modes.
    """
    shapes = normalise_on_cart1(shapes, stacklevel=4)
    modal_mass = diag(quad(shapes, M))
    modal_stiffness = diag(quad(shapes, K))
    omega2 = modal_stiffness / modal_mass
    order = np.argsort(omega2, axis=-1)
    take = lambda a: np.take_along_axis(a, order, axis=-1)  # noqa: E731
    shapes = np.take_along_axis(shapes, order[..., None, :], axis=-1)
    return cls(
        omega_rad_s=np.sqrt(take(omega2)),
        shapes=shapes,
        modal_mass=take(modal_mass),
        modal_stiffness=take(modal_stiffness),
        **{k: take(np.asarray(v)) for k, v in extra.items()},
    )


def undamped_modes(M, K) -> UndampedModes:
    """Natural frequencies and mode shapes from ``(K - omega^2 M) u = 0``.

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Mass matrix, kg; symmetric positive definite.
    K : array_like, shape (..., n, n)
        Stiffness matrix, N/m; symmetric positive definite.  Leading (batch) dimensions of
        M and K broadcast.

    Returns
    -------
    UndampedModes
        Frequencies ascending, shapes normalised on cart 1.

    Raises
    ------
    ModelError
        If M or K is not square, symmetric and positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> modes = undamped_modes(np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]]))
    >>> modes.omega_rad_s.round(6)
    array([1.      , 1.732051])
    >>> modes.shapes
    array([[ 1.,  1.],
           [ 1., -1.]])
    """
    M, K = check_pencil(M, K)
    if M.ndim == 2:
        _, vectors = scipy.linalg.eigh(K, M)
    else:
        L = np.linalg.cholesky(M)
        Linv = np.linalg.inv(L)
        A = Linv @ K @ np.swapaxes(Linv, -1, -2)
        A = 0.5 * (A + np.swapaxes(A, -1, -2))
        _, y = np.linalg.eigh(A)
        vectors = np.swapaxes(Linv, -1, -2) @ y
    return modes_from_shapes(M, K, vectors)


def orthogonality_error(M, shapes) -> np.ndarray:
    """Largest off-diagonal entry of ``U^T M U`` relative to its diagonal.

    The value is ``max_{i != j} |G_ij| / sqrt(G_ii G_jj)`` with ``G = U^T M U``, i.e. the
    largest cosine between two modes in the M inner product; 0 for exact modes.

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Mass matrix, kg (or any symmetric weight, e.g. K).
    shapes : array_like, shape (..., n, m)
        Mode shapes as columns.

    Returns
    -------
    ndarray, shape (...,)
        Dimensionless.

    Examples
    --------
    >>> import numpy as np
    >>> float(orthogonality_error(np.eye(2), np.array([[1.0, 1.0], [1.0, -1.0]])))
    0.0
    """
    G = quad(np.asarray(shapes), np.asarray(M, dtype=float))
    d = np.sqrt(np.abs(diag(G)))
    rel = np.abs(G) / (d[..., :, None] * d[..., None, :])
    m = rel.shape[-1]
    rel = np.where(np.eye(m, dtype=bool), 0.0, rel)
    return np.max(rel, axis=(-2, -1)) if m > 1 else np.zeros(rel.shape[:-2])
