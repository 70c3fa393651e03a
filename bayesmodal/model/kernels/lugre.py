"""Compiled kernel (numba) of the LuGre friction model, batched across parameter sets.

The bristle deflection ``z_i`` of cart ``i`` obeys ``z' = v - a(v) z`` with
``a(v) = sigma0 |v| / g(v)``; over a sub-step ``h`` with the velocity frozen at ``v`` this
is solved exactly::

    z(h) = z0 E + z_ss (1 - E),      E = exp(-a h),  z_ss = sign(v) g(v) / sigma0,
    mean of z over the step = z0 phi + z_ss (1 - phi),   phi = (1 - E) / (a h),

so the stiff bristle relaxation (``a h`` up to thousands while sliding) is stable for every
step.  The exponentials are evaluated by branch-free range reduction and a series
(``_exp``) so that the lane loop vectorises.  The friction force
``F = sigma0 z + sigma1 z'`` is held over the sub-step at its mean,
``sigma0 mean(z) + sigma1 (z(h) - z0) / h``, and the carts are advanced by the exact
zero-order-hold step of the linear rig with that force as an input.  The velocity frozen
for the bristles is the mid-step velocity ``v0 + (h / 2) a0``, with the acceleration
``a0`` at the start taken with the last sub-step's friction force: an O(h^2) velocity,
so the scheme is second order in ``h`` with one linear step and one bristle update per
sub-step (a predictor-corrector with two of each was 1.5 times slower for 25 % less
error).  Every operation is a smooth
function of the parameters (``|v|`` and ``sign(v)`` enter only through ``a`` and
``z_ss (1 - E)``, both continuous in ``v``), so the simulated output is continuous in
them.  Layouts and batching as in ``bayesmodal.model.kernels._codegen``.
"""

from __future__ import annotations

import functools

import numpy as np

from ._codegen import (
    _compile,
    _fma_sum,
    _head,
    _lane_inputs,
    _Rows,
    checked_columns,
    checked_outputs,
    interleave,
    run_batched,
    sensor_lines,
    with_sensors,
)
from ._exp import exp_neg, one_minus_exp
from .coulomb import _staged_inputs, checked_stages
from .stop import checked_side, stop_depth_lines

#: Lanes the LuGre kernel takes through the whole record at a time, their parameters and
#: state packed together: those of 32 lanes (about 100 rows, 25 KB) stay in the
#: first-level data cache, those of 64 (50 KB) do not (docs/performance.md, 26 Nov 2026).
#: The input and the output keep the kernel's full width, so that a batch of 64 sets is
#: one chunk and its output a view, not a copy.
LANE_BLOCK = 32


def _bristles(t: str, n: int, P) -> list[str]:
    """Code of every cart's bristle state ``z1c{i}`` at the sub-step end and held friction
    force ``Fc{i}`` for the velocity ``vm{i}`` frozen over the sub-step.

    The carts are taken together stage by stage (Stribeck level, relaxation, force), their
    exponentials interleaved line by line: three independent chains side by side, and
    each series coefficient read once for the three carts."""
    C = range(n)
    L = []
    for i in C:
        L += [f"{t}e{i} = vm{i} * {P('ivs')}", f"{t}e2{i} = e{i} * e{i}"]
    # Stribeck: g = Fc + (Fs - Fc) e^{-(v/vs)^2}
    L += interleave([exp_neg(t, f"e2{i}", f"es{i}", tag=f"_s{i}") for i in C])
    for i in C:
        L += [f"{t}g{i} = fma(fx{i}, es{i}, fc{i})",  # Fc + (Fs - Fc) e^{-(v/vs)^2}
              f"{t}g{i} = g{i} if g{i} > 1e-300 else 1e-300",
              f"{t}ah{i} = s0 * abs(vm{i}) * h / g{i}"]
    # relaxation over the step: E = 1 - om, ph = om / ah
    L += interleave([one_minus_exp(t, f"ah{i}", f"om{i}", f"ph{i}", tag=f"_r{i}") for i in C])
    # with d = z0 - z_ss: z(h) = z_ss + d E and, as z(h) - z0 = -d (1 - E), the held force
    # sigma0 (z_ss + d phi) - sigma1 d (1 - E) / h = sigma0 z_ss + d (sigma0 phi - sigma1
    # (1 - E) / h)
    for i in C:
        L += [f"{t}sg{i} = math.copysign(g{i}, vm{i})",  # sigma0 z_ss
              f"{t}ss{i} = sg{i} / s0",
              f"{t}d{i} = z{i} - ss{i}",
              f"{t}z1c{i} = fma(d{i}, 1.0 - om{i}, ss{i})",
              f"{t}Fc{i} = fma(d{i}, fma(-s1 * ih, om{i}, s0 * ph{i}), sg{i})"]
    return L


