"""Coulomb friction with stick-slip: the event-corrected batched kernel."""

from __future__ import annotations

import functools

import numpy as np

from ._codegen import (
    _aligned_lines,
    _compile,
    _head,
    _lane_inputs,
    _Rows,
    checked_outputs,
    checked_zeros,
    run_batched,
)
from ._coulomb_steps import (
    _coulomb_at_rest,
    _coulomb_events,
    _coulomb_load,
    _coulomb_predict,
    _coulomb_quiet_step,
    _coulomb_read,
    _coulomb_store,
    _scratch_rows,
    _split_substep,
)
from .stop import checked_side, stop_input_lines

#: Lanes of the friction kernel that take a sample together (two AVX-512 vectors of
#: float64: LLVM does not vectorise loops of 8), and lanes with an event packed together
#: to take it again in event-corrected sub-steps; no lane's result depends on the rest of
#: its batch.
REFINE_GROUP = 16

#: The whole-sample steps the adaptive friction kernel compiles: a group of lanes none of
#: whose carts is stuck takes the ``"sliding"`` step (without the held carts' ramp
#: correction and tests), the others the ``"held"`` one; the two give the same result
#: bit for bit where both apply (``("held",)`` alone is the kernel without the split:
#: tests compare the two).
GROUP_STEPS = ("sliding", "held")

#: Memoryless input stages the friction kernel can apply itself to the shared input, in
#: the order given, each with one parameter per lane: ``offset`` (V, added), ``deadband``
#: (V, sharp), ``saturation`` (V, clip level), ``gain`` (1/V, ``v (1 + kappa |v|)``).
#: Written as numpy's own operations in ``effects`` (``transform_input``), so that the
#: kernel's input is bit for bit the per-lane input computed there, without the
#: ``(N, lanes)`` input block that costs a copy and a stream of 4 MB per chunk.
INPUT_STAGES = ("offset", "deadband", "saturation", "gain")


#: The parameter of each stage that leaves the input unchanged, bit for bit: ``v + 0``,
#: ``sign(v) max(|v| - 0, 0)``, ``clip(v, -inf, inf)`` and ``v (1 + 0 |v|)`` are ``v``.
IDENTITY_STAGES = {"offset": 0.0, "deadband": 0.0, "saturation": np.inf, "gain": 0.0}


def every_stage(input_stages, nb: int) -> tuple:
    """``input_stages`` completed to all of ``INPUT_STAGES``, the missing ones at their
    identity (``IDENTITY_STAGES``), when they are given in that order.

    One compiled friction kernel then serves every combination of memoryless input
    effects (16 lanes, idle machine: 14.7 s to compile with all four stages, 11.4 s with
    one, 10.6 s with none), at the cost of a few operations per lane and sample
    (docs/performance.md); stages given in another order are kept as they are.
    """
    kinds = [kind for kind, _ in input_stages]
    order = [INPUT_STAGES.index(k) for k in kinds if k in INPUT_STAGES]
    if len(order) != len(kinds) or order != sorted(set(order)):
        return tuple(input_stages)
    given = dict(input_stages)
    return tuple((k, given[k] if k in given else np.full(nb, IDENTITY_STAGES[k]))
                 for k in INPUT_STAGES)


def _stage_code(t: str, kind: str, p: str) -> list[str]:
    """Code applying one input stage with lane parameter ``p`` to ``uk``."""
    if kind == "offset":
        return [f"{t}uk = uk + {p}"]
    if kind == "deadband":
        # np.sign(v) * np.maximum(np.abs(v) - v_dead, 0.0); np.sign(-0.0) is 0.0
        return [f"{t}ud = abs(uk) - {p}",
                f"{t}ud = ud if ud > 0.0 else 0.0",
                f"{t}uk = (1.0 if uk > 0.0 else (-1.0 if uk < 0.0 else 0.0)) * ud"]
    if kind == "saturation":
        # np.clip(v, -level, level)
        return [f"{t}ul = {p}",
                f"{t}uk = -ul if uk < -ul else (ul if uk > ul else uk)"]
    if kind == "gain":
        return [f"{t}uk = uk * (1.0 + {p} * abs(uk))"]
    raise ValueError(f"unknown input stage {kind!r}; use one of {INPUT_STAGES}")


