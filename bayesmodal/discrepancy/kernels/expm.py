"""Batched matrix exponentials and the exact zero-order hold of many systems at once."""

from __future__ import annotations

import functools
import math

import numpy as np

from ._codegen import (
    _compile,
)

#: Scaled norm bound and Taylor degree: theta^(m+1) / (m+1)! = 2.3e-17 relative error.
_EXPM_THETA = 0.5
_EXPM_DEGREE = 14


@functools.lru_cache(maxsize=16)
def _expm_kernel(d: int):
    """Compiled ``kernel(X, n_squarings, E, X2, X3, X4, T)`` for (d, d, W) stacks.

    ``E = T_14(X)^(2^s)`` with ``T_14`` the degree-14 Taylor polynomial evaluated by
    Paterson-Stockmeyer (``X^2, X^3, X^4`` and three products in ``X^4``: six matrix
    products instead of thirteen) and ``s = n_squarings[b]`` (int, shape (W,)) for lane
    ``b``, whose ``X`` is already scaled by ``2^-s``; the other arrays are work space.
    The inner products are unrolled so that the lane loop (last axis) is innermost and
    vectorised.
    """
    c = [1.0 / math.factorial(k) for k in range(_EXPM_DEGREE + 1)]

    def product(out, a, m):
        terms = " + ".join(f"{a}[i, {k}, b] * {m}[{k}, j, b]" for k in range(d))
        return [f"    for i in range({d}):",
                f"        for j in range({d}):",
                "            for b in range(W):",
                f"                {out}[i, j, b] = {terms}"]

    def combination(out, j0):
        # out = sum_i c[j0 + i] X^i, i = 0..3 (only the terms up to the degree)
        pw = ["", "X", "X2", "X3"]
        terms = [f"{c[j0 + i]!r} * {pw[i]}[i, j, b]" for i in range(1, 4)
                 if j0 + i <= _EXPM_DEGREE]
        return [f"    for i in range({d}):",
                f"        for j in range({d}):",
                f"            one = {c[j0]!r} if i == j else 0.0",
                "            for b in range(W):",
                f"                {out}[i, j, b] = one + " + " + ".join(terms)]

    L = ["def kernel(X, n_squarings, E, X2, X3, X4, T):", "    W = X.shape[2]"]
    L += product("X2", "X", "X") + product("X3", "X2", "X") + product("X4", "X2", "X2")
    L += combination("E", 12)
    for j0 in (8, 4, 0):
        L += product("T", "E", "X4")
        L += combination("E", j0)
        L += [f"    for i in range({d}):",
              f"        for j in range({d}):",
              "            for b in range(W):",
              "                E[i, j, b] += T[i, j, b]"]
    L += ["    for q in range(n_squarings.max()):"]
    L += ["    " + line for line in product("T", "E", "E")]
    L += [f"        for i in range({d}):",
          f"            for j in range({d}):",
          "                for b in range(W):",
          "                    E[i, j, b] = T[i, j, b] if q < n_squarings[b] else E[i, j, b]"]
    return _compile(L, f"<bayesmodal expm d={d}>")


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
    >>> float(expm_batched(np.array([[[1.0]]]))[0, 0, 0])  # e
    2.718281828459045
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
    _expm_kernel(d)(X, s, E, *(np.empty_like(X) for _ in range(4)))
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