def _friction_at_sample(t: str, n: int, P, X, stop: int) -> list[str]:
    """Code of the force ``fo{i}`` (N) friction and the end stop put on each cart at the
    sample, from the state there: ``-(sigma0 z + sigma1 z')`` with the bristle rate
    ``z' = v - sigma0 |v| z / g(v)`` of the LuGre equation itself (not the mean held over a
    sub-step), and the stop's ``-side k_stop max(0, side (x_1 - x_stop))``.

    Where the friction level ``g(v)`` is zero (``Fc_i = Fs_i = 0``, the null) the bristles
    carry no force: the sub-steps relax them at once to ``z = 0`` there, and ``z'`` of the
    equation at the level floored to ``1e-300`` would be a ratio of two round-offs."""
    L = [f"{t}s0 = {P('sg0')}", f"{t}s1 = {P('sg1')}"]
    for i in range(n):
        v, z = f"x{n + i}", f"z{i}"
        L += [f"{t}{z} = {X('z', i)}",
              f"{t}e{i} = {v} * {P('ivs')}", f"{t}e2{i} = e{i} * e{i}"]
        L += exp_neg(t, f"e2{i}", f"es{i}", tag=f"_s{i}")
        L += [f"{t}g{i} = fma({P('fx', i)}, es{i}, {P('fc', i)})",
              f"{t}gf{i} = g{i} if g{i} > 1e-300 else 1e-300",
              f"{t}dz{i} = {v} - s0 * abs({v}) * {z} / gf{i}",
              f"{t}fo{i} = -fma(s1, dz{i}, s0 * {z}) if g{i} > 1e-300 else 0.0"]
    if stop:
        L += stop_depth_lines(t, "x0", stop, P("xq"))
        L += [f"{t}fo0 = fo0 - {stop:+d}.0 * {P('kq')} * pq"]
    return L


