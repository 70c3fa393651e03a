"""Compiled inner loops (numba) for the model extensions, batched across parameter sets.

Every nonlinear extension is written as the *exact* zero-order-hold discretisation of the
linear rig over a sub-step ``h = dt / n_sub`` plus extra force inputs ``f`` acting on the
carts (friction, cubic spring forces) or a switch between two exactly discretised linear
systems (backlash).  The linear part is therefore integrated without error and the only
approximation is in how ``f`` varies within a sub-step; with the extension switched off
``f = 0`` and the kernels reproduce the linear simulator to rounding error.  The
linear-input extensions (lag, delay, saturation) run an exact linear recursion whose
input is shifted and clipped per parameter set inside the kernel.

Batching follows ``bayesmodal._kernels``: the parameter sets ("lanes") are innermost and
contiguous, the lane count is a compile-time constant (a power of two up to
``MAX_WIDTH``), the kernel source is generated for each shape with the state unrolled into
scalars, and the branches of the hybrid models (stick, slip, contact) are written on local
scalars so that the compiler turns them into per-lane selects and vectorises across
parameter sets.  Lanes take every branch's cost, but SIMD across 8 lanes more than pays
for it.

Flat layouts (float64): parameters ``P (rows, width)``, state ``X (rows, width)`` updated in
place, outputs ``Y (N, n_out, width)`` with ``Y[k]`` the positions at ``t = k dt``.  The
driver ``run_batched`` packs per-lane arrays into these blocks, pads the batch with a
repeated valid lane, splits it into chunks of at most ``MAX_WIDTH`` lanes, and returns a
``(nb, N, n_out)`` view of the output buffer (no copy).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

MAX_WIDTH = 64

_JIT = {"nogil": True, "boundscheck": False, "error_model": "numpy"}


def padded_width(nb: int) -> int:
    """Kernel width for a batch of ``nb`` parameter sets (power of two <= MAX_WIDTH)."""
    w = 1
    while w < min(nb, MAX_WIDTH):
        w *= 2
    return w


def _compile(lines: list[str], label: str):
    namespace: dict = {}
    # the source is generated from integers only (shapes), never from user text
    exec(compile("\n".join(lines), label, "exec"), namespace)  # noqa: S102
    return njit(**_JIT)(namespace["kernel"])


class _Rows:
    """Named rows of a flat lane-innermost block; ``rows(name, i)`` is the code of element i."""

    def __init__(self, array: str, width: int, fields: list[tuple[str, int]]):
        self.array, self.width = array, width
        self.offset: dict[str, int] = {}
        n = 0
        for name, count in fields:
            self.offset[name] = n
            n += count
        self.size = n

    def __call__(self, name: str, i: int = 0) -> str:
        return f"{self.array}[{(self.offset[name] + i) * self.width} + b]"


def _pack(arrays, lanes: np.ndarray) -> np.ndarray:
    """Rows of per-lane arrays (each (nb, ...)) as one flat (rows, width) block."""
    width = lanes.size
    cols = [np.asarray(a, dtype=float)[lanes].reshape(width, -1) for a in arrays]
    return np.ascontiguousarray(np.concatenate(cols, axis=1).T).ravel()


def run_batched(kernel_for_width, params, state, u, n_out: int, *args) -> np.ndarray:
    """Run ``kernel(P, X, u, *args, Y)`` over the batch in chunks of lanes.

    Parameters
    ----------
    kernel_for_width : callable
        ``width -> compiled kernel``.
    params, state : list of ndarray, each shape (nb, ...)
        Per-lane parameter and initial-state arrays, packed in this order.
    u : ndarray, shape (N,)
        Input samples.
    n_out : int
        Outputs per sample.
    *args
        Extra scalar arguments passed to the kernel after ``u``.

    Returns
    -------
    ndarray, shape (nb, N, n_out)
        A view of the (chunk, N, n_out, lane) output buffer.
    """
    nb = params[0].shape[0]
    width = padded_width(nb)
    n_chunks = -(-nb // width)
    kernel = kernel_for_width(width)
    N = u.shape[0]
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        kernel(_pack(params, lanes), _pack(state, lanes), u, *args, Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]


def _head(signature: str, n_out: int, width: int, state: _Rows) -> list[str]:
    """Kernel start: the sample loop and the output of the first ``n_out`` state rows."""
    return [
        f"def kernel({signature}):",
        "    for k in range(u.shape[0]):",
        "        uk = u[k]",
        f"        yo = k * {n_out * width}",
        f"        for b in range({width}):",
    ] + [f"            Y[yo + {i * width} + b] = {state('x', i)}" for i in range(n_out)]


# ---------------------------------------------------------------------------------------
# linear recursion with a shifted, clipped input per lane (delay, saturation, motor lag)
@functools.lru_cache(maxsize=32)
def linear_input_kernel(n_states: int, n_out: int, width: int):
    """Compiled ``kernel(P, X, up, shift, Y)`` for the recursion (see ``linear_input_run``)."""
    s, w = n_states, width
    P = _Rows("P", w, [("A", s * s), ("B1", s), ("B2", s), ("lo", 1), ("hi", 1)])
    X = _Rows("X", w, [("x", s)])
    L = [
        "def kernel(P, X, up, shift, Y):",
        "    N = Y.shape[0] // " + str(n_out * w),
        "    for k in range(N):",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
        "            j = k + shift[b]",
        f"            ua = min(max(up[j], {P('lo')}), {P('hi')})",
        f"            ub = min(max(up[j + 1], {P('lo')}), {P('hi')})",
    ]
    L += [f"            x{i} = {X('x', i)}" for i in range(s)]
    L += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        terms = " + ".join(f"{P('A', i * s + j)} * x{j}" for j in range(s))
        L.append(f"            {X('x', i)} = {P('B1', i)} * ua + {P('B2', i)} * ub + {terms}")
    return _compile(L, f"<bayesmodal linear-input s={s} o={n_out} w={w}>")


def linear_input_run(Ad, B1, B2, u, x0, n_out, *, shift=None, level=None):
    """Batched ``x[k+1] = Ad x[k] + B1 v[k - m - 1] + B2 v[k - m]``, ``v = clip(u, +-level)``.

    Parameters
    ----------
    Ad : ndarray, shape (nb, s, s)
    B1, B2 : ndarray, shape (nb, s)
    u : ndarray, shape (N,)
        Input, zero before the first sample.
    x0 : ndarray, shape (nb, s)
    n_out : int
        Number of leading states returned.
    shift : ndarray of int, shape (nb,), optional
        Whole-sample delay ``m >= 0`` of each lane (default 0).
    level : ndarray, shape (nb,), optional
        Clip level of each lane (default: no clipping).

    Returns
    -------
    ndarray, shape (nb, N, n_out)
    """
    nb, s, _ = Ad.shape
    N = u.size
    m = np.zeros(nb, np.int64) if shift is None else np.minimum(shift, N).astype(np.int64)
    lvl = np.full(nb, np.inf) if level is None else np.asarray(level, dtype=float)
    pad = int(m.max()) + 1
    up = np.concatenate([np.zeros(pad), u])  # up[k + pad - m - 1] = v[k - m - 1]
    width = padded_width(nb)
    n_chunks = -(-nb // width)
    kernel = linear_input_kernel(s, n_out, width)
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)
        P = _pack([Ad, B1, B2, -lvl, lvl], lanes)
        X = _pack([x0], lanes)
        kernel(P, X, up, np.ascontiguousarray(pad - 1 - m[lanes]), Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]


# ---------------------------------------------------------------------------------------
# Coulomb friction with stick-slip
@functools.lru_cache(maxsize=16)
def coulomb_kernel(n: int, width: int):
    """Compiled stick-slip Coulomb friction kernel (see ``coulomb_run``)."""
    s, w = 2 * n, width
    R, C = range(s), range(n)
    P = _Rows("P", w, [("A", s * s), ("bh", s), ("fh", s * n), ("G", n * s), ("gb", n),
                       ("mi", n), ("fc", n), ("fs", n)])
    X = _Rows("X", w, [("x", s), ("st", n), ("d", n), ("xs", n), ("gzp", n)])
    L = _head("P, X, u, n_sub, h, Y", n, w, X)
    L[1:1] = ["    u_prev = u[0]"]
    L += ["        for sub in range(n_sub):",
          "            same = uk == u_prev",
          "            u_prev = uk",
          f"            for b in range({w}):"]
    t = "                "
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    for i in C:
        L += [f"{t}st{i} = {X('st', i)} != 0.0", f"{t}d{i} = {X('d', i)}",
              f"{t}xs{i} = {X('xs', i)}", f"{t}fc{i} = {P('fc', i)}", f"{t}fs{i} = {P('fs', i)}",
              f"{t}gb{i} = {P('gb', i)}"]
    for i in C:
        gz = " + ".join(f"{P('G', i * s + j)} * x{j}" for j in R)
        L += [f"{t}gz{i} = {gz}",
              f"{t}F{i} = gz{i} + gb{i} * uk",
              f"{t}Fp{i} = {X('gzp', i)} + gb{i} * uk",
              f"{t}{X('gzp', i)} = gz{i}"]
    # break-away of stuck carts, written as selects (no nested branches) so that the
    # compiler vectorises it across lanes
    for i in C:
        L += [f"{t}aF = abs(F{i})",
              f"{t}hold = st{i} and aF < fs{i}",
              f"{t}brk = st{i} and not hold",
              f"{t}d{i} = (1.0 if F{i} > 0.0 else (-1.0 if F{i} < 0.0 else 0.0)) if brk else d{i}",
              f"{t}f{i} = -F{i} if hold else -fc{i} * d{i}",
              f"{t}aFp = abs(Fp{i})",
              f"{t}late = brk and same and aFp < fs{i} and aF > aFp",
              f"{t}tau = h * (aF - fs{i}) / (aF - aFp) if late else 0.0",
              f"{t}dv = d{i} * (0.5 * (aF + fs{i}) - fc{i}) * {P('mi', i)} * tau",
              f"{t}x{n + i} += dv",
              f"{t}x{i} += 0.5 * dv * tau",
              f"{t}st{i} = hold"]
    for r in R:
        terms = " + ".join([f"{P('A', r * s + j)} * x{j}" for j in R]
                           + [f"{P('fh', r * n + j)} * f{j}" for j in C])
        L.append(f"{t}n{r} = {P('bh', r)} * uk + {terms}")
    # velocity reversals inside the step: stick or slide back
    for i in C:
        fe = " + ".join(f"{P('G', i * s + j)} * n{j}" for j in R)
        L += [f"{t}v0 = x{n + i}",
              f"{t}v1 = n{n + i}",
              f"{t}rev = not st{i} and d{i} * v1 < 0.0",
              f"{t}a = v0 / (v0 - v1) if v0 != v1 else 0.0",
              f"{t}a = min(max(a, 0.0), 1.0)",
              f"{t}tau = (1.0 - a) * h",
              f"{t}Fe = gb{i} * uk + {fe}",
              f"{t}Fx = F{i} + a * (Fe - F{i})",
              f"{t}stick = rev and abs(Fx) < fs{i}",
              f"{t}flip = rev and not stick",
              f"{t}dv = 2.0 * fc{i} * d{i} * {P('mi', i)} * tau if flip else 0.0",
              f"{t}p = n{i} - 0.5 * v1 * tau if stick else n{i} + 0.5 * dv * tau",
              f"{t}n{i} = xs{i} if st{i} else p",
              f"{t}n{n + i} = 0.0 if st{i} or stick else v1 + dv",
              f"{t}xs{i} = p if stick else xs{i}",
              f"{t}d{i} = -d{i} if flip else d{i}",
              f"{t}st{i} = st{i} or stick"]
    L += [f"{t}{X('x', r)} = n{r}" for r in R]
    for i in C:
        L += [f"{t}{X('st', i)} = 1.0 if st{i} else 0.0", f"{t}{X('d', i)} = d{i}",
              f"{t}{X('xs', i)} = xs{i}"]
    return _compile(L, f"<bayesmodal coulomb n={n} w={w}>")


def coulomb_run(Ah, Bh, Fh, G, gb, minv, Fc, Fs, u, n_sub, h, x0):
    """Stick-slip Coulomb friction on every cart (see ``extensions.coulomb``).

    Per sub-step: the friction force of each cart is decided at the start (stuck carts
    hold the net force exactly, ``f = -F``, while ``|F| < Fs``; sliding carts get
    ``f = -Fc dir``), the state is advanced exactly with that force held, and the events
    inside the step are then corrected to second order:

    - a sliding cart whose velocity changed sign crossed zero at the fraction
      ``a = v0 / (v0 - v1)`` of the step.  If the net force there is below ``Fs`` it sticks
      (velocity set to zero, position moved back by the distance travelled after the
      crossing, ``v1 tau / 2``); otherwise friction reverses and the wrong force over the
      remaining ``tau = (1 - a) h`` is undone: ``dv = 2 Fc dir tau / m``,
      ``dx = dv tau / 2``;
    - a stuck cart whose net force passed ``Fs`` during the previous sub-step (same input)
      started slipping ``tau = h (|F| - Fs) / (|F| - |F_prev|)`` ago; it gets the velocity
      and displacement of that interval under the mean net force.

    Parameters
    ----------
    Ah : ndarray, shape (nb, s, s)
        One sub-step of the linear system.
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
        Kinetic and static friction levels, N.
    u : ndarray, shape (N,)
    n_sub : int
    h : float
        Sub-step, s.
    x0 : ndarray, shape (nb, s)

    Returns
    -------
    ndarray, shape (nb, N, n)
        Positions, a view of the kernel's output buffer.
    """
    n = Fc.shape[1]
    v = x0[:, n:]
    state = [x0, v == 0.0, np.sign(v), x0[:, :n], np.full(v.shape, np.nan)]
    params = [Ah, Bh, Fh, G, gb, minv, Fc, Fs]
    return run_batched(functools.partial(coulomb_kernel, n), params, state, u, n,
                       int(n_sub), float(h))


# ---------------------------------------------------------------------------------------
# cubic spring stiffness
def _cubic_force_lines(t: str, n: int, src: str, dst: str) -> list[str]:
    # spring i joins cart i and i + 1 (the last one joins cart n - 1 to the frame); its
    # extension is d_i = x_{i+1} - x_i (or -x_{n-1}) and it pulls cart i with k3_i d_i^3
    # and cart i + 1 with -k3_i d_i^3
    lines = []
    for i in range(n):
        d = f"({src}{i + 1} - {src}{i})" if i < n - 1 else f"(-{src}{i})"
        lines += [f"{t}e{i} = {d}", f"{t}c{i} = k3_{i} * e{i} * e{i} * e{i}"]
    for i in range(n):
        lines.append(f"{t}{dst}{i} = c{i}" + (f" - c{i - 1}" if i > 0 else ""))
    return lines


@functools.lru_cache(maxsize=16)
def cubic_kernel(n: int, width: int):
    """Compiled cubic-spring kernel (see ``cubic_run``)."""
    s, w = 2 * n, width
    R, C = range(s), range(n)
    P = _Rows("P", w, [("A", s * s), ("bh", s), ("p", s * n), ("q", s * n), ("k3", n)])
    X = _Rows("X", w, [("x", s)])
    L = _head("P, X, u, n_sub, Y", n, w, X)
    L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
    t = "                "
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    L += [f"{t}k3_{i} = {P('k3', i)}" for i in C]
    L += _cubic_force_lines(t, n, "x", "f")
    for r in R:
        terms = " + ".join([f"{P('A', r * s + j)} * x{j}" for j in R]
                           + [f"{P('p', r * n + j)} * f{j}" for j in C])
        L.append(f"{t}y{r} = {P('bh', r)} * uk + {terms}")
    L += _cubic_force_lines(t, n, "y", "g")
    for r in R:
        terms = " + ".join(f"{P('q', r * n + j)} * (g{j} - f{j})" for j in C)
        L.append(f"{t}{X('x', r)} = y{r} + {terms}")
    return _compile(L, f"<bayesmodal cubic n={n} w={w}>")


def cubic_run(Ah, Bh, F0h, F1h, k3, u, n_sub, x0):
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
    k3 : ndarray, shape (nb, n)
        Cubic stiffness of each spring, N/m^3.
    u : ndarray, shape (N,)
    n_sub : int
    x0 : ndarray, shape (nb, s)

    Returns
    -------
    ndarray, shape (nb, N, n)
    """
    n = k3.shape[1]
    return run_batched(functools.partial(cubic_kernel, n), [Ah, Bh, F0h, F1h, k3], [x0], u,
                       n, int(n_sub))


