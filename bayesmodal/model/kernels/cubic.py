"""Cubic (hardening or softening) springs, and an end stop on the driven cart: the
batched kernel of position-dependent spring forces."""

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
    run_batched,
    sensor_lines,
    with_sensors,
)
from .stop import checked_side, stop_force_lines


# cubic spring stiffness (and the end stop)
def chain_springs(n: int) -> tuple[tuple[int, int], ...]:
    """The chain's springs: spring ``i`` joins cart ``i`` and ``i + 1``, the last one joins
    cart ``n - 1`` to the frame (``-1``)."""
    return tuple((i, i + 1 if i < n - 1 else -1) for i in range(n))


def checked_springs(springs, n: int) -> tuple[tuple[int, int], ...]:
    """``springs`` as a tuple of integer pairs in ``-1..n-1`` (only these reach generated
    source), each with at least one end on a cart."""
    out = tuple((int(a), int(b)) for a, b in springs)
    for a, b in out:
        if not (-1 <= a < n and -1 <= b < n) or a == b:
            raise ValueError(f"spring ends must be distinct carts 0..{n - 1} or -1, got "
                             f"{(a, b)}")
    return out


def _cubic_force_lines(t: str, n: int, src: str, dst: str, stop: int = 0,
                       springs=None) -> list[str]:
    # spring i joins carts a and b (-1: the frame or a clamped cart); its extension is
    # d_i = x_b - x_a and it pulls cart a with k3_i d_i^3 and cart b with -k3_i d_i^3.
    # The chain (default): a = i, b = i + 1, the last spring to the frame.
    springs = chain_springs(n) if springs is None else springs
    lines = []
    for i, (a, b) in enumerate(springs):
        if a >= 0 and b >= 0:
            d = f"({src}{b} - {src}{a})"
        else:
            d = f"({src}{b})" if a < 0 else f"(-{src}{a})"
        lines += [f"{t}e{i} = {d}", f"{t}c{i} = k3_{i} * e{i} * e{i} * e{i}"]
    for j in range(n):
        plus = [f"c{i}" for i, (a, _) in enumerate(springs) if a == j]
        minus = [f"c{i}" for i, (_, b) in enumerate(springs) if b == j]
        terms = (plus[0] if plus else ("-" + minus.pop(0) if minus else "0.0"))
        terms += "".join(f" + {c}" for c in plus[1:]) + "".join(f" - {c}" for c in minus)
        lines.append(f"{t}{dst}{j} = {terms}")
    if stop:
        lines += stop_force_lines(t, src, dst, stop, "xq", "kq")
    return lines


@functools.lru_cache(maxsize=16)
def cubic_kernel(n: int, width: int, per_lane: bool = False, stop: int = 0,
                 springs: tuple[tuple[int, int], ...] | None = None,
                 outputs: tuple[tuple[int, int], ...] | None = None,
                 columns: tuple[tuple[int, ...], ...] | None = None):
    """Compiled cubic-spring kernel (see ``cubic_run``); ``per_lane``: see ``_lane_inputs``;
    ``stop`` (+1 or -1): with the end stop of that side on cart 1 (rows ``xq``, ``kq``);
    ``springs``: the springs' ends (``cubic_run``), default the chain's; ``outputs``: the
    sensors ``(k, order)`` read at each sample (``sensor_lines``: rows ``oc``, ``od``,
    ``oe`` of the acceleration sensors), default the cart positions; ``columns``: the
    states each acceleration row involves (``sensor_lines``)."""
    stop = checked_side(stop) if stop else 0
    chain = springs is None or tuple(springs) == chain_springs(n)
    springs = chain_springs(n) if chain else checked_springs(springs, n)
    s, w, q = 2 * n, width, len(springs)
    R, C = range(s), range(n)
    rows = [("A", s * s), ("bh", s), ("p", s * n), ("q", s * n), ("k3", q)]
    rows += [("xq", 1), ("kq", 1)] if stop else []
    if outputs is not None:
        outputs = checked_outputs(outputs, n)
        n_acc = sum(order == 2 for _, order in outputs)
        columns = None if columns is None else checked_columns(columns, n_acc, s)
        n_c = n_acc * s if columns is None else sum(map(len, columns))
        rows += [("oc", n_c), ("od", n_acc), ("oe", n_acc)] if n_acc else []
    P = _Rows("P", w, rows)
    X = _Rows("X", w, [("x", s)])

    def step(t: str, read: bool) -> list[str]:
        # one ETD2RK sub-step of a lane; with ``read`` each sensor is read at its start,
        # from the state and the forces the predictor evaluates there anyway
        L = [f"{t}x{r} = {X('x', r)}" for r in R]
        L += [f"{t}k3_{i} = {P('k3', i)}" for i in range(q)]
        if stop:
            L += [f"{t}xq = {P('xq')}", f"{t}kq = {P('kq')}"]
        L += _cubic_force_lines(t, n, "x", "f", stop, springs)
        if read:
            L += sensor_lines(t, outputs, n, s, P, [("od", "uk")], force="f",
                              columns=columns)
        for r in R:
            prods = ([(P('A', r * s + j), f"x{j}") for j in R]
                     + [(P('p', r * n + j), f"f{j}") for j in C])
            L.append(f"{t}y{r} = {_fma_sum(P('bh', r) + ' * uk', prods)}")
        L += _cubic_force_lines(t, n, "y", "g", stop, springs)
        for r in R:
            prods = [(P('q', r * n + j), f"(g{j} - f{j})") for j in C]
            L.append(f"{t}{X('x', r)} = {_fma_sum(f'y{r}', prods)}")
        return L

    if outputs is None:
        L = _head("P, X, u, n_sub, Y", n, w, X, per_lane)
        L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
        L += step("                ", False)
    else:  # the first sub-step reads the sensors: the head's own loop is left out
        L = _head("P, X, u, n_sub, Y", len(outputs), w, X, per_lane)[: -len(outputs)]
        L += step("            ", True)
        L += ["        for sub in range(1, n_sub):", f"            for b in range({w}):"]
        L += step("                ", False)
    tag = f" stop{stop:+d}" if stop else ""
    tag += "" if chain else " springs=" + ",".join(f"{a}:{b}" for a, b in springs)
    tag += "" if outputs is None else " outputs=" + ",".join(f"{k}:{o}" for k, o in outputs)
    tag += "" if columns is None else f" columns={columns}"
    if per_lane:
        return _compile(_lane_inputs(L, w), f"<bayesmodal cubic n={n} w={w} per-lane{tag}>")
    return _compile(L, f"<bayesmodal cubic n={n} w={w}{tag}>")


