"""Compiled inner loops (numba) for the batched linear recursion.

Two kernels run a batch of parameter sets at once, with the batch ("lane") index innermost
and contiguous so that the compiler vectorises across parameter sets (SIMD across emcee
walkers).  LLVM proves such a loop free of dependences only when the lane width and the
row strides are compile-time constants, so the kernel source is generated for each shape
with the state loop unrolled, compiled once, and cached in memory.  Batches are padded to
a power of two (at most ``MAX_WIDTH``) and longer batches are split into chunks.

``direct`` runs ``x[k+1] = Ad x[k] + Bd u[k]`` on the full state (``s^2 + s`` multiply-adds
a step).  ``modal`` runs the same recursion in scaled complex modal coordinates, one
complex scalar recursion ``w[k+1] = mu w[k] + u[k]`` per underdamped mode and
``y = Re(G w)`` (``5 m + 2 m n_out`` multiply-adds a step), which is about twice as fast.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

MAX_WIDTH = 64

#: Byte alignment of the blocks the kernels read and write, the width of an AVX-512
#: vector: a row of lanes that starts off it makes every vector load or store straddle
#: two cache lines (numpy and numba align to 16 and 32 bytes, so a fresh block lands on
#: 64 or not by the allocator's history).  Measured (26 Nov 2026, docs/performance.md):
#: the linear simulator on 64 sets 11.6 us per evaluation with its modal parameter block
#: on 64 bytes, 17.0-18.5 us on 8, 16, 32 or 48; the Coulomb kernel 192 against 211 us.
ALIGN_BYTES = 64


def aligned_empty(shape, dtype=float) -> np.ndarray:
    """An uninitialised C-contiguous array of ``shape`` starting on ``ALIGN_BYTES`` (a view
    into a slightly larger allocation)."""
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(d) for d in shape)
    itemsize = np.dtype(dtype).itemsize
    size = int(np.prod(shape))
    buf = np.empty(size + ALIGN_BYTES // itemsize, dtype)
    start = (-buf.ctypes.data % ALIGN_BYTES) // itemsize
    return buf[start : start + size].reshape(shape)

_JIT = dict(fastmath=False, boundscheck=False, error_model="numpy", nogil=True)


def padded_width(nb: int) -> int:
    """Kernel width used for a batch of ``nb`` parameter sets (power of two <= MAX_WIDTH)."""
    w = 1
    while w < min(nb, MAX_WIDTH):
        w *= 2
    return w


def _compile(lines: list[str], label: str):
    namespace: dict = {}
    # The source is generated from integers only (shapes), never from user text.
    exec(compile("\n".join(lines), f"<bayesmodal {label}>", "exec"), namespace)  # noqa: S102
    return njit(**_JIT)(namespace["kernel"])


@functools.lru_cache(maxsize=64)
def direct_kernel(n_states: int, n_out: int, width: int):
    """Compiled ``kernel(P, u, X, Y)`` for the full-state recursion.

    Flat float64 arrays: ``P`` ``(s*s + s, width)`` with rows ``i*s + j`` = ``Ad[i, j]`` and
    rows ``s*s + i`` = ``Bd[i]``; ``u`` ``(N,)``; ``X`` ``(s, width)`` state, updated in place;
    ``Y`` ``(N, n_out, width)`` with ``Y[k] = X[:n_out]`` before step ``k``.
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
    return _compile(lines, f"direct s={s} o={n_out} w={w}")


def _modal_state_and_outputs(nm: int, n_out: int, w: int, row0: int,
                             feed: bool = False) -> list[str]:
    """Kernel lines loading each mode's state ``wr, wi`` of lane ``b`` and writing the
    outputs ``Y = Re(sum_m q_m w_m)``, the output residues ``q`` from row ``row0`` of
    ``Q`` on (shared by the uniform-step and the per-step modal kernels); ``feed`` adds
    ``D[i] u[k]`` (rows of ``D`` per output)."""
    lines = []
    for m in range(nm):
        lines.append(f"            wr{m} = W[{2 * m * w} + b]")
        lines.append(f"            wi{m} = W[{(2 * m + 1) * w} + b]")
    for i in range(n_out):
        terms = " + ".join(
            f"Q[{(row0 + 2 * (i * nm + m)) * w} + b] * wr{m}"
            f" - Q[{(row0 + 2 * (i * nm + m) + 1) * w} + b] * wi{m}"
            for m in range(nm)
        )
        if feed:
            terms += f" + D[{i * w} + b] * uk"
        lines.append(f"            Y[yo + {i * w} + b] = {terms}")
    return lines