# ---------------------------------------------------------------------------------------
# backlash between the motor and cart 1
@functools.lru_cache(maxsize=16)
def backlash_kernel(n: int, width: int):
    """Compiled backlash kernel (see ``backlash_run``)."""
    s, w = 2 * n, width
    R = range(s)
    P = _Rows("P", w, [("Ae", s * s), ("be", s), ("Ad", s * s), ("ge", s), ("m1", 1),
                       ("mp", 1), ("gv", 1), ("gap", 1)])
    X = _Rows("X", w, [("x", s), ("eng", 1), ("side", 1), ("xm", 1), ("vm", 1),
                       ("fp", 1)])
    L = _head("P, X, u, n_sub, h, Y", n, w, X)
    L[1:1] = ["    u_prev = u[0]"]
    L += ["        for sub in range(n_sub):",
          "            same = uk == u_prev",
          "            u_prev = uk",
          f"            for b in range({w}):"]
    t = "                "
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    f1 = " + ".join(f"{P('ge', j)} * x{j}" for j in R)
    L += [f"{t}engaged = {X('eng')} != 0.0",
          f"{t}side = {X('side')}",
          f"{t}xm = {X('xm')}",
          f"{t}vm = {X('vm')}",
          f"{t}fcon_prev = {X('fp')}",
          f"{t}half = 0.5 * {P('gap')}",
          f"{t}mp = {P('mp')}",
          f"{t}mt = {P('m1')}",
          f"{t}mc = mt - mp",
          f"{t}fm = {P('gv')} * uk",
          f"{t}am = fm / mp",
          f"{t}if engaged:",
          f"{t}    F1 = {f1}",
          f"{t}    fcon = (mc * fm - mp * F1) / mt",
          f"{t}    if side * fcon < 0.0:",
          f"{t}        if half == 0.0:",
          f"{t}            side = -side",
          f"{t}        else:",
          f"{t}            engaged = False",
          f"{t}            xm = x0 + side * half",
          f"{t}            vm = x{n}",
          # the contact force crossed zero inside the last sub-step (same input): since
          # then cart 1 and the motor have moved apart, second-order correction
          f"{t}            if same and side * fcon_prev > 0.0:",
          f"{t}                tau = h * fcon / (fcon - fcon_prev)",
          f"{t}                a1e = (F1 + fm) / mt",
          f"{t}                dv1 = (F1 / mc - a1e) * tau",
          f"{t}                dvm = (am - a1e) * tau",
          f"{t}                x0 += 0.5 * dv1 * tau",
          f"{t}                x{n} += dv1",
          f"{t}                xm += 0.5 * dvm * tau",
          f"{t}                vm += dvm",
          f"{t}    fcon_prev = fcon",
          f"{t}if engaged:"]
    for r in R:
        terms = " + ".join(f"{P('Ae', r * s + j)} * x{j}" for j in R)
        L.append(f"{t}    y{r} = {P('be', r)} * uk + {terms}")
    L += [f"{t}else:"]
    for r in R:
        terms = " + ".join(f"{P('Ad', r * s + j)} * x{j}" for j in R)
        L.append(f"{t}    y{r} = {terms}")
    L += [f"{t}    delta0 = xm - x0",
          f"{t}    xm += vm * h + 0.5 * am * h * h",
          f"{t}    vm += am * h",
          f"{t}    delta = xm - y0",
          f"{t}    if abs(delta) >= half:",
          # plastic impact: momentum is right whenever it happened; the position of cart 1
          # is corrected for the time since the impact
          f"{t}        side = 1.0 if delta > 0.0 else -1.0",
          f"{t}        a = (side * half - delta0) / (delta - delta0) if delta != delta0 else 1.0",
          f"{t}        a = min(max(a, 0.0), 1.0)",
          f"{t}        vc = (mp * vm + mc * y{n}) / mt",
          f"{t}        y0 += (vc - y{n}) * (1.0 - a) * h",
          f"{t}        y{n} = vc",
          f"{t}        engaged = True"]
    L += [f"{t}{X('x', r)} = y{r}" for r in R]
    L += [f"{t}{X('eng')} = 1.0 if engaged else 0.0",
          f"{t}{X('side')} = side",
          f"{t}{X('xm')} = xm",
          f"{t}{X('vm')} = vm",
          f"{t}{X('fp')} = fcon_prev"]
    return _compile(L, f"<bayesmodal backlash n={n} w={w}>")


