"""Linear recursion with a shifted, clipped input per lane (delay, saturation, motor lag)."""

from __future__ import annotations

import functools

import numpy as np

from ._codegen import (
    _compile,
    _fma_sum,
    _pack,
    _pack_input,
    _Rows,
    aligned_empty,
    padded_width,
)


@functools.lru_cache(maxsize=32)
def linear_input_kernel(n_states: int, n_out: int, width: int, shifted: bool, clipped: bool,
                        per_lane: bool = False, mapped: bool = False,
                        feeds: tuple[bool, ...] | None = None):
    """Compiled ``kernel(P, X, up, shift, Y)`` for the recursion (see ``linear_input_run``).

    Without ``shifted`` every lane reads the same input sample (and ``B1`` is not used);
    without ``clipped`` the input is not clipped.  With ``per_lane`` ``up`` is a flat
    ``(N_padded, width)`` block, one input column per lane.  With ``mapped`` the outputs
    are ``C x + D1 ua + D2 ub`` (rows ``oc``, ``od1``, ``od2``: sensors of any kind),
    else the first ``n_out`` states; with ``feeds`` (sensor coordinates, one flag per
    output) an output flagged True is ``S x_i + D1 ua + D2 ub`` (rows ``os``, ``od1``,
    ``od2``, one entry per flagged output).
    """
    feeds = None if feeds is None else tuple(bool(f) for f in feeds)  # flags only
    s, w = n_states, width
    rows = [("A", s * s), ("B1", s), ("B2", s), ("lo", 1), ("hi", 1)]
    if mapped:
        rows += [("oc", n_out * s), ("od1", n_out), ("od2", n_out)]
    n_fed = sum(feeds) if feeds is not None else 0
    if n_fed:
        rows += [("os", n_fed), ("od1", n_fed), ("od2", n_fed)]
    P = _Rows("P", w, rows)
    X = _Rows("X", w, [("x", s)])

    def clip(v):
        if not clipped:
            return v
        return (f"({P('lo')} if {v} < {P('lo')} else ({P('hi')} if {v} > {P('hi')}"
                f" else {v}))")

    L = [
        "def kernel(P, X, up, shift, Y):",
        "    N = Y.shape[0] // " + str(n_out * w),
        f"    off = up.shape[0] // {w} - N" if per_lane else "    off = up.shape[0] - N",
        "    for k in range(N):",
        f"        yo = k * {n_out * w}",
        "        uk = up[k + off]" if not per_lane else "        ko = (k + off) * " + str(w),
        f"        for b in range({w}):",
    ]
    if per_lane:
        L += ["            uk = up[ko + b]"]
    lane = f" * {w} + b" if per_lane else ""
    if shifted:
        L += ["            j = k + shift[b]",
              f"            ua = {clip(f'up[j{lane}]')}",
              f"            ub = {clip(f'up[(j + 1){lane}]' if per_lane else 'up[j + 1]')}"]
    else:
        L += [f"            ub = {clip('uk')}"]
    L += [f"            x{i} = {X('x', i)}" for i in range(s)]
    if mapped:
        for i in range(n_out):
            prods = [(P('oc', i * s + j), f"x{j}") for j in range(s)]
            if shifted:
                prods.insert(0, (P('od1', i), "ua"))
            L.append(f"            Y[yo + {i * w} + b] = "
                     f"{_fma_sum(P('od2', i) + ' * ub', prods)}")
    elif n_fed:
        a = 0
        for i in range(n_out):
            if not feeds[i]:
                L.append(f"            Y[yo + {i * w} + b] = x{i}")
                continue
            prods = [(P('od1', a), "ua")] if shifted else []
            prods.append((P('os', a), f"x{i}"))
            L.append(f"            Y[yo + {i * w} + b] = "
                     f"{_fma_sum(P('od2', a) + ' * ub', prods)}")
            a += 1
    else:
        L += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        prods = [(P('A', i * s + j), f"x{j}") for j in range(s)]
        if shifted:
            prods.insert(0, (P('B1', i), "ua"))
        L.append(f"            {X('x', i)} = {_fma_sum(P('B2', i) + ' * ub', prods)}")
    return _compile(L, f"<bayesmodal linear-input s={s} o={n_out} w={w} "
                       f"shift={shifted} clip={clipped} per_lane={per_lane} mapped={mapped} "
                       f"feeds={feeds}>")


def linear_input_run(Ad, B1, B2, u, x0, n_out, *, shift=None, level=None, out_map=None,
                     feeds=None):
    """Batched ``x[k+1] = Ad x[k] + B1 v[k - m - 1] + B2 v[k - m]``, ``v = clip(u, +-level)``.

    Parameters
    ----------
    Ad : ndarray, shape (nb, s, s)
    B1, B2 : ndarray, shape (nb, s)
    u : ndarray, shape (N,) or (nb, N)
        Input, zero before the first sample; shared or one row per lane.
    x0 : ndarray, shape (nb, s)
    n_out : int
        Number of leading states returned.
    shift : ndarray of int, shape (nb,), optional
        Whole-sample delay ``m >= 0`` of each lane (default 0).
    level : ndarray, shape (nb,), optional
        Clip level of each lane (default: no clipping).
    out_map : tuple of ndarray, optional
        ``(C, D1, D2)`` of shapes (nb, n_out, s), (nb, n_out), (nb, n_out): the outputs are
        ``y[k] = C x[k] + D1 v[k - m - 1] + D2 v[k - m]`` (sensors of any kind,
        ``effects._linear.sensor_map``); ``n_out`` is then ``C.shape[1]``.  Default: the
        first ``n_out`` states.
    feeds : tuple of bool, optional
        Instead of ``out_map``, with the state in sensor coordinates (the first ``n_out``
        states are the readings): which outputs add ``S x_i + D1 ... + D2 ...``; then
        ``out_map`` is ``(S, D1, D2)``, each (nb, sum(feeds)).

    Returns
    -------
    ndarray, shape (nb, N, n_out)
    """
    nb, s, _ = Ad.shape
    N = u.shape[-1]
    per_lane = u.ndim == 2
    shifted = shift is not None or bool(np.any(B1 != 0.0))
    m = np.zeros(nb, np.int64) if shift is None else np.minimum(shift, N).astype(np.int64)
    clipped = level is not None
    lvl = np.full(nb, np.inf) if level is None else np.asarray(level, dtype=float)
    pad = int(m.max()) + 1
    # up[k + pad - m - 1] = v[k - m - 1]
    up = np.concatenate([np.zeros(u.shape[:-1] + (pad,)), u], axis=-1)
    width = padded_width(nb)
    n_chunks = -(-nb // width)
    mapped = out_map is not None and feeds is None
    params = [Ad, B1, B2, -lvl, lvl]
    if mapped:
        n_out = out_map[0].shape[1]
    if out_map is not None and (mapped or any(feeds)):
        params += list(out_map)
    feeds = None if feeds is None else tuple(bool(f) for f in feeds)
    kernel = linear_input_kernel(s, n_out, width, shifted, clipped, per_lane, mapped, feeds)
    Y = aligned_empty(n_chunks * N * n_out * width).reshape(n_chunks, N, n_out, width)
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)
        P = _pack(params, lanes)
        X = _pack([x0], lanes)
        kernel(P, X, _pack_input(up, lanes), np.ascontiguousarray(pad - 1 - m[lanes]),
               Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]