@functools.lru_cache(maxsize=64)
def modal_kernel(n_modes: int, n_out: int, width: int):
    """Compiled ``kernel(Q, u, W, Y)`` for the scaled modal recursion.

    Flat float64 arrays: ``Q`` rows ``2m, 2m+1`` = real, imaginary part of the discrete
    pole ``mu_m``; rows ``2*n_modes + 2*(i*n_modes + m) (+1)`` = real (imaginary) part of
    the output gain ``G[i, m]``; ``W`` ``(2*n_modes, width)`` modal state (real, imaginary
    interleaved by mode), updated in place; ``Y`` as for the direct kernel, with
    ``Y[k, i] = sum_m Re(G[i, m] w_m[k])``.
    """
    nm, w = n_modes, width
    lines = [
        "def kernel(Q, u, W, Y):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
    ]
    lines += _modal_state_and_outputs(nm, n_out, w, 2 * nm)
    for m in range(nm):
        lines.append(f"            mr = Q[{2 * m * w} + b]")
        lines.append(f"            mi = Q[{(2 * m + 1) * w} + b]")
        lines.append(f"            W[{2 * m * w} + b] = mr * wr{m} - mi * wi{m} + uk")
        lines.append(f"            W[{(2 * m + 1) * w} + b] = mi * wr{m} + mr * wi{m}")
    return _compile(lines, f"modal m={nm} o={n_out} w={w}")


@functools.lru_cache(maxsize=64)
def modal_feed_kernel(n_modes: int, n_out: int, width: int):
    """Compiled ``kernel(Q, u, W, D, Y)``: :func:`modal_kernel` with a feedthrough of the
    input, ``Y[k, i] = sum_m Re(G[i, m] w_m[k]) + D[i] u[k]`` (``D`` ``(n_out, width)``
    flat: acceleration outputs carry the force of the input held from the sample)."""
    nm, w = n_modes, width
    lines = [
        "def kernel(Q, u, W, D, Y):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
    ]
    lines += _modal_state_and_outputs(nm, n_out, w, 2 * nm, feed=True)
    for m in range(nm):
        lines.append(f"            mr = Q[{2 * m * w} + b]")
        lines.append(f"            mi = Q[{(2 * m + 1) * w} + b]")
        lines.append(f"            W[{2 * m * w} + b] = mr * wr{m} - mi * wi{m} + uk")
        lines.append(f"            W[{(2 * m + 1) * w} + b] = mi * wr{m} + mr * wi{m}")
    return _compile(lines, f"modal feed m={nm} o={n_out} w={w}")


@functools.lru_cache(maxsize=64)
def modal_sums_kernel(n_modes: int, n_out: int, width: int):
    """Compiled ``kernel(Q, u, W, y, S)``: the modal recursion of :func:`modal_kernel` that,
    instead of storing the outputs, accumulates the residual sums against a record.

    ``y`` ``(N, n_out)`` flat, the measured outputs; ``S`` ``(4 * n_out, width)`` flat, rows
    ``i``, ``n_out + i``, ``2 n_out + i``, ``3 n_out + i`` = ``sum_{k>=1} r_k^2``,
    ``sum_{k>=1} r_k r_{k-1}``, ``r_0`` and ``r_{N-1}`` of output ``i``, with
    ``r_k = y_k - Re(G w[k])`` evaluated exactly as the stored output minus ``y`` would be
    (the sums of ``_resid_kernels``, bit for bit, without writing the (N, n_out, width)
    prediction to memory and reading it back).  The first two row blocks must be zero.
    """
    return _modal_sums(n_modes, n_out, width, affine=False)


@functools.lru_cache(maxsize=64)
def modal_affine_sums_kernel(n_modes: int, n_out: int, width: int):
    """Compiled ``kernel(Q, u, W, V, GV, y, S)``: as :func:`modal_sums_kernel` for the
    prediction ``g (a + v0 b)`` with ``a`` the response to ``u`` (modal state ``W``) and
    ``b`` the response to a constant 1 (state ``V``), both from the same modal form;
    ``GV`` ``(2, width)`` flat holds ``g`` and ``v0`` per lane.  Bit for bit the sums of
    ``_resid_kernels.ar1_sums_affine`` of the two stored responses.
    """
    return _modal_sums(n_modes, n_out, width, affine=True)