def cubic_run(Ah, Bh, F0h, F1h, k3, u, n_sub, x0, stop=None, springs=None, outputs=None,
              out_map=None, columns=None):
    """Cubic spring forces ``k3_i d_i^3`` by the exponential Runge-Kutta scheme ETD2RK.

    Predictor with the force held over the sub-step (``F0h``), corrector with the force
    ramped linearly between its values at both ends (``F1h``, the response to the unit
    ramp ``s / h``); second-order in the nonlinear part, exact in the linear part.

    Parameters
    ----------
    Ah : ndarray, shape (nb, s, s)
    Bh : ndarray, shape (nb, s)
    F0h, F1h : ndarray, shape (nb, s, n)
        Response to a held and to a ramped force on each cart over a sub-step.
    k3 : ndarray, shape (nb, n_springs)
        Cubic stiffness of each spring, N/m^3.
    u : ndarray, shape (N,)
    n_sub : int
    x0 : ndarray, shape (nb, s)
    stop : tuple (side, x_stop, k_stop), optional
        An end stop on cart 1 (``kernels.stop``): side +1 or -1, ``x_stop`` (nb,) m and
        ``k_stop`` (nb,) N/m; its force enters with the spring forces.
    springs : tuple of (int, int), optional
        Ends ``(a, b)`` of each spring (carts ``0..n-1``, ``-1`` for the frame), its
        extension ``x_b - x_a``; default the chain's (``chain_springs``).
    outputs : ndarray of int, shape (n_out, 2), optional
        Sensors ``(k, order)`` to read (``effects._linear.sensor_spec``), with
    out_map : tuple of ndarray
        ``(C, D, E)`` of shapes (nb, n_out, s), (nb, n_out), (nb, n_out, n): the readings
        are ``C x[k] + D u[k] + E f(x[k])`` with ``f`` the spring and stop forces on the
        carts at the sample (``effects._linear.sensor_map``).  Default: the cart
        positions.
    columns : tuple of tuple of int, optional
        The states each acceleration sensor's row of ``C`` can involve (the rig's
        structure, ``effects._linear.acceleration_columns``); default all.

    Returns
    -------
    ndarray, shape (nb, N, n) or (nb, N, n_out)
    """
    n = x0.shape[1] // 2
    params = [Ah, Bh, F0h, F1h, k3]
    kernel = functools.partial(cubic_kernel, n)
    if springs is not None and tuple(springs) != chain_springs(n):
        kernel = functools.partial(kernel, springs=checked_springs(springs, n))
    if stop is not None:
        side, xq, kq = stop
        params += [np.asarray(xq, float).reshape(-1, 1), np.asarray(kq, float).reshape(-1, 1)]
        kernel = functools.partial(kernel, stop=checked_side(side))
    kernel, params, n_out = with_sensors(kernel, params, outputs, out_map, columns, n)
    return run_batched(kernel, params, [x0], u, n_out, int(n_sub))