@functools.lru_cache(maxsize=16)
def lugre_kernel(n: int, width: int, per_lane: bool = False, stages: tuple[str, ...] = (),
                 stop: int = 0, outputs: tuple[tuple[int, int], ...] | None = None,
                 columns: tuple[tuple[int, ...], ...] | None = None):
    """Compiled ``kernel(P, X, u, n_sub, h, Y)`` (see ``lugre_run``); ``stages`` (of
    ``kernels.coulomb.INPUT_STAGES``, shared input only) are applied to the input in the
    kernel, with parameter rows ``s0, s1, ...``; ``stop`` (+1 or -1): the end stop of that
    side on cart 1 (rows ``xq``, m, and ``kq``, N/m; ``kernels.stop``), its force held
    over each sub-step at its mid-step value and kept in cart 1's ``fr`` row for the next
    sub-step's mid-step velocity.

    Each lane's input of the sample (after the stages) is computed once, in the loop that
    writes the outputs, and kept in the state row ``u`` for the sub-steps.

    ``outputs``: the sensors ``(k, order)`` read at each sample (``sensor_lines``: rows
    ``oc``, ``od``, ``oe`` of the acceleration sensors, the friction and stop forces at the
    sample from ``_friction_at_sample``), default the cart positions; ``columns``: the
    states each acceleration row involves."""
    stages = checked_stages(stages, per_lane)
    stop = checked_side(stop) if stop else 0
    if outputs is not None:
        outputs = checked_outputs(outputs, n)
        columns = None if columns is None else checked_columns(
            columns, sum(o == 2 for _, o in outputs), 2 * n)
    s, w = 2 * n, width
    R, C = range(s), range(n)
    blk = min(w, LANE_BLOCK)
    base = (lambda name: None) if blk == w else (lambda name: name)
    P = _Rows("P", blk, [("A", s * s), ("bh", s), ("fh", s * n), ("W", n * s), ("wb", n),
                         ("wf", n), ("fc", n), ("fx", n), ("sg0", 1), ("sg1", 1), ("ivs", 1)]
              + [(f"s{j}", 1) for j in range(len(stages))]
              + ([("xq", 1), ("kq", 1)] if stop else []) + _sensor_rows(outputs, columns, s),
              base("po"))
    X = _Rows("X", blk, [("x", s), ("z", n), ("fr", n), ("u", 1)], base("xo"))
    if outputs is None:
        L = _head("P, X, u, n_sub, h, Y", n, w, X, per_lane)
    else:  # each sensor read from the state and the forces at the sample
        L = _head("P, X, u, n_sub, h, Y", len(outputs), w, X, per_lane)[: -len(outputs)]
        t = " " * 12
        L += [f"{t}x{r} = {X('x', r)}" for r in R]
        if any(o == 2 for _, o in outputs):
            L += _friction_at_sample(t, n, P, X, stop)
        L += sensor_lines(t, outputs, n, s, P, [("od", "uk")], force="fo", columns=columns)
    L[1:1] = ["    ih = 1.0 / h"]
    L.append(f"            {X('u')} = uk")
    if per_lane:
        L = _lane_inputs(L, w)
    elif stages:
        L = _staged_inputs(L, P, None, stages, None)
    L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
    t = " " * 16
    L += [f"{t}uk = {X('u')}"]
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    L += [f"{t}s0 = {P('sg0')}", f"{t}s1 = {P('sg1')}"]
    for i in C:
        L += [f"{t}z{i} = {X('z', i)}", f"{t}fc{i} = {P('fc', i)}", f"{t}fx{i} = {P('fx', i)}"]
    # the velocity at mid-step from the acceleration at the start (the friction force of
    # the last sub-step standing in for the one at its end), v + (h / 2) a = W x +
    # wb u - wf fr with the rows of ``lugre_run``
    for i in C:
        init = f"fma({P('wb', i)}, uk, -({P('wf', i)} * {X('fr', i)}))"
        L += [f"{t}vm{i} = {_fma_sum(init, [(P('W', i * s + j), f'x{j}') for j in R])}"]
    L += _bristles(t, n, P)
    if stop:
        # cart 1 at mid-step, x + (h / 4) (v + vm) (second order), and the stop's force
        # there; it joins cart 1's friction force as the force held over the sub-step
        L += [f"{t}xm0 = x0 + 0.25 * h * (x{n} + vm0)"]
        L += stop_depth_lines(t, "xm0", stop, P("xq"))
        L += [f"{t}Fc0 = Fc0 + {stop:+d}.0 * {P('kq')} * pq"]
    for r in R:
        prods = ([(P('A', r * s + j), f"x{j}") for j in R]
                 + [(P('fh', r * n + j), f"(-Fc{j})") for j in C])
        L.append(f"{t}{X('x', r)} = {_fma_sum(P('bh', r) + ' * uk', prods)}")
    L += [f"{t}{X('z', i)} = z1c{i}" for i in C]
    L += [f"{t}{X('fr', i)} = Fc{i}" for i in C]
    kind = (" per-lane" if per_lane else "".join(" " + k for k in stages)) + (
        f" stop{stop:+d}" if stop else "")
    kind += "" if outputs is None else " outputs=" + ",".join(f"{k}:{o}" for k, o in outputs)
    kind += "" if columns is None else f" columns={columns}"
    if blk < w:
        L = _lane_blocks(L, w, blk, P.size, X.size)
    return _compile(L, f"<bayesmodal lugre2 n={n} w={w}{kind}>")


def _sensor_rows(outputs, columns, s: int) -> list[tuple[str, int]]:
    """Parameter rows of the acceleration sensors (``sensor_lines``): ``oc`` (their rows
    of the state matrix, ``columns`` only if given), ``od`` (input) and ``oe`` (``1 /
    m_k``)."""
    n_acc = 0 if outputs is None else sum(o == 2 for _, o in outputs)
    if not n_acc:
        return []
    n_c = n_acc * s if columns is None else sum(map(len, columns))
    return [("oc", n_c), ("od", n_acc), ("oe", n_acc)]


def _lane_blocks(lines: list[str], width: int, block: int, p_rows: int,
                 x_rows: int) -> list[str]:
    """Kernel source taking the lanes in blocks of ``block``, each block through the whole
    record: an outer loop over the blocks, every lane loop ``b`` over the lanes of its
    block, the block's parameter and state rows (``_pack(..., block)``) at ``po + b`` and
    ``xo + b``, its input and output at ``b`` in the full width."""
    out = [lines[0], f"    for c0 in range(0, {width}, {block}):",
           f"        po = (c0 // {block}) * {p_rows * block} - c0",
           f"        xo = (c0 // {block}) * {x_rows * block} - c0"]
    for line in lines[1:]:
        line = line.replace(f"for b in range({width}):", f"for b in range(c0, c0 + {block}):")
        out.append("    " + line)
    return out