def _modal_sums(nm: int, no: int, w: int, affine: bool):
    def terms(i, s):
        return " + ".join(
            f"Q[{(2 * nm + 2 * (i * nm + m)) * w} + b] * {s}r{m}"
            f" - Q[{(2 * nm + 2 * (i * nm + m) + 1) * w} + b] * {s}i{m}"
            for m in range(nm))

    def body(first: bool) -> list[str]:
        out = []
        for m in range(nm):
            out.append(f"            wr{m} = W[{2 * m * w} + b]")
            out.append(f"            wi{m} = W[{(2 * m + 1) * w} + b]")
            if affine:
                out.append(f"            vr{m} = V[{2 * m * w} + b]")
                out.append(f"            vi{m} = V[{(2 * m + 1) * w} + b]")
        if affine:
            out.append("            g = GV[b]")
            out.append(f"            v0 = GV[{w} + b]")
        for i in range(no):
            out.append(f"            yh = {terms(i, 'w')}")
            if affine:
                out.append(f"            bh = {terms(i, 'v')}")
                out.append(f"            r = y[yo + {i}] - g * (yh + v0 * bh)")
            else:
                out.append(f"            r = y[yo + {i}] - yh")
            if first:
                out.append(f"            S[{(2 * no + i) * w} + b] = r")
            else:
                out.append(f"            p = S[{(3 * no + i) * w} + b]")
                out.append(f"            S[{i * w} + b] += r * r")
                out.append(f"            S[{(no + i) * w} + b] += r * p")
            out.append(f"            S[{(3 * no + i) * w} + b] = r")
        for m in range(nm):
            out.append(f"            mr = Q[{2 * m * w} + b]")
            out.append(f"            mi = Q[{(2 * m + 1) * w} + b]")
            out.append(f"            W[{2 * m * w} + b] = mr * wr{m} - mi * wi{m} + uk")
            out.append(f"            W[{(2 * m + 1) * w} + b] = mi * wr{m} + mr * wi{m}")
            if affine:
                out.append(f"            V[{2 * m * w} + b] = mr * vr{m} - mi * vi{m} + 1.0")
                out.append(f"            V[{(2 * m + 1) * w} + b] = mi * vr{m} + mr * vi{m}")
        return out

    args = "Q, u, W, V, GV, y, S" if affine else "Q, u, W, y, S"
    lines = [f"def kernel({args}):", "    uk = u[0]", "    yo = 0",
             f"    for b in range({w}):"]
    lines += [ln[4:] for ln in body(True)]
    lines += ["    for k in range(1, u.shape[0]):", "        uk = u[k]",
              f"        yo = k * {no}", f"        for b in range({w}):"]
    lines += body(False)
    return _compile(lines, f"modal {'affine ' if affine else ''}sums m={nm} o={no} w={w}")


@functools.lru_cache(maxsize=64)
def direct_steps_kernel(n_states: int, n_out: int, width: int):
    """Compiled ``kernel(P, idx, u, X, Y)``: the full-state recursion of
    :func:`direct_kernel` with a discretisation per step.

    ``P`` holds one block of ``s*s + s`` rows (laid out as :func:`direct_kernel`'s) per
    distinct step; ``idx`` (int64, shape (N,)) the block of step ``k -> k+1`` (its last
    entry is not used).
    """
    s, w = n_states, width
    rows = s * s + s
    lines = [
        "def kernel(P, idx, u, X, Y):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        # a view at the step's block: its indices are then provably non-negative (a
        # runtime offset inside the index keeps numba's wraparound test in the lane
        # loop, which then does not vectorise: 3.7 times slower)
        f"        Pj = P[idx[k] * {rows * w}:]",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
    ]
    lines += [f"            x{i} = X[{i * w} + b]" for i in range(s)]
    lines += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        terms = " + ".join(f"Pj[{(i * s + j) * w} + b] * x{j}" for j in range(s))
        lines.append(f"            X[{i * w} + b] = Pj[{(s * s + i) * w} + b] * uk + {terms}")
    return _compile(lines, f"direct steps s={s} o={n_out} w={w}")


@functools.lru_cache(maxsize=64)
def modal_steps_kernel(n_modes: int, n_out: int, width: int):
    """Compiled ``kernel(Q, idx, u, W, Y)``: the scaled modal recursion of
    :func:`modal_kernel` with a discrete pole and an input weight per step,
    ``w[k+1] = mu_j w[k] + r_j u[k]`` for the step's block ``j = idx[k]``.

    ``Q`` rows ``2 (i*n_modes + m) (+1)``: real (imaginary) part of the output gain
    ``G[i, m]``; then one block of ``4 n_modes`` rows per distinct step: rows ``2m, 2m+1``
    the pole ``mu_m``, rows ``2 n_modes + 2m (+1)`` the input weight ``r_m`` (1 for the
    step the gains are scaled to, where the recursion is :func:`modal_kernel`'s to the
    last bit).  ``idx`` int64, shape (N,) (its last entry is not used).
    """
    nm, w = n_modes, width
    g_rows = 2 * nm * n_out
    lines = [
        "def kernel(Q, idx, u, W, Y):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        f"        Qj = Q[{g_rows * w} + idx[k] * {4 * nm * w}:]",  # as direct_steps_kernel
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
    ]
    lines += _modal_state_and_outputs(nm, n_out, w, 0)
    for m in range(nm):
        lines.append(f"            mr = Qj[{2 * m * w} + b]")
        lines.append(f"            mi = Qj[{(2 * m + 1) * w} + b]")
        lines.append(f"            rr = Qj[{(2 * nm + 2 * m) * w} + b]")
        lines.append(f"            ri = Qj[{(2 * nm + 2 * m + 1) * w} + b]")
        lines.append(f"            W[{2 * m * w} + b] = mr * wr{m} - mi * wi{m} + rr * uk")
        lines.append(f"            W[{(2 * m + 1) * w} + b] = mi * wr{m} + mr * wi{m} + ri * uk")
    return _compile(lines, f"modal steps m={nm} o={n_out} w={w}")