def checked_stages(stages, per_lane: bool) -> tuple[str, ...]:
    """``stages`` as a tuple of ``INPUT_STAGES`` names for a kernel with a shared input;
    only these names reach generated source."""
    stages = tuple(stages)
    unknown = [k for k in stages if k not in INPUT_STAGES]
    if unknown:
        raise ValueError(f"unknown input stage {unknown[0]!r}; use one of {INPUT_STAGES}")
    if stages and per_lane:
        raise ValueError("input stages apply to a shared input; pass u of shape (N,)")
    return stages


def _staged_inputs(lines: list[str], P, PP, stages: tuple[str, ...],
                   packed_from: int | None, *, stop: int = 0, n: int = 0, X=None,
                   XX=None, steps: tuple[str, str] = ("h", "h")) -> list[str]:
    """Kernel source applying ``stages`` to the shared input in every lane loop.

    The sample's raw input is read once (``u0``); each ``for b in range(...)`` loop starts
    with the lane's own transformed input ``uk`` from its parameter rows (``P``, or the
    packed copy ``PP`` in the loops after line ``packed_from``); where a loop does not use
    ``uk`` the compiler drops the code.  With ``stop`` (+1 or -1) the end stop's force on
    the driven cart is added to ``uk`` last (``kernels.stop.stop_input_lines``), from the
    lane's state (``X``, or ``XX`` after ``packed_from``: ``n`` positions, then
    velocities) and the loop's step (``steps``: before and after ``packed_from``).
    """
    out = []
    for i, line in enumerate(lines):
        if line.strip() == "uk = u[k]":
            out.append(line.replace("uk = u[k]", "u0 = u[k]"))
            continue
        out.append(line)
        if line.strip().startswith("for b in range("):
            late = packed_from is not None and i >= packed_from
            rows = PP if late else P
            t = line[: len(line) - len(line.lstrip())] + "    "
            out.append(f"{t}uk = u0")
            for j, kind in enumerate(stages):
                out += _stage_code(t, kind, rows(f"s{j}"))
            if stop:
                st = XX if late else X
                out += stop_input_lines(t, st("x", 0), st("x", n), steps[int(late)], stop,
                                        rows("xq"), rows("kq"))
    return out


def structural_zeros(G: np.ndarray) -> tuple[int, ...]:
    """Flat indices of the entries of ``G`` (nb, n, 2n) that are an exact zero in every
    lane: springs and dampers the rig does not have (on the three-cart chain 4 of 18,
    those joining carts 1 and 3).  The diagonal entries (each cart's own spring and
    damper, read by the held-force code) are never left out."""
    G = np.asarray(G)
    n = G.shape[1]
    zero = ~np.any(G != 0.0, axis=0)
    zero[np.arange(n), np.arange(n)] = False
    zero[np.arange(n), n + np.arange(n)] = False
    return tuple(int(k) for k in np.flatnonzero(zero))