def lugre_run(Ah, Bh, Fh, G, gb, minv, Fc, Fs, sigma0, sigma1, v_stribeck, u, n_sub, h, x0,
              input_stages=(), stop=None, outputs=None, out_map=None, columns=None):
    """LuGre friction on every cart (see ``extensions.lugre``), bristles relaxed at start.

    Parameters
    ----------
    Ah : ndarray, shape (nb, s, s)
        One sub-step of the linear rig.
    Bh : ndarray, shape (nb, s)
        Response to the input held over a sub-step.
    Fh : ndarray, shape (nb, s, n)
        Response to a force held on each cart over a sub-step.
    G : ndarray, shape (nb, n, s)
        ``[-K, -C]``: spring and damper force on each cart, N.
    gb : ndarray, shape (nb, n)
        Motor force per volt on each cart, N/V.
    minv : ndarray, shape (nb, n)
        Inverse masses, 1/kg.
    Fc, Fs : ndarray, shape (nb, n)
        Coulomb and static friction levels, N.
    sigma0, sigma1, v_stribeck : ndarray, shape (nb,)
        Bristle stiffness (N/m), bristle damping (N s/m), Stribeck velocity (m/s).
    u : ndarray, shape (N,) or (nb, N)
        Input, V, held over each sample; shared or one row per lane.
    n_sub : int
        Sub-steps per sample.
    h : float
        Sub-step, s.
    x0 : ndarray, shape (nb, s)
    input_stages : sequence of (str, ndarray of shape (nb,))
        Memoryless stages (``kernels.coulomb.INPUT_STAGES``) applied in this order to the
        shared input ``u`` (N,) inside the kernel, each with its parameter per lane: bit
        for bit the same stages applied in ``effects`` to a per-lane input, without the
        ``(N, lanes)`` input block.
    stop : tuple (side, x_stop, k_stop), optional
        An end stop on cart 1 (``kernels.stop``): side +1 or -1, ``x_stop`` (nb,) m (signed
        by the side), ``k_stop`` (nb,) N/m.
    outputs : ndarray of int, shape (n_out, 2), optional
        Sensors ``(k, order)`` to read (``effects._linear.sensor_spec``), with
    out_map : tuple of ndarray
        ``(C, D, E)`` of shapes (nb, n_out, s), (nb, n_out), (nb, n_out, n): the readings
        are ``C x[k] + D u[k] + E f[k]`` with ``f`` the friction and stop forces on the
        carts at the sample's state (``effects._linear.sensor_map``; ``u`` after the
        input stages).  Default: the cart positions.
    columns : tuple of tuple of int, optional
        The states each acceleration sensor's row of ``C`` can involve
        (``effects._linear.acceleration_columns``); default all.

    Returns
    -------
    ndarray, shape (nb, N, n) or (nb, N, n_out)
        Cart positions, m, or the sensors' readings (a view of the kernel's output buffer).
    """
    nb, s = x0.shape
    n = s // 2
    # mid-step velocity v_i + (h / 2) (G_i x + gb_i u - fr_i) / m_i = W_i x + wb_i u - wf_i fr_i
    wf = 0.5 * h * np.asarray(minv, dtype=float)
    W = wf[:, :, None] * np.asarray(G, dtype=float)
    W[:, np.arange(n), n + np.arange(n)] += 1.0
    params = [Ah, Bh, Fh, W, wf * gb, wf, Fc, np.asarray(Fs) - np.asarray(Fc), sigma0, sigma1,
              1.0 / np.asarray(v_stribeck, dtype=float)]
    state = [x0, np.zeros((nb, n)), np.zeros((nb, n)), np.zeros((nb, 1))]
    kinds = tuple(kind for kind, _ in input_stages)
    if kinds and u.ndim != 1:
        raise ValueError("input stages apply to a shared input; pass u of shape (N,)")
    params += [np.asarray(values, dtype=float).reshape(-1, 1) for _, values in input_stages]
    kernel = functools.partial(lugre_kernel, n)
    if kinds:
        kernel = functools.partial(kernel, stages=kinds)
    if stop is not None:
        side, xq, kq = stop
        params += [np.asarray(xq, float).reshape(-1, 1), np.asarray(kq, float).reshape(-1, 1)]
        kernel = functools.partial(kernel, stop=checked_side(side))
    kernel, params, n_out = with_sensors(kernel, params, outputs, out_map, columns, n)
    return run_batched(kernel, params, state, u, n_out, int(n_sub), float(h),
                       lane_block=LANE_BLOCK)
