"""Modal Assurance Criterion between two sets of mode shapes."""

from __future__ import annotations

import numpy as np

from .._errors import ModelError

__all__ = ["mac"]


def mac(phi_a, phi_b) -> np.ndarray:
    """Modal Assurance Criterion matrix.

    ``MAC_ij = |phi_a_i^H phi_b_j|^2 / ((phi_a_i^H phi_a_i) (phi_b_j^H phi_b_j))``: 1 for
    shapes that are complex multiples of each other, 0 for orthogonal ones.

    Parameters
    ----------
    phi_a : array_like, shape (..., n_dof, n_a) or (n_dof,)
        Mode shapes as columns (real or complex); a 1-D array is one shape.
    phi_b : array_like, shape (..., n_dof, n_b) or (n_dof,)

    Returns
    -------
    ndarray, shape (..., n_a, n_b)
        Values in [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> mac(np.array([[1.0, 1.0], [1.0, -1.0]]), np.array([[2.0], [2.0]])).ravel()
    array([1., 0.])
    """
    a = np.asarray(phi_a)
    b = np.asarray(phi_b)
    a = a[:, None] if a.ndim == 1 else a
    b = b[:, None] if b.ndim == 1 else b
    if a.shape[-2] != b.shape[-2]:
        raise ModelError(
            f"mode shapes must have the same number of DOFs: {a.shape[-2]} vs {b.shape[-2]}"
        )
    cross = np.abs(np.conj(np.swapaxes(a, -1, -2)) @ b) ** 2
    na = np.sum(np.abs(a) ** 2, axis=-2)
    nb = np.sum(np.abs(b) ** 2, axis=-2)
    denom = na[..., :, None] * nb[..., None, :]
    if np.any(denom == 0):
        raise ModelError("a mode shape is identically zero")
    return cross / denom