@functools.lru_cache(maxsize=32)
def coulomb_kernel(n: int, width: int, adaptive: bool = True, per_lane: bool = False,
                   asymmetric: bool = False, stages: tuple[str, ...] = (), stop: int = 0,
                   rates: bool = False, g_zeros: tuple[int, ...] = ()):
    """Compiled stick-slip Coulomb friction kernel (see ``coulomb_run``).

    The kernel returns how many packed groups of lanes took a sample again in sub-steps
    and how many times a group at rest skipped a sample (both 0 without ``adaptive``).
    With ``per_lane`` the input is one column per lane (see ``_lane_inputs``); with
    ``asymmetric`` the kinetic level depends on the direction of sliding (parameter rows
    ``fc`` forwards, ``fn`` backwards); ``stages`` (of ``INPUT_STAGES``, shared input
    only) are applied to the input in the kernel, with parameter rows ``s0, s1, ...``;
    ``stop`` (+1 or -1, shared input only): an end stop of that side on the driven cart,
    rows ``xq`` (m) and ``kq`` (``k_stop / g_v``, V/m) (``kernels.stop``); ``rates``: it
    takes ``cols`` (before ``Y``) and writes those rows of the carts' positions,
    velocities and accelerations (``_coulomb_steps._coulomb_read``), not the positions;
    ``g_zeros``: flat indices of the entries of ``G`` that are zero in every lane
    (``structural_zeros``), whose products the kernel leaves out (one compiled variant
    per pattern of the rig's springs and dampers).
    """
    stages = checked_stages(stages, per_lane)
    g_zeros = checked_zeros(g_zeros, n)
    zeros = frozenset(("G", k) for k in g_zeros)
    stop = checked_side(stop) if stop else 0
    if stop and per_lane:
        raise ValueError("the end stop needs a shared input; pass u of shape (N,)")
    asym, rates = bool(asymmetric), bool(rates)
    w = width
    s = 2 * n
    p_rows = [("A", s * s), ("bh", s), ("fh", s * n), ("rh", s * n), ("Ad", s * s), ("bd", s),
              ("fd", s * n), ("rd", s * n), ("G", n * s), ("gb", n), ("mi", n), ("fc", n),
              ("fs", n)] + ([("fn", n)] if asym else [])
    p_rows += [(f"s{j}", 1) for j in range(len(stages))]
    p_rows += [("xq", 1), ("kq", 1)] if stop else []
    tag = f"{' asym' * asym}{''.join(' ' + k for k in stages)}{f' stop{stop:+d}' * bool(stop)}"
    tag += " rates" * rates
    tag += f" G0={','.join(map(str, g_zeros))}" * bool(g_zeros)
    x_rows = [("x", s), ("st", n), ("d", n), ("xs", n)]
    P, X = _Rows("P", w, p_rows, zeros=zeros), _Rows("X", w, x_rows)
    L = _head("P, X, u, n_sub, h, Y", n, w, X, per_lane)
    if rates:  # the sensors' rows ``cols`` of the lane's rates, n_out a sample
        L = [L[0].replace("h, Y", "h, cols, Y"), "    n_out = cols.shape[0]",
             *_aligned_lines("Z", str(3 * n * w)), *L[1:-n - 2], f"        yo = k * n_out * {w}"]
    L[1:1] = ["    nref = 0", "    nrest = 0"]

    def corrected(t, P, X):
        return (_coulomb_load(t, P, X, n, asym)
                + _coulomb_predict(t, P, n, ("A", "bh", "fh", "rh"), asym)
                + _coulomb_events(t, P, n, asym) + _coulomb_store(t, X, n))

    if not adaptive:
        L += _coulomb_read(P, X, n, w, 0, asym, stop) if rates else []
        L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
        L += corrected(" " * 16, P, X)
        L += ["    return nref, nrest"]
        if per_lane:
            return _compile(_lane_inputs(L, w), f"<bayesmodal coulomb n={n} w={w} per-lane{tag}>")
        if stages or stop:
            L = _staged_inputs(L, P, P, stages, None, stop=stop, n=n, X=X, XX=X)
        return _compile(L, f"<bayesmodal coulomb n={n} w={w}{tag}>")
    # S: state at the start of the sample, and a last row with the lane's event flag (one
    # array less for the vectoriser to check for aliasing).  Lanes with an event are
    # packed (parameters PP, state XX) into groups of g and take the sample again there
    g = min(w, REFINE_GROUP)
    # the packed state XX also holds the sub-steps' scratch rows (one array less for the
    # vectoriser to check for aliasing: with a separate one, the first loop of a sub-step
    # ran one lane at a time)
    PP, XX = _Rows("PP", g, p_rows, zeros=zeros), _Rows("XX", g, x_rows + _scratch_rows(n))
    n_a = P.offset["Ad"]
    n_pl = n_a + P.size - P.offset["G"]
    L[1:1] = _packing_preamble(P, X, XX, w, g)
    # a group whose lanes are all at rest skips the sample (the state does not change);
    # the others take the sample in one step, and the lanes with an event in it take it
    # again in event-corrected sub-steps, packed into groups.  A corrected step without
    # an event in it is the quick step bit for bit (its corrections are selects that keep
    # the quick values, or add an exact zero), so the packed lanes take only corrected
    # sub-steps: a quick sub-step first, to spare the corrected one where no packed lane
    # had an event, cost more than it saved (72-78 % of packed sub-steps had one)
    # a group that rested over the last sample rests again if the input is the same (the
    # test below sees the same state and input): the measured impulse and step records
    # hold their input over 99.8 % of samples.  A per-lane input is always tested
    same = "False" if per_lane else "k > 0 and u[k] == u[k - 1]"
    L += ["        nf = 0",
          f"        same = {same}",
          *(_coulomb_read(P, X, n, w, g, asym, stop) if rates else []),
          f"        for g0 in range(0, {w}, {g}):",
          f"            if same and rested[g0 // {g}]:",
          "                nrest += 1",
          "                continue",
          "            nq = 0",
          "            ns = 0",
          f"            for b in range(g0, g0 + {g}):"]
    L += _coulomb_at_rest(" " * 16, P, X, n)
    L += [f"                ns += 1 if {X('st', i)} != 0.0 else 0" for i in range(n)]
    L += [f"            rested[g0 // {g}] = nq == {g}",
          f"            if nq == {g}:", "                nrest += 1", "                continue",
          "            ev = 0"]
    # a group none of whose carts is stuck takes the step without the held carts' ramp
    # correction (an exact zero for it: the same result) and their tests
    heads = ("if ns == 0:", "else:") if len(GROUP_STEPS) == 2 else ("if True:",)
    for kind, head in zip(GROUP_STEPS, heads, strict=True):
        L += [f"            {head}", f"                for b in range(g0, g0 + {g}):"]
        L += _coulomb_quiet_step(" " * 20, P, X, n, ("Ad", "bd", "fd", "rd"), "dt", asym,
                                 bool(stop), kind == "held")
    L += ["            if ev > 0:",
          f"                for b in range(g0, g0 + {g}):",
          f"                    if S[{X.size * w} + b] != 0.0:",
          "                        idx[nf] = b",
          "                        nf += 1",
          f"        for c0 in range(0, nf, {g}):",
          "            nref += 1",
          f"            m = min({g}, nf - c0)",
          # the packed lanes' sub-step parameters, from their lane-major copy PL (a
          # lane's rows in 14 cache lines instead of one line a row), and start states;
          # unused slots keep valid numbers of an earlier lane
          "            for j in range(m):",
          "                bj = idx[c0 + j]",
          f"                for r in range({n_a}):",
          f"                    PP[r * {g} + j] = PL[bj * {n_pl} + r]",
          f"                for r in range({P.offset['G']}, {P.size}):",
          f"                    PP[r * {g} + j] = PL[bj * {n_pl} + r - {P.offset['G'] - n_a}]",
          f"                for r in range({X.size}):",
          f"                    XX[r * {g} + j] = S[r * {w} + bj]",
          "            for sub in range(n_sub):"]
    L += _split_substep(" " * 16, PP, XX, XX, n, g, asym)
    L += ["            for j in range(m):",
          "                bj = idx[c0 + j]",
          f"                for r in range({X.size}):",
          f"                    X[r * {w} + bj] = XX[r * {g} + j]"]
    L += ["    return nref, nrest"]
    if per_lane:
        packed_from = next(i for i, line in enumerate(L) if "for c0 in range(0, nf" in line)
        # the packed lanes' inputs, copied where their state is packed
        pack = next(i for i, line in enumerate(L)
                    if i > packed_from and line.strip() == "bj = idx[c0 + j]")
        L.insert(pack + 1, f"                UU[j] = u[k * {w} + bj]")
        L.insert(1, f"    UU = np.zeros({g})")
        packed_from += 1
        return _compile(_lane_inputs(L, w, packed_from=packed_from),
                        f"<bayesmodal coulomb n={n} w={w} adaptive per-lane{tag}>")
    if stages or stop:
        packed_from = next(i for i, line in enumerate(L) if "for c0 in range(0, nf" in line)
        L = _staged_inputs(L, P, PP, stages, packed_from, stop=stop, n=n, X=X, XX=XX,
                           steps=("dt", "h"))
    return _compile(L, f"<bayesmodal coulomb n={n} w={w} adaptive{tag}>")


