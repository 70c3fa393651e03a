"""Batched matrix exponentials and the exact zero-order hold of many systems at once."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Scaled norm bound and Taylor degree: theta^(m+1) / (m+1)! = 2.3e-17 relative error.
_EXPM_THETA = 0.5
_EXPM_DEGREE = 14


_COEFFS = np.array([1.0 / math.factorial(k) for k in range(_EXPM_DEGREE + 1)])


@njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
def _product(out, a, m):
    """``out = a @ m`` for each lane of (d, d, W) stacks, the lane loop innermost.

    Each entry is summed over ``k`` from 0 up, one rounding a term, as the unrolled
    expression ``a[i, 0] m[0, j] + a[i, 1] m[1, j] + ...`` evaluates from the left."""
    d, W = a.shape[0], a.shape[2]
    for i in range(d):
        for j in range(d):
            for b in range(W):
                out[i, j, b] = a[i, 0, b] * m[0, j, b]
            for k in range(1, d):
                for b in range(W):
                    out[i, j, b] = out[i, j, b] + a[i, k, b] * m[k, j, b]


@njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
def _combination(out, X, X2, X3, c, j0):
    """``out = c[j0] I + c[j0+1] X + c[j0+2] X^2 + c[j0+3] X^3``, the terms up to the
    Taylor degree only, summed from the left."""
    d, W = X.shape[0], X.shape[2]
    top = c.size - 1
    for i in range(d):
        for j in range(d):
            one = c[j0] if i == j else 0.0
            if j0 + 3 <= top:
                for b in range(W):
                    out[i, j, b] = (one + c[j0 + 1] * X[i, j, b] + c[j0 + 2] * X2[i, j, b]
                                    + c[j0 + 3] * X3[i, j, b])
            else:  # j0 + 2 == top: the degree-14 polynomial's last block
                for b in range(W):
                    out[i, j, b] = one + c[j0 + 1] * X[i, j, b] + c[j0 + 2] * X2[i, j, b]


@njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
def _expm_kernel(X, n_squarings, E, X2, X3, X4, T, c):
    """``E = T_14(X)^(2^s)`` for (d, d, W) stacks of any size ``d``.

    ``T_14`` is the degree-14 Taylor polynomial (coefficients ``c``) evaluated by
    Paterson-Stockmeyer (``X^2, X^3, X^4`` and three products in ``X^4``: six matrix
    products instead of thirteen) and ``s = n_squarings[b]`` (int, shape (W,)) for lane
    ``b``, whose ``X`` is already scaled by ``2^-s``; the other arrays are work space.
    One compiled function serves every ``d`` (a kernel unrolled per size took 20-40 s to
    compile, one for each state size in use); the lane loop (last axis) is innermost and
    vectorised."""
    d, W = X.shape[0], X.shape[2]
    _product(X2, X, X)
    _product(X3, X2, X)
    _product(X4, X2, X2)
    _combination(E, X, X2, X3, c, 12)
    for j0 in (8, 4, 0):
        _product(T, E, X4)
        _combination(E, X, X2, X3, c, j0)
        for i in range(d):
            for j in range(d):
                for b in range(W):
                    E[i, j, b] += T[i, j, b]
    top = n_squarings.max() if W else 0
    for q in range(top):
        _product(T, E, E)
        for i in range(d):
            for j in range(d):
                for b in range(W):
                    E[i, j, b] = T[i, j, b] if q < n_squarings[b] else E[i, j, b]


def expm_batched(Z: np.ndarray) -> np.ndarray:
    """Matrix exponentials of a stack of small matrices, compiled and batched.

    Scaling and squaring with a degree-14 Taylor polynomial (the scaled matrices have
    infinity norm <= 0.5, truncation error below 3e-17 relative), vectorised across the
    batch; no BLAS calls, so it does not suffer from thread oversubscription on a loaded
    machine the way ``scipy.linalg.expm`` on a stack does.  Each matrix is scaled and
    squared by its own norm, so that the result does not depend on the rest of the batch.

    Parameters
    ----------
    Z : ndarray, shape (nb, d, d)

    Returns
    -------
    ndarray, shape (nb, d, d)

    Examples
    --------
    >>> bool(np.isclose(expm_batched(np.array([[[1.0]]]))[0, 0, 0], np.e, rtol=1e-15))  # e
    True
    """
    Z = np.asarray(Z, dtype=float)
    nb, d, _ = Z.shape
    norm = np.max(np.sum(np.abs(Z), axis=-1), axis=-1) if d else np.zeros(nb)
    if not np.all(np.isfinite(norm)):
        raise ValueError("expm_batched: matrix with non-finite entries")
    with np.errstate(divide="ignore"):
        s = np.ceil(np.log2(norm / _EXPM_THETA))
    s = np.where(norm > _EXPM_THETA, s, 0).astype(np.int64)
    X = np.ascontiguousarray(np.moveaxis(Z * np.ldexp(1.0, -s)[:, None, None], 0, -1))
    E = np.empty_like(X)
    _expm_kernel(X, s, E, *(np.empty_like(X) for _ in range(4)), _COEFFS)
    return np.ascontiguousarray(np.moveaxis(E, -1, 0))


def zoh(A: np.ndarray, inputs: np.ndarray, h, *, ramp: bool = False):
    """Exact one-step matrices of ``z' = A z + inputs w`` for a batch of systems.

    For ``w`` held over the step, ``z(h) = Ah z(0) + G0 w`` with ``Ah = e^{A h}`` and
    ``G0 = int_0^h e^{A s} ds inputs``; with ``ramp`` also the response ``G1`` to the unit
    ramp ``s / h``: blocks of the Van Loan exponential
    ``expm([[A h, inputs h, 0], [0, 0, I], [0, 0, 0]])``, by ``expm_batched``
    (``tests/test_nl_kernels.py`` checks it against scipy's ``expm``).  ``h`` may be a
    scalar or one step per system.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s)
    inputs : ndarray, shape (nb, s, m)
    h : float or ndarray, shape (nb,)
        Step, s.
    ramp : bool
        Also return the response to the unit ramp ``t / h`` over the step.

    Returns
    -------
    Ah : ndarray, shape (nb, s, s)
    G0 : ndarray, shape (nb, s, m)
    G1 : ndarray, shape (nb, s, m)
        Only with ``ramp=True``.
    """
    nb, s, _ = A.shape
    m = inputs.shape[-1]
    hb = np.broadcast_to(np.asarray(h, dtype=float), (nb,))[:, None, None]
    size = s + m + (m if ramp else 0)
    Z = np.zeros((nb, size, size))
    Z[:, :s, :s] = A * hb
    Z[:, :s, s : s + m] = inputs * hb
    if ramp:
        Z[:, s : s + m, s + m :] = np.eye(m)
    E = expm_batched(Z)
    if ramp:
        return E[:, :s, :s], E[:, :s, s : s + m], E[:, :s, s + m :]
    return E[:, :s, :s], E[:, :s, s : s + m]