def backlash_run(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, n_sub, h, x0):
    """Rack-pinion backlash with a plastic contact (see ``extensions.backlash``).

    Engaged (``|delta| = gap / 2`` on side ``side``): motor and cart 1 move together; the
    exact linear step ``(Ae, Be)`` applies.  The contact force on cart 1 is
    ``Fcon = ((m1 - m_p) g_v u - m_p F1) / m1`` with ``F1 = Ge z`` the other forces on
    cart 1; the contact opens when ``side * Fcon < 0`` (with the motion since the zero
    crossing of ``Fcon`` inside the last sub-step added to cart 1 and the motor).
    Disengaged: the carts follow the exact unforced step ``Adis`` (cart 1 without the motor
    mass) and the motor is a free mass ``m_p`` under ``g_v u``; when ``|delta|`` reaches
    ``gap / 2`` the contact closes with a plastic impact that conserves momentum, and cart
    1's position is corrected for the part of the sub-step after the impact.  With
    ``gap = 0`` the contact never opens (it only changes side) and the scheme is the linear
    simulator.

    Parameters
    ----------
    Ae, Adis : ndarray, shape (nb, s, s)
        One sub-step engaged and disengaged.
    Be : ndarray, shape (nb, s)
        Engaged response to the input held over a sub-step.
    Ge : ndarray, shape (nb, s)
        Spring and damper force on cart 1 from the state, N.
    m1, m_p, g_v, gap : ndarray, shape (nb,)
        Cart 1 mass with the motor (kg), motor mass (kg), gain (N/V), gap (m).
    u : ndarray, shape (N,)
    n_sub : int
    h : float
        Sub-step, s.
    x0 : ndarray, shape (nb, s)

    Returns
    -------
    ndarray, shape (nb, N, n)
    """
    nb, s = x0.shape
    n = s // 2
    engaged = (gap == 0.0).astype(float)
    # at rest with the pinion in the middle of the gap
    state = [x0, engaged, np.ones(nb), x0[:, 0], x0[:, n], np.zeros(nb)]
    params = [Ae, Be, Adis, Ge, m1, m_p, g_v, gap]
    return run_batched(functools.partial(backlash_kernel, n), params, state, u, n,
                       int(n_sub), float(h))


# ---------------------------------------------------------------------------------------
# parameter-dependent discretisation: matrix exponentials of a batch, lanes innermost
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
    """Exact one-step matrices of ``z' = A z + inputs w`` (compiled ``zoh_blocks``).

    Same as ``extensions._base.zoh_blocks`` (Van Loan block exponential) with
    ``expm_batched`` for the exponential; ``h`` may be a scalar or one step per system.

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