def _packing_preamble(P, X, XX, w: int, g: int) -> list[str]:
    """Kernel source before the sample loop of the adaptive friction kernel: the rows
    sub-steps use (not those of the whole-sample step, ``Ad`` to ``rd``) copied
    lane-major into ``PL``, the saved states ``S``, the packed groups' parameters ``PP``
    and states ``XX`` (unused slots hold copies of lane 0: valid numbers), the packed
    lanes' indices ``idx`` and the sample interval ``dt``."""
    n_a = P.offset["Ad"]
    n_pl = n_a + P.size - P.offset["G"]
    return [*_aligned_lines("PL", str(w * n_pl)),
            # (not a lane loop ``b``, which gets the input code of every lane loop)
            f"    for lane in range({w}):",
            f"        for r in range({n_a}):",
            f"            PL[lane * {n_pl} + r] = P[r * {w} + lane]",
            f"        for r in range({P.offset['G']}, {P.size}):",
            f"            PL[lane * {n_pl} + r - {P.offset['G'] - n_a}] = P[r * {w} + lane]",
            *_aligned_lines("S", f"X.shape[0] + {w}"),
            f"    rested = np.zeros({-(-w // g)}, np.bool_)",
            *_aligned_lines("PP", str(P.size * g)), *_aligned_lines("XX", str(XX.size * g)),
            f"    idx = np.empty({w}, np.int64)",
            "    dt = h * n_sub",
            f"    for j in range({g}):",
            f"        for r in range({P.size}):",
            f"            PP[r * {g} + j] = P[r * {w}]",
            f"        for r in range({X.size}):",
            f"            XX[r * {g} + j] = X[r * {w}]"]


