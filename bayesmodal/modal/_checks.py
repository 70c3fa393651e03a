"""Validation and small numerical helpers shared by the modal methods."""

from __future__ import annotations

import warnings

import numpy as np

from .._errors import ModelError

#: Relative asymmetry above which a mass or stiffness matrix is rejected.
_SYMMETRY_RTOL = 1e-10
#: A mode whose cart-1 amplitude is below this fraction of its largest amplitude cannot be
#: normalised on cart 1 (it has a node there).
_NODE_RTOL = 1e-8


def check_pencil(M, K) -> tuple[np.ndarray, np.ndarray]:
    """Validate a mass/stiffness pair and broadcast it to a common shape.

    Parameters
    ----------
    M, K : array_like, shape (..., n, n)
        Mass (kg) and stiffness (N/m) matrices; symmetric positive definite.

    Returns
    -------
    M, K : ndarray, shape (..., n, n), float
        Broadcast copies (exactly symmetrised).

    Raises
    ------
    ModelError
        Wrong shapes, non-finite entries, asymmetry, or a matrix that is not positive
        definite (a rig must be fixed to the frame so that K > 0).
    """
    M = np.asarray(M, dtype=float)
    K = np.asarray(K, dtype=float)
    for name, X in (("M", M), ("K", K)):
        if X.ndim < 2 or X.shape[-1] != X.shape[-2] or X.shape[-1] < 1:
            raise ModelError(f"{name} must have shape (..., n, n) with n >= 1, got {X.shape}")
    if M.shape[-1] != K.shape[-1]:
        raise ModelError(f"M and K sizes differ: M {M.shape}, K {K.shape}")
    try:
        batch = np.broadcast_shapes(M.shape[:-2], K.shape[:-2])
    except ValueError:
        raise ModelError(
            f"M and K batch shapes do not broadcast: M {M.shape}, K {K.shape}"
        ) from None
    n = M.shape[-1]
    M = np.broadcast_to(M, batch + (n, n))
    K = np.broadcast_to(K, batch + (n, n))
    for name, X in (("M", M), ("K", K)):
        if not np.all(np.isfinite(X)):
            raise ModelError(f"{name} has non-finite entries")
        scale = np.max(np.abs(X), axis=(-2, -1))
        asym = np.max(np.abs(X - np.swapaxes(X, -1, -2)), axis=(-2, -1))
        if np.any(asym > _SYMMETRY_RTOL * scale):
            worst = float(np.max(asym / np.where(scale > 0, scale, 1.0)))
            raise ModelError(f"{name} is not symmetric (relative asymmetry {worst:.3g})")
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    K = 0.5 * (K + np.swapaxes(K, -1, -2))
    for name, X in (("M", M), ("K", K)):
        if not np.all(is_positive_definite(X)):
            bad = np.argwhere(~np.atleast_1d(is_positive_definite(X)))[0]
            where = f" (batch index {tuple(int(i) for i in bad)})" if batch else ""
            hint = " (is every cart tied to the frame?)" if name == "K" else ""
            raise ModelError(f"{name} is not positive definite{where}{hint}")
    return M, K


def is_positive_definite(X: np.ndarray) -> np.ndarray:
    """Boolean mask, shape (...,), of symmetric matrices that admit a Cholesky factor."""
    try:
        np.linalg.cholesky(X)
        return np.ones(X.shape[:-2], dtype=bool)
    except np.linalg.LinAlgError:
        pass
    flat = X.reshape((-1,) + X.shape[-2:])
    ok = np.empty(len(flat), dtype=bool)
    for i, x in enumerate(flat):
        try:
            np.linalg.cholesky(x)
            ok[i] = True
        except np.linalg.LinAlgError:
            ok[i] = False
    return ok.reshape(X.shape[:-2])


def normalise_on_cart1(shapes: np.ndarray, *, stacklevel: int = 3) -> np.ndarray:
    """Scale each column so that its first component (cart 1) equals 1.

    Columns with a node at cart 1 (|first| < 1e-8 max|column|) are instead scaled so that
    their largest-magnitude component is 1, with a warning.

    Parameters
    ----------
    shapes : ndarray, shape (..., n, n_modes), real or complex
    """
    first = shapes[..., :1, :]
    big = np.take_along_axis(
        shapes, np.argmax(np.abs(shapes), axis=-2)[..., None, :], axis=-2
    )
    node = np.abs(first) < _NODE_RTOL * np.abs(big)
    if np.any(node):
        warnings.warn(
            f"{int(np.sum(node))} mode(s) have a node at cart 1 and were normalised on their "
            "largest component instead",
            stacklevel=stacklevel,
        )
    scale = np.where(node, big, first)
    return shapes / scale


def diag(X: np.ndarray) -> np.ndarray:
    """Diagonal of a stack of square matrices, shape (..., n)."""
    return np.diagonal(X, axis1=-2, axis2=-1).copy()


def quad(U: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Congruence ``U^T X U`` (``U^H X U`` for complex U) over a stack, shape (..., m, m)."""
    return np.conj(np.swapaxes(U, -1, -2)) @ X @ U


def n_negative(H: np.ndarray) -> np.ndarray:
    """Number of negative eigenvalues of symmetric matrices, without an eigen-solver.

    Counts the negative pivots of an LDL^T factorisation (Sylvester's law of inertia:
    the pivots have the same signs as the eigenvalues).  No pivoting is done, which is
    adequate for the Hessians of a Rayleigh quotient at its stationary points.

    Parameters
    ----------
    H : ndarray, shape (..., m, m)

    Returns
    -------
    ndarray of int, shape (...,)
    """
    A = np.array(H, dtype=float, copy=True)
    m = A.shape[-1]
    count = np.zeros(A.shape[:-2], dtype=int)
    scale = np.max(np.abs(A), axis=(-2, -1)) if m else np.zeros(A.shape[:-2])
    tiny = np.finfo(float).eps * np.where(scale > 0, scale, 1.0)
    for j in range(m):
        piv = A[..., j, j]
        count += piv < 0
        safe = np.where(np.abs(piv) > tiny, piv, np.where(piv < 0, -tiny, tiny))
        col = A[..., j + 1 :, j] / safe[..., None]
        A[..., j + 1 :, j + 1 :] -= col[..., :, None] * A[..., j, j + 1 :][..., None, :]
    return count
