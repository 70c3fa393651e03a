"""Compiled inner loops (numba) for the batched linear recursion.

The recursion ``x[k+1] = Ad x[k] + Bd u[k]`` is run for a whole batch of parameter sets at
once with the batch index innermost and contiguous, so that the compiler vectorises across
parameter sets (SIMD across emcee walkers).  LLVM only proves the loop free of
dependences when the batch width and the row strides are compile-time constants, so the
kernel source is generated for each ``(n_states, n_out, width)`` with the state loop
unrolled, compiled once and kept in a small in-memory cache.  Batches are padded to a power
of two (at most ``MAX_WIDTH``) and longer batches are split into chunks.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

MAX_WIDTH = 64


def padded_width(nb: int) -> int:
    """Kernel width used for a batch of ``nb`` parameter sets (power of two <= MAX_WIDTH)."""
    w = 1
    while w < min(nb, MAX_WIDTH):
        w *= 2
    return w


@functools.lru_cache(maxsize=64)
def recursion_kernel(n_states: int, n_out: int, width: int):
    """Return a compiled kernel ``kernel(P, u, X, Y)``.

    Layout (all flat, float64, C order):

    - ``P``: ``(n_states * n_states + n_states, width)``, rows ``i * n_states + j`` hold
      ``Ad[i, j]`` and rows ``n_states**2 + i`` hold ``Bd[i]`` for each batch lane;
    - ``u``: ``(N,)`` input samples;
    - ``X``: ``(n_states, width)`` state, updated in place (initial state in, final out);
    - ``Y``: ``(N, n_out, width)`` outputs, ``Y[k] = X[:n_out]`` before step ``k``.
    """
    s, w = n_states, width
    lines = [
        "def kernel(P, u, X, Y):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
    ]
    lines += [f"            x{i} = X[{i * w} + b]" for i in range(s)]
    lines += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        terms = " + ".join(f"P[{(i * s + j) * w} + b] * x{j}" for j in range(s))
        lines.append(f"            X[{i * w} + b] = P[{(s * s + i) * w} + b] * uk + {terms}")
    namespace: dict = {}
    exec(compile("\n".join(lines), f"<bayesmodal recursion s={s} o={n_out} w={w}>", "exec"), namespace)  # noqa: S102 - generated from integers only
    return njit(fastmath=False, boundscheck=False, error_model="numpy", nogil=True)(
        namespace["kernel"]
    )


def run_recursion(
    Ad: np.ndarray, Bd: np.ndarray, u: np.ndarray, x0: np.ndarray, n_out: int
) -> np.ndarray:
    """Batched ``x[k+1] = Ad x[k] + Bd u[k]``; outputs the first ``n_out`` states.

    Parameters
    ----------
    Ad : ndarray, shape (nb, s, s)
    Bd : ndarray, shape (nb, s)
    u : ndarray, shape (N,)
    x0 : ndarray, shape (nb, s)
    n_out : int

    Returns
    -------
    y : ndarray, shape (nb, N, n_out)
        A view of a buffer laid out as (chunk, N, n_out, width).
    """
    nb, s, _ = Ad.shape
    u = np.ascontiguousarray(u, dtype=np.float64)
    N = u.shape[0]
    width = padded_width(nb)
    n_chunks = -(-nb // width)
    kernel = recursion_kernel(s, n_out, width)
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        P = np.empty((s * s + s, width))
        P[: s * s] = Ad[lanes].reshape(width, s * s).T
        P[s * s :] = Bd[lanes].T
        X = np.ascontiguousarray(x0[lanes].T)
        kernel(P.ravel(), u, X.ravel(), Y[c].reshape(-1))
    # (chunk, N, out, lane) -> (chunk*lane, N, out); a view when there is one chunk
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]