def coulomb_run(Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, G, gb, minv, Fc, Fs, u, n_sub, h, x0, *,
                adaptive=True, Fc_backward=None, input_stages=(), stop=None, outputs=None):
    """Stick-slip Coulomb friction on every cart (see ``extensions.coulomb``).

    A step: the friction force of each cart is decided at its start (stuck carts hold the
    net force, ``f = -F``, while ``|F| < Fs``, or break away at once if the input jumped
    past ``Fs``; sliding carts get ``f = -Fc dir``) and the state is advanced exactly with
    that force held, a stuck cart's holding force ramping to its end value (one
    correction with the ramp response, so that the held cart does not drift and pull on
    its neighbours).  That is all a step without an event needs.

    Each sample is first taken in one such step.  A lane that had, or may have had, an
    event in it (see ``_coulomb_quiet_step``) takes the sample again in ``n_sub``
    sub-steps ``h``, each with the events located on cubic Hermite interpolants in time
    (values and rates at both ends; Newton from the chord, safeguarded for the
    break-away) and corrected (a sub-step without an event gives the uncorrected step's
    result bit for bit):

    - a stuck cart whose held net force reached ``Fs`` inside the step broke away there
      and gains the velocity and displacement of the integrals of the interpolated net
      force less ``Fc`` from then to the end;
    - a sliding cart whose velocity changed sign crossed zero ``tau`` before the end.  If
      the net force there is below ``Fs`` it sticks where the velocity vanished (the
      distance travelled since is the integral of the velocity interpolant), and breaks
      away again later in the same step if its held force reaches ``Fs`` by the end;
      otherwise friction reverses and the wrong force over ``tau`` is undone:
      ``dv = 2 Fc dir tau / m``, ``dx = dv tau / 2``.

    Lanes run in groups of ``REFINE_GROUP`` (vectorised); a group whose lanes are all at
    rest skips the sample, and the lanes with an event in a sample (from any group) are
    packed into groups of ``REFINE_GROUP`` that take it again in sub-steps; every lane's
    arithmetic is its own, so the output of a parameter set never depends on the others
    in the batch.  The error is second order in the sub-step
    where events are, but a stick-or-reverse decision taken with ``|F|`` within a fraction
    of a percent of ``Fs`` can flip and change the whole future (as in any fixed-step
    scheme).

    Parameters
    ----------
    Ah : ndarray, shape (nb, s, s)
        One sub-step of the linear system.
    Bh : ndarray, shape (nb, s)
        Response to the input held over a sub-step.
    Fh : ndarray, shape (nb, s, n)
        Response to a force held on each cart over a sub-step.
    Rh : ndarray, shape (nb, s, n)
        Response to a force on each cart ramping from 0 to 1 over a sub-step.
    Ad, Bd, Fd, Rd : ndarray
        The same over a whole sample interval.
    G : ndarray, shape (nb, n, s)
        ``[-K, -C]``: spring and damper force on each cart, N.
    gb : ndarray, shape (nb, n)
        Motor force per volt on each cart, N/V.
    minv : ndarray, shape (nb, n)
        Inverse masses, 1/kg.
    Fc, Fs : ndarray, shape (nb, n)
        Kinetic and static friction levels, N (``Fc`` forwards if ``Fc_backward`` is
        given).
    u : ndarray, shape (N,) or (nb, N)
    n_sub : int
    h : float
        Sub-step, s.
    x0 : ndarray, shape (nb, s)
    adaptive : bool
        False: every sample in ``n_sub`` corrected sub-steps (slower; for checks).
    Fc_backward : ndarray, shape (nb, n), optional
        Kinetic level when sliding in the negative direction, N (default: ``Fc``).
    input_stages : sequence of (str, ndarray of shape (nb,))
        Memoryless stages (``INPUT_STAGES``) applied in this order to the shared input
        ``u`` (N,) inside the kernel, each with its parameter per lane; the result is bit
        for bit that of the same stages applied in ``effects`` and a per-lane input.
        Stages given in ``INPUT_STAGES`` order (and any run with ``stop``) use the one
        kernel with all four, the others at their identity (``every_stage``).
    stop : tuple (side, x_stop, k_stop), optional
        An end stop on the driven cart (``kernels.stop``; shared input only): side +1 or
        -1, ``x_stop`` (nb,) m, ``k_stop`` (nb,) N/m.  Its force is held over each step at
        its predicted mid-step value, and lanes in or near contact take the sample in
        sub-steps.
    outputs : ndarray of int, shape (n_out, 2), optional
        Sensors ``(k, order)`` to read (``effects._linear.sensor_spec``): cart ``k``'s
        position (0), velocity (1) or acceleration (2) at each sample.  The kernel then
        reads every cart's three into a scratch block and copies the sensors' rows, an
        index array given at run time (one compiled variant for any set of sensors;
        ``_coulomb_steps._coulomb_read``).  The velocity is the state; the
        acceleration at a sample is that of the sample's own state, ``(F + f) / m``, with
        ``F`` the net force of the springs, dampers, the input held from the sample (and
        the end stop, at the sample's position) and ``f`` the friction of that state:
        ``-Fc dir`` for a sliding cart, the static balance ``-F`` (acceleration exactly
        0) for a stuck cart with ``|F| < Fs``, and ``-Fc`` in the direction of ``F`` for a
        stuck cart that breaks away at the sample (``|F| >= Fs``).  A stick or a reversal
        inside a step shows at the next sample through that sample's state, never as a
        difference of positions.

    Returns
    -------
    ndarray, shape (nb, N, n) or (nb, N, n_out)
        Positions, a view of the kernel's output buffer, or with ``outputs`` each
        sensor's reading (m, m/s, m/s^2 along +x), in sensor order.
    """
    n = Fc.shape[1]
    v = x0[:, n:]
    state = [x0, v == 0.0, np.sign(v), x0[:, :n]]
    params = [Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, G, gb, minv, Fc, Fs]
    if Fc_backward is not None:
        params.append(Fc_backward)
    if (input_stages or stop is not None) and u.ndim == 1:
        # one kernel for every combination of input stages (and for the end stop)
        input_stages = every_stage(input_stages, Fc.shape[0])
    kinds = tuple(kind for kind, _ in input_stages)
    if kinds and u.ndim != 1:
        raise ValueError("input stages apply to a shared input; pass u of shape (N,)")
    params += [np.asarray(values, dtype=float).reshape(-1, 1) for _, values in input_stages]
    kernel = functools.partial(coulomb_kernel, n, adaptive=bool(adaptive),
                               g_zeros=structural_zeros(G))
    if Fc_backward is not None:
        kernel = functools.partial(kernel, asymmetric=True)
    if kinds:
        kernel = functools.partial(kernel, stages=kinds)
    if stop is not None:
        side, xq, kq = stop
        if u.ndim != 1:
            raise ValueError("the end stop needs a shared input; pass u of shape (N,)")
        drive = np.flatnonzero(np.any(gb != 0.0, axis=0))
        if drive.tolist() != [0]:
            raise ValueError("the end stop acts through the motor input: the motor must "
                             f"drive cart 1 alone, it drives carts {(drive + 1).tolist()}")
        # the stop's force as a voltage on the driven cart: k_stop / g_v (V/m)
        params += [np.asarray(xq, float).reshape(-1, 1),
                   (np.asarray(kq, float) / gb[:, 0]).reshape(-1, 1)]
        kernel = functools.partial(kernel, stop=checked_side(side))
    if outputs is None:
        return run_batched(kernel, params, state, u, n, int(n_sub), float(h))
    cols = np.array([order * n + k for k, order in checked_outputs(outputs, n)], np.int64)
    return run_batched(functools.partial(kernel, rates=True), params, state, u, cols.size,
                       int(n_sub), float(h), cols)
