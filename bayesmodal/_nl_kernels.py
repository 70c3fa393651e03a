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
for it.  The friction kernel takes each sample in one exact step and takes it again in
corrected sub-steps only for the lanes with an event in it, packed into full vectors
(see ``coulomb_run``).

Flat layouts (float64): parameters ``P (rows, width)``, state ``X (rows, width)`` updated in
place, outputs ``Y (N, n_out, width)`` with ``Y[k]`` the positions at ``t = k dt``.  The
driver ``run_batched`` packs per-lane arrays into these blocks, pads the batch with a
repeated valid lane, splits it into chunks of at most ``MAX_WIDTH`` lanes, and returns a
``(nb, N, n_out)`` view of the output buffer (no copy).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import math
import os
import sys
import tempfile
from pathlib import Path

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

MAX_WIDTH = 64

#: Safeguarded Newton steps for the break-away time of the friction kernel (a held force
#: reaching the static level, on its cubic Hermite interpolant in time).
HERMITE_NEWTON = 2

#: Newton steps from the chord for the velocity zero of the friction kernel.
REVERSAL_NEWTON = 2

#: Lanes of the friction kernel that take a sample together (two AVX-512 vectors of
#: float64: LLVM does not vectorise loops of 8), and lanes with an event packed together
#: to take it again in sub-steps; a packed group takes the event-corrected path when one
#: of its lanes needs it and the others keep their quick result, so that no lane depends
#: on the rest of its batch.
REFINE_GROUP = 16

#: Relative margin below the static level under which a stuck cart of the friction
#: kernel is at rest for certain over a step (rounding of the step is ~1e-16).
REST_MARGIN = 1e-9

#: Newton steps for the impact time of the backlash kernel.
IMPACT_NEWTON = 2

_JIT = {"nogil": True, "boundscheck": False, "error_model": "numpy"}


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (``llvm.fma``): the same in vector and scalar code."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


def _fma_sum(init: str, products) -> str:
    """Code of ``init + sum(a * b)`` as a chain of fused multiply-adds."""
    expr = init
    for a, b in products:
        expr = f"fma({a}, {b}, {expr})"
    return expr


def _rising_cubic_root(t: str, x: str, c: tuple[str, str, str, str]) -> list[str]:
    """Code locating the root ``x`` in [0, 1] of ``c0 + x (c1 + x (c2 + x c3))``, which
    is negative at 0 and not negative at 1.

    Starts from the chord (``x`` must hold it) and takes ``HERMITE_NEWTON`` Newton steps
    safeguarded by the bracket [lo, hi] (a step leaving it bisects instead).  On cubics with an
    inflection or strong curvature in the step plain Newton from the chord overshoots
    (a break-away located 0.18 of a step late on a quadratically rising force).
    """
    c0, c1, c2, c3 = c
    lines = [f"{t}lo = 0.0", f"{t}hi = 1.0"]
    for _ in range(HERMITE_NEWTON):
        lines += [
            f"{t}g = {c0} + {x} * ({c1} + {x} * ({c2} + {x} * {c3}))",
            f"{t}dg = {c1} + {x} * (2.0 * {c2} + 3.0 * {x} * {c3})",
            f"{t}hi = {x} if g > 0.0 else hi",
            f"{t}lo = lo if g > 0.0 else {x}",
            f"{t}xn = {x} - g / dg",
            f"{t}xn = xn if dg != 0.0 else -1.0",
            f"{t}xb = 0.5 * (lo + hi)",
            f"{t}{x} = xn if (xn > lo) & (xn < hi) else xb",
        ]
    return lines


def padded_width(nb: int) -> int:
    """Kernel width for a batch of ``nb`` parameter sets (power of two <= MAX_WIDTH)."""
    w = 1
    while w < min(nb, MAX_WIDTH):
        w *= 2
    return w


def _kernel_dir() -> Path | None:
    """Writable directory for the generated kernel sources (None: compile in memory)."""
    env = os.environ.get("BAYESMODAL_KERNEL_DIR")
    candidates = [Path(env)] if env else []
    candidates += [Path.home() / ".cache" / "bayesmodal" / "kernels",
                   Path(tempfile.gettempdir()) / f"bayesmodal-kernels-{os.getuid()}"]
    for d in candidates:
        try:
            d.mkdir(parents=True, exist_ok=True)
            if os.access(d, os.W_OK):
                return d
        except OSError:
            continue
    return None


def _compile(lines: list[str], label: str):
    """Compile generated kernel source ``def kernel(...)`` with numba.

    The source (generated from integers only, shapes, never from user text) is written
    once to a file named by its hash, so that numba's on-disk cache keeps the compiled
    machine code between processes (a first compilation takes seconds per kernel).
    """
    src = "\n".join(lines) + "\n"
    key = hashlib.sha256(f"{numba.__version__}\n{src}".encode()).hexdigest()[:20]
    folder = _kernel_dir()
    if folder is not None:
        path = folder / f"k_{key}.py"
        try:
            if not path.exists():
                tmp = folder / f".k_{key}.{os.getpid()}.tmp"
                header = (f"# {label}\n# generated by bayesmodal._nl_kernels\n"
                          "import math\n\nimport numpy as np\n\n"
                          "from bayesmodal._nl_kernels import fma\n\n")
                tmp.write_text(header + src)
                os.replace(tmp, path)
            name = f"_bayesmodal_kernel_{key}"
            module = sys.modules.get(name)
            if module is None:
                spec = importlib.util.spec_from_file_location(name, path)
                module = importlib.util.module_from_spec(spec)
                sys.modules[name] = module  # numba's cache re-imports it by name
                spec.loader.exec_module(module)
            return njit(cache=True, **_JIT)(module.kernel)
        except OSError:
            pass
    namespace: dict = {"np": np, "math": math, "fma": fma}
    exec(compile(src, label, "exec"), namespace)  # noqa: S102
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


def _lane_inputs(lines: list[str], width: int, packed_from: int | None = None) -> list[str]:
    """Kernel source reading a per-lane input: ``uk = u[k * width + b]`` in each lane loop.

    The shared-input kernels read ``uk = u[k]`` once per sample (``_head``); their per-lane
    variants get ``u`` as an ``(N, width)`` block and read the lane's own sample at the top
    of every ``for b in range(...)`` loop (an unused read is removed by the compiler).  In
    loops after line ``packed_from`` the lanes are packed slots whose inputs the kernel
    copied to ``UU`` (a contiguous read keeps those loops vectorised; a gather did not).
    """
    out = []
    for i, line in enumerate(lines):
        out.append(line)
        if line.strip().startswith("for b in range("):
            packed = packed_from is not None and i >= packed_from
            indent = line[: len(line) - len(line.lstrip())] + "    "
            out.append(f"{indent}uk = UU[b]" if packed else f"{indent}uk = u[k * {width} + b]")
    return out


def _pack_input(u: np.ndarray, lanes: np.ndarray) -> np.ndarray:
    """Shared input (N,) as is, or the lanes' rows of a per-lane input (nb, N) as a flat
    lane-innermost ``(N, width)`` block."""
    if u.ndim == 1:
        return u
    return np.ascontiguousarray(u[lanes].T).ravel()


def run_batched(kernel_for_width, params, state, u, n_out: int, *args) -> np.ndarray:
    """Run ``kernel(P, X, u, *args, Y)`` over the batch in chunks of lanes.

    Parameters
    ----------
    kernel_for_width : callable
        ``width -> compiled kernel``.
    params, state : list of ndarray, each shape (nb, ...)
        Per-lane parameter and initial-state arrays, packed in this order.
    u : ndarray, shape (N,) or (nb, N)
        Input samples, shared by all lanes or one row per lane (the kernel is then
        ``kernel_for_width(width, per_lane=True)``).
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
    kernel = kernel_for_width(width) if u.ndim == 1 else kernel_for_width(width, per_lane=True)
    N = u.shape[-1]
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        kernel(_pack(params, lanes), _pack(state, lanes), _pack_input(u, lanes), *args,
               Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]


def _head(signature: str, n_out: int, width: int, state: _Rows,
          per_lane: bool = False) -> list[str]:
    """Kernel start: the sample loop and the output of the first ``n_out`` state rows.

    With ``per_lane`` the input ``u`` is an ``(N, width)`` block and ``uk`` is not read
    here (see ``_lane_inputs``)."""
    loop = [f"    for k in range(u.shape[0] // {width}):"] if per_lane else [
        "    for k in range(u.shape[0]):", "        uk = u[k]"]
    return [
        f"def kernel({signature}):",
        *loop,
        f"        yo = k * {n_out * width}",
        f"        for b in range({width}):",
    ] + [f"            Y[yo + {i * width} + b] = {state('x', i)}" for i in range(n_out)]


# ---------------------------------------------------------------------------------------
# linear recursion with a shifted, clipped input per lane (delay, saturation, motor lag)
@functools.lru_cache(maxsize=32)
def linear_input_kernel(n_states: int, n_out: int, width: int, shifted: bool, clipped: bool,
                        per_lane: bool = False):
    """Compiled ``kernel(P, X, up, shift, Y)`` for the recursion (see ``linear_input_run``).

    Without ``shifted`` every lane reads the same input sample (and ``B1`` is not used);
    without ``clipped`` the input is not clipped.  With ``per_lane`` ``up`` is a flat
    ``(N_padded, width)`` block, one input column per lane.
    """
    s, w = n_states, width
    P = _Rows("P", w, [("A", s * s), ("B1", s), ("B2", s), ("lo", 1), ("hi", 1)])
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
    L += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        prods = [(P('A', i * s + j), f"x{j}") for j in range(s)]
        if shifted:
            prods.insert(0, (P('B1', i), "ua"))
        L.append(f"            {X('x', i)} = {_fma_sum(P('B2', i) + ' * ub', prods)}")
    return _compile(L, f"<bayesmodal linear-input s={s} o={n_out} w={w} "
                       f"shift={shifted} clip={clipped} per_lane={per_lane}>")


def linear_input_run(Ad, B1, B2, u, x0, n_out, *, shift=None, level=None):
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
    kernel = linear_input_kernel(s, n_out, width, shifted, clipped, per_lane)
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)
        P = _pack([Ad, B1, B2, -lvl, lvl], lanes)
        X = _pack([x0], lanes)
        kernel(P, X, _pack_input(up, lanes), np.ascontiguousarray(pad - 1 - m[lanes]),
               Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2)
    if n_chunks == 1:
        return y[0, :nb]
    return y.reshape(n_chunks * width, N, n_out)[:nb]


# ---------------------------------------------------------------------------------------
# Coulomb friction with stick-slip
def _held_force(P, n: int, i: int, fe: str, x: str) -> str:
    """Code of cart i's net force at the step end were it held at ``x`` (velocity 0):
    the end force ``fe`` without the cart's own spring and damper motion over the step."""
    s = 2 * n
    return f"{fe} + {P('G', i * s + i)} * ({x} - n{i}) - {P('G', i * s + n + i)} * n{n + i}"


def _force_rates(P, n: int, i: int) -> tuple[list, list]:
    """The products whose sums are the rates of change of cart i's net force at the step
    start and end, N/s: ``G`` times the velocities and accelerations (``x{n+j}``,
    ``A0_j``; ``V1_j``, ``A1_j``)."""
    s, C = 2 * n, range(n)
    r0 = ([(P("G", i * s + j), f"x{n + j}") for j in C]
          + [(P("G", i * s + n + j), f"A0_{j}") for j in C])
    r1 = ([(P("G", i * s + j), f"V1_{j}") for j in C]
          + [(P("G", i * s + n + j), f"A1_{j}") for j in C])
    return r0, r1


def _sum(products) -> str:
    """Code of ``sum(a * b)``."""
    return " + ".join(f"{a} * {b}" for a, b in products)


def _kinetic(i: int, d: str, asym: bool) -> str:
    """Code of cart i's kinetic friction level when sliding in direction ``d`` (+-1): one
    level ``fc{i}``, or with ``asym`` ``fp{i}`` forwards and ``fn{i}`` backwards."""
    return f"(fp{i} if {d} > 0.0 else fn{i})" if asym else f"fc{i}"


def _coulomb_load(t, P, X, n, asym=False) -> list[str]:
    """Code loading a lane's state and friction parameters into scalars."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    for i in C:
        L += [f"{t}st{i} = {X('st', i)} != 0.0", f"{t}d{i} = {X('d', i)}",
              f"{t}xs{i} = {X('xs', i)}", f"{t}fc{i} = {P('fc', i)}", f"{t}fs{i} = {P('fs', i)}",
              f"{t}gb{i} = {P('gb', i)}", f"{t}mi{i} = {P('mi', i)}"]
        if asym:
            L += [f"{t}fp{i} = fc{i}", f"{t}fn{i} = {P('fn', i)}"]
    return L


def _coulomb_predict(t, P, n, mats, asym=False) -> list[str]:
    """Code of the friction decision at the step start and the state predicted with it
    held over the step (matrices ``mats = (A, B, F, R)`` of the step: input, held and
    ramped force responses), the net forces at the end (``Fe``) and the velocities and
    accelerations at both ends."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    # friction over the sub-step: stuck carts hold the net force (or break away at once
    # when the input jumped past Fs), sliding carts get -Fc dir; written as selects (no
    # nested branches) so that the compiler vectorises across lanes
    for i in C:
        gz = " + ".join(f"{P('G', i * s + j)} * x{j}" for j in R)
        L += [f"{t}F{i} = gb{i} * uk + {gz}",
              f"{t}aF{i} = abs(F{i})",
              f"{t}hold = st{i} & (aF{i} < fs{i})",
              f"{t}d{i} = math.copysign(1.0, F{i}) if st{i} != hold else d{i}",
              f"{t}f{i} = -F{i} if hold else -{_kinetic(i, f'd{i}', asym)} * d{i}",
              f"{t}st{i} = hold"]
    for r in R:
        prods = [(P(mats[0], r * s + j), f"x{j}") for j in R]
        prods += [(P(mats[2], r * n + j), f"f{j}") for j in C]
        L.append(f"{t}n{r} = {P(mats[1], r)} * uk + {_sum(prods)}")

    def end_force(i):
        return f"{t}Fe{i} = gb{i} * uk + {_sum((P('G', i * s + j), f'n{j}') for j in R)}"

    # net forces at the end; a held cart's force changed over the step, and holding it
    # with its start value would let it drift and pull on its neighbours: hold it with
    # the force ramping to its end value instead (one correction with the ramp response)
    for i in C:
        # (a product with 1 or 0, not a branch: the compiler would sink the end force
        # into the branch and not vectorise the loop)
        L += [end_force(i),
              f"{t}df{i} = (1.0 if st{i} else 0.0) * (F{i} -"
              f" ({_held_force(P, n, i, f'Fe{i}', f'xs{i}')}))"]
    for r in R:
        prods = [(P(mats[3], r * n + j), f"df{j}") for j in C]
        L.append(f"{t}n{r} = {_fma_sum(f'n{r}', prods)}")
    # net forces at the end again, and the rates of change of the net force at both ends
    # (G times velocities and accelerations; held carts neither move nor accelerate)
    for i in C:
        L += [end_force(i),
              f"{t}A0_{i} = (F{i} + f{i}) * mi{i}",
              f"{t}A1_{i} = 0.0 if st{i} else (Fe{i} + f{i}) * mi{i}",
              f"{t}V1_{i} = 0.0 if st{i} else n{n + i}"]
    return L


def _coulomb_events(t, P, n, asym=False) -> list[str]:
    """Code locating and correcting the events inside a step (see ``coulomb_run``)."""
    L: list[str] = []
    for i in range(n):
        v = n + i
        r0, r1 = (_sum(r) for r in _force_rates(P, n, i))
        L += [f"{t}Fe = Fe{i}",
              # stuck: did the net force on the held cart reach Fs inside the step?
              # (on its cubic Hermite interpolant in time, Newton from the chord)
              f"{t}Fh = {_held_force(P, n, i, 'Fe', f'xs{i}')}",
              f"{t}aE = abs(Fh)",
              f"{t}slip = st{i} & (aE >= fs{i})",
              f"{t}db = math.copysign(1.0, Fh)",
              f"{t}ab = (fs{i} - aF{i}) / (aE - aF{i})",
              f"{t}ab = ab if slip & (aE > aF{i}) else 0.0",
              f"{t}ab = (0.0 if ab < 0.0 else (1.0 if ab > 1.0 else ab))",
              f"{t}q0 = db * F{i}",
              f"{t}q1 = db * Fh",
              f"{t}k0 = db * h * ({r0})",
              f"{t}k1 = db * h * ({r1})",
              # q(s) = q0 + s (k0 + s (c2 + s c3)), the Hermite cubic in power form
              f"{t}c2 = 3.0 * (q1 - q0) - 2.0 * k0 - k1",
              f"{t}c3 = 2.0 * (q0 - q1) + k0 + k1",
              f"{t}qs = q0 - fs{i}"]
        L += _rising_cubic_root(t, "ab", ("qs", "k0", "c2", "c3"))
        L += [f"{t}ab = ab if slip else 0.0",
              # velocity and displacement gained from the break-away to the end of the
              # step under the net force q(s) less the kinetic level: integrals of
              # (q - Fc) and (1 - s)(q - Fc) over [ab, 1] (antiderivatives J1 and J2)
              f"{t}p0 = q0 - {_kinetic(i, 'db', asym)}",
              f"{t}j1 = ab * (p0 + ab * (0.5 * k0 + ab * ({1 / 3!r} * c2 + 0.25 * ab * c3)))",
              f"{t}j2 = ab * ab * (0.5 * p0 + ab * ({1 / 3!r} * k0 + ab * (0.25 * c2"
              f" + 0.2 * ab * c3)))",
              f"{t}i0 = p0 + 0.5 * k0 + {1 / 3!r} * c2 + 0.25 * c3 - j1",
              f"{t}i1 = 0.5 * p0 + {1 / 3!r} * k0 + 0.25 * c2 + 0.2 * c3 - j2",
              f"{t}dvb = db * mi{i} * h * i0",
              f"{t}dxb = db * mi{i} * h * h * (i0 - i1)",
              # sliding: a velocity reversal inside the step, located on the cubic Hermite
              # interpolant of the velocity (end values and accelerations)
              f"{t}v0 = x{v}",
              f"{t}v1 = n{v}",
              f"{t}rev = (not st{i}) & (d{i} * v1 < 0.0)",
              f"{t}a = v0 / (v0 - v1)",
              f"{t}a = a if v0 != v1 else 0.0",
              f"{t}a = (0.0 if a < 0.0 else (1.0 if a > 1.0 else a))",
              f"{t}m0 = (F{i} + f{i}) * mi{i} * h",
              f"{t}m1 = (Fe + f{i}) * mi{i} * h",
              # v(s) = v0 + s (m0 + s (e2 + s e3))
              f"{t}e2 = 3.0 * (v1 - v0) - 2.0 * m0 - m1",
              f"{t}e3 = 2.0 * (v0 - v1) + m0 + m1"]
        for _ in range(REVERSAL_NEWTON):
            L += [f"{t}g = v0 + a * (m0 + a * (e2 + a * e3))",
                  f"{t}dg = m0 + a * (2.0 * e2 + 3.0 * a * e3)",
                  f"{t}an = a - g / dg",
                  f"{t}a = an if dg != 0.0 else a",
                  f"{t}a = (0.0 if a < 0.0 else (1.0 if a > 1.0 else a))"]
        L += [f"{t}tau = (1.0 - a) * h",
              # stick if the net force at the crossing is below Fs, else slide back
              f"{t}stick = rev & (abs(F{i} + a * (Fe - F{i})) < fs{i})",
              f"{t}flip = rev != stick",
              # the friction after the crossing, fc(-d) d, instead of -fc(d) d
              f"{t}dv = {_reversal_levels(i, asym)} * d{i} * mi{i} * tau",
              f"{t}dv = dv if flip else 0.0",
              # distance travelled after the crossing: integral of the interpolant
              f"{t}after = h * (v0 + 0.5 * m0 + {1 / 3!r} * e2 + 0.25 * e3"
              f" - a * (v0 + a * (0.5 * m0 + a * ({1 / 3!r} * e2 + 0.25 * a * e3))))",
              f"{t}pa = n{i} - after",
              f"{t}pb = n{i} + 0.5 * dv * tau",
              f"{t}p = pa if stick else pb",
              # stuck at the crossing, but the held net force reaches Fs again before
              # the end of the step: break away there (linear in time from the crossing)
              f"{t}Fk = {_held_force(P, n, i, 'Fe', 'p')}",
              f"{t}aK = abs(Fk)",
              f"{t}brk = stick & (aK >= fs{i})",
              f"{t}dk = math.copysign(1.0, Fk)",
              f"{t}qx = dk * (F{i} + a * (Fe - F{i}))",
              f"{t}ak = a + (1.0 - a) * (fs{i} - qx) / (aK - qx)",
              f"{t}ak = ak if brk & (aK > qx) else 1.0",
              f"{t}ak = (a if ak < a else (1.0 if ak > 1.0 else ak))",
              f"{t}tk = (1.0 - ak) * h",
              f"{t}dvk = dk * (0.5 * (aK + fs{i}) - {_kinetic(i, 'dk', asym)}) * mi{i} * tk",
              f"{t}dxk = dk * mi{i} * tk * tk * ({1 / 6!r} * aK + {1 / 3!r} * fs{i}"
              f" - 0.5 * {_kinetic(i, 'dk', asym)})",
              f"{t}pk = p + dxk",
              f"{t}p = pk if brk else p",
              f"{t}xb = xs{i} + dxb",
              f"{t}xh = xb if slip else xs{i}",
              f"{t}n{i} = xh if st{i} else p",
              f"{t}vh = dvb if slip else 0.0",
              f"{t}vk = dvk if brk else 0.0",
              f"{t}vf = v1 + dv",
              f"{t}vs = vk if stick else vf",
              f"{t}n{v} = vh if st{i} else vs",
              f"{t}xs{i} = p if stick else xs{i}",
              f"{t}dr = -d{i} if flip else d{i}",
              f"{t}dr = dk if brk else dr",
              f"{t}d{i} = db if slip else dr",
              f"{t}st{i} = (st{i} != slip) | (stick != brk)"]
    return L


def _reversal_levels(i: int, asym: bool) -> str:
    """Code of ``fc(d) + fc(-d)`` for cart i sliding in direction ``d{i}``."""
    return f"(fp{i} + fn{i})" if asym else f"2.0 * fc{i}"


def _coulomb_store(t, X, n) -> list[str]:
    """Code storing a lane's state."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    L += [f"{t}{X('x', r)} = n{r}" for r in R]
    for i in C:
        L += [f"{t}{X('st', i)} = 1.0 if st{i} else 0.0", f"{t}{X('d', i)} = d{i}",
              f"{t}{X('xs', i)} = xs{i}"]
    return L


def _coulomb_quiet_step(t, P, X, n, mats, step, asym=False) -> list[str]:
    """Code of a step without event corrections that counts the lanes needing them.

    Saves the lane's state in ``S``, takes the step with the matrices ``mats`` (of length
    ``step``) and keeps held carts in place.  The lane's flag (the last row of ``S``) is
    set, and ``ev`` counts it, if any cart had or may have had an event in the step: the
    velocity of a sliding cart or the held force of a stuck one tested at the end, at the
    midpoint of its cubic Hermite interpolant and on the linear extrapolations from both
    ends (a velocity dipping through zero and back, or a held force peaking past ``Fs``
    inside the step, which the end values alone would hide).
    """
    C, w = range(n), X.width
    L = [f"{t}S[{r * w} + b] = {X.array}[{r * w} + b]" for r in range(X.size)]
    L += _coulomb_load(t, P, X, n, asym)
    L += _coulomb_predict(t, P, n, mats, asym)
    flags = []
    for i in C:
        v = n + i
        r0, r1 = (_fma_sum("0.0", r) for r in _force_rates(P, n, i))
        L += [f"{t}q1 = {_held_force(P, n, i, f'Fe{i}', f'xs{i}')}",
              f"{t}k0 = {step} * ({r0})",
              f"{t}k1 = {step} * ({r1})",
              f"{t}qm = 0.5 * (F{i} + q1) + 0.125 * (k0 - k1)",
              f"{t}hit = ((abs(q1) >= fs{i}) | (abs(qm) >= fs{i}) | (abs(F{i} + k0) >= fs{i})"
              f" | (abs(q1 - k1) >= fs{i}))",
              f"{t}m0 = A0_{i} * {step}",
              f"{t}m1 = A1_{i} * {step}",
              f"{t}vm = 0.5 * (x{v} + n{v}) + 0.125 * (m0 - m1)",
              f"{t}turn = ((d{i} * n{v} < 0.0) | (d{i} * vm < 0.0) | (d{i} * (x{v} + m0) < 0.0)"
              f" | (d{i} * (n{v} - m1) < 0.0))",
              f"{t}ev{i} = hit if st{i} else turn",
              f"{t}n{i} = xs{i} if st{i} else n{i}",
              f"{t}n{v} = 0.0 if st{i} else n{v}"]
        flags.append(f"ev{i}")
    L += [f"{t}e = {' | '.join(flags)}",
          f"{t}S[{X.size * w} + b] = 1.0 if e else 0.0",
          f"{t}ev += 1 if e else 0"]
    return L + _coulomb_store(t, X, n)


def _coulomb_at_rest(t, P, X, n) -> list[str]:
    """Code adding 1 to ``nq`` for a lane at rest over the coming step.

    A lane is at rest when every cart is stuck and each one's net force at the step start
    is below its static level by more than ``REST_MARGIN`` times the size of the terms
    it sums.  Over a step with the input held, such a lane's state does not change: the
    quick step would return it bit for bit (held carts are put back where they stuck,
    with velocity 0, and no held force can reach ``Fs``: the rounding of the quick step
    is ~1e-16 of the same terms), so the kernel skips the step for a group of lanes all
    at rest.  The test depends on the lane's own state only, and skipping changes no
    result: the output is the same whatever the batch.
    """
    s = 2 * n
    L: list[str] = [f"{t}rest = True"]
    for i in range(n):
        terms = [f"{P('gb', i)} * uk"] + [f"{P('G', i * s + j)} * {X('x', j)}"
                                          for j in range(s)]
        L += [f"{t}Fq = {' + '.join(terms)}",
              f"{t}mq = {' + '.join(f'abs({term})' for term in terms)}",
              f"{t}rest = rest & ({X('st', i)} != 0.0)"
              f" & (abs(Fq) + {REST_MARGIN!r} * mq < {P('fs', i)})"]
    return L + [f"{t}nq += 1 if rest else 0"]


@functools.lru_cache(maxsize=16)
def coulomb_kernel(n: int, width: int, adaptive: bool = True, per_lane: bool = False,
                   asymmetric: bool = False):
    """Compiled stick-slip Coulomb friction kernel (see ``coulomb_run``).

    The kernel returns how many packed groups of lanes took a sample again in sub-steps
    and how many times a group at rest skipped a sample (both 0 without ``adaptive``).
    With ``per_lane`` the input is one column per lane (see ``_lane_inputs``); with
    ``asymmetric`` the kinetic level depends on the direction of sliding (parameter rows
    ``fc`` forwards, ``fn`` backwards).
    """
    asym = bool(asymmetric)
    w = width
    s = 2 * n
    p_rows = [("A", s * s), ("bh", s), ("fh", s * n), ("rh", s * n), ("Ad", s * s), ("bd", s),
              ("fd", s * n), ("rd", s * n), ("G", n * s), ("gb", n), ("mi", n), ("fc", n),
              ("fs", n)] + ([("fn", n)] if asym else [])
    x_rows = [("x", s), ("st", n), ("d", n), ("xs", n)]
    P, X = _Rows("P", w, p_rows), _Rows("X", w, x_rows)
    L = _head("P, X, u, n_sub, h, Y", n, w, X, per_lane)
    L[1:1] = ["    nref = 0", "    nrest = 0"]

    def corrected(t, P, X):
        return (_coulomb_load(t, P, X, n, asym)
                + _coulomb_predict(t, P, n, ("A", "bh", "fh", "rh"), asym)
                + _coulomb_events(t, P, n, asym) + _coulomb_store(t, X, n))

    if not adaptive:
        L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
        L += corrected(" " * 16, P, X)
        L += ["    return nref, nrest"]
        if per_lane:
            return _compile(_lane_inputs(L, w),
                            f"<bayesmodal coulomb n={n} w={w} per-lane{' asym' * asym}>")
        return _compile(L, f"<bayesmodal coulomb n={n} w={w}{' asym' * asym}>")
    # S: state at the start of the sample, and a last row with the lane's event flag (one
    # array less for the vectoriser to check for aliasing).  Lanes with an event are
    # packed (parameters PP, state XX) into groups of g and take the sample again there;
    # S2: state at the start of a sub-step and flags, T2: the quick results
    g = min(w, REFINE_GROUP)
    PP, XX = _Rows("PP", g, p_rows), _Rows("XX", g, x_rows)
    flag2 = X.size * g
    L[1:1] = [f"    S = np.empty(X.shape[0] + {w})",
              f"    PP = np.empty({P.size * g})", f"    XX = np.empty({X.size * g})",
              f"    S2 = np.empty({(X.size + 1) * g})", f"    T2 = np.empty({X.size * g})",
              f"    idx = np.empty({w}, np.int64)",
              f"    slot = np.zeros({g}, np.int64)",
              "    dt = h * n_sub",
              # unused packed slots hold copies of lane 0 (valid numbers)
              f"    for j in range({g}):",
              f"        for r in range({P.size}):",
              f"            PP[r * {g} + j] = P[r * {w}]",
              f"        for r in range({X.size}):",
              f"            XX[r * {g} + j] = X[r * {w}]"]
    rows = range(X.size)

    def retake(t, start, result):
        # keep the quick step's result, go back to the step's start
        return ([f"{t}for b in range({g}):"]
                + [f"{t}    {result}[{r * g} + b] = XX[{r * g} + b]" for r in rows]
                + [f"{t}    XX[{r * g} + b] = {start}[{r * g} + b]" for r in rows])

    def keep_quick(t, start, result):
        # lanes without an event take the quick step's result: every lane's result
        # depends on its own parameters only, never on the other lanes of its group
        return ([f"{t}for b in range({g}):"]
                + [f"{t}    XX[{r * g} + b] = XX[{r * g} + b] if {start}[{flag2} + b] != 0.0"
                   f" else {result}[{r * g} + b]" for r in rows])

    # a group whose lanes are all at rest skips the sample (the state does not change);
    # the others take the sample in one step, and the lanes with an event in it take it
    # again in sub-steps, packed into groups: each sub-step first without corrections and
    # again with them where a lane of the packed group needs them
    L += ["        nf = 0",
          f"        for g0 in range(0, {w}, {g}):",
          "            nq = 0",
          f"            for b in range(g0, g0 + {g}):"]
    L += _coulomb_at_rest(" " * 16, P, X, n)
    L += [f"            if nq == {g}:", "                nrest += 1", "                continue",
          "            ev = 0",
          f"            for b in range(g0, g0 + {g}):"]
    L += _coulomb_quiet_step(" " * 16, P, X, n, ("Ad", "bd", "fd", "rd"), "dt", asym)
    L += ["            if ev > 0:",
          f"                for b in range(g0, g0 + {g}):",
          f"                    if S[{X.size * w} + b] != 0.0:",
          "                        idx[nf] = b",
          "                        nf += 1",
          f"        for c0 in range(0, nf, {g}):",
          "            nref += 1",
          f"            m = min({g}, nf - c0)",
          "            for j in range(m):",
          "                bj = idx[c0 + j]",
          # a slot keeps its lane's parameters until another lane is packed there (the
          # rows of the whole-sample step, Ad to rd, are not used in sub-steps)
          "                if slot[j] != bj:",
          "                    slot[j] = bj",
          f"                    for r in range({P.offset['Ad']}):",
          f"                        PP[r * {g} + j] = P[r * {w} + bj]",
          f"                    for r in range({P.offset['G']}, {P.size}):",
          f"                        PP[r * {g} + j] = P[r * {w} + bj]",
          f"                for r in range({X.size}):",
          f"                    XX[r * {g} + j] = S[r * {w} + bj]",
          "            for sub in range(n_sub):",
          "                ev = 0",
          f"                for b in range({g}):"]
    L += [line.replace("S[", "S2[") for line in
          _coulomb_quiet_step(" " * 20, PP, XX, n, ("A", "bh", "fh", "rh"), "h", asym)]
    L += ["                if ev > 0:"] + retake(" " * 20, "S2", "T2")
    L += [f"                    for b in range({g}):"]
    L += corrected(" " * 24, PP, XX)
    L += keep_quick(" " * 20, "S2", "T2")
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
                        f"<bayesmodal coulomb n={n} w={w} adaptive per-lane{' asym' * asym}>")
    return _compile(L, f"<bayesmodal coulomb n={n} w={w} adaptive{' asym' * asym}>")


def coulomb_run(Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, G, gb, minv, Fc, Fs, u, n_sub, h, x0, *,
                adaptive=True, Fc_backward=None):
    """Stick-slip Coulomb friction on every cart (see ``extensions.coulomb``).

    A step: the friction force of each cart is decided at its start (stuck carts hold the
    net force, ``f = -F``, while ``|F| < Fs``, or break away at once if the input jumped
    past ``Fs``; sliding carts get ``f = -Fc dir``) and the state is advanced exactly with
    that force held, a stuck cart's holding force ramping to its end value (one
    correction with the ramp response, so that the held cart does not drift and pull on
    its neighbours).  That is all a step without an event needs.

    Each sample is first taken in one such step.  A lane that had, or may have had, an
    event in it (see ``_coulomb_quiet_step``) takes the sample again in ``n_sub``
    sub-steps ``h``, each again first quick and then, for a lane with an event in it, with
    the events located on cubic Hermite interpolants in time (values and rates at both
    ends; Newton from the chord, safeguarded for the break-away) and corrected:

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
    packed into groups of ``REFINE_GROUP`` that take it again in sub-steps.  A packed
    group takes the corrected path in a sub-step when one of its lanes needs it, but every
    lane keeps the result of the path its own flags chose: the output of a parameter set
    never depends on the others in the batch.  The error is second order in the sub-step
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

    Returns
    -------
    ndarray, shape (nb, N, n)
        Positions, a view of the kernel's output buffer.
    """
    n = Fc.shape[1]
    v = x0[:, n:]
    state = [x0, v == 0.0, np.sign(v), x0[:, :n]]
    params = [Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, G, gb, minv, Fc, Fs]
    if Fc_backward is not None:
        params.append(Fc_backward)
    kernel = functools.partial(coulomb_kernel, n, adaptive=bool(adaptive))
    if Fc_backward is not None:
        kernel = functools.partial(kernel, asymmetric=True)
    return run_batched(kernel, params, state, u, n, int(n_sub), float(h))


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
def cubic_kernel(n: int, width: int, per_lane: bool = False):
    """Compiled cubic-spring kernel (see ``cubic_run``); ``per_lane``: see ``_lane_inputs``."""
    s, w = 2 * n, width
    R, C = range(s), range(n)
    P = _Rows("P", w, [("A", s * s), ("bh", s), ("p", s * n), ("q", s * n), ("k3", n)])
    X = _Rows("X", w, [("x", s)])
    L = _head("P, X, u, n_sub, Y", n, w, X, per_lane)
    L += ["        for sub in range(n_sub):", f"            for b in range({w}):"]
    t = "                "
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    L += [f"{t}k3_{i} = {P('k3', i)}" for i in C]
    L += _cubic_force_lines(t, n, "x", "f")
    for r in R:
        prods = ([(P('A', r * s + j), f"x{j}") for j in R]
                 + [(P('p', r * n + j), f"f{j}") for j in C])
        L.append(f"{t}y{r} = {_fma_sum(P('bh', r) + ' * uk', prods)}")
    L += _cubic_force_lines(t, n, "y", "g")
    for r in R:
        prods = [(P('q', r * n + j), f"(g{j} - f{j})") for j in C]
        L.append(f"{t}{X('x', r)} = {_fma_sum(f'y{r}', prods)}")
    if per_lane:
        return _compile(_lane_inputs(L, w), f"<bayesmodal cubic n={n} w={w} per-lane>")
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
def backlash_kernel(n: int, width: int, per_lane: bool = False):
    """Compiled backlash kernel (see ``backlash_run``); ``per_lane``: see ``_lane_inputs``."""
    s, w = 2 * n, width
    R = range(s)
    P = _Rows("P", w, [("Ae", s * s), ("be", s), ("Ad", s * s), ("ge", s), ("mt", 1),
                       ("mp", 1), ("imt", 1), ("imc", 1), ("imp", 1), ("gv", 1),
                       ("half", 1)])
    X = _Rows("X", w, [("x", s), ("eng", 1), ("side", 1), ("xm", 1), ("vm", 1),
                       ("fp", 1)])
    L = _head("P, X, u, n_sub, h, Y", n, w, X, per_lane)
    t = "                "
    if per_lane:
        # the last sub-step's input: the previous sample's in the first sub-step
        L[1:1] = ["    ih2 = 1.0 / (h * h)"]
        L += ["        ko = (k - 1 if k > 0 else 0) * " + str(w),
              "        for sub in range(n_sub):",
              f"            for b in range({w}):",
              f"{t}uk = u[k * {w} + b]",
              f"{t}uo = u[ko + b] if sub == 0 else uk"]
    else:
        L[1:1] = ["    u_prev = u[0]", "    ih2 = 1.0 / (h * h)"]
        L += ["        for sub in range(n_sub):",
              "            uo = u_prev",
              "            u_prev = uk",
              f"            for b in range({w}):"]
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    f1 = " + ".join(f"{P('ge', j)} * x{j}" for j in R)
    L += [f"{t}engaged = {X('eng')} != 0.0",
          f"{t}side = {X('side')}",
          f"{t}xm = {X('xm')}",
          f"{t}vm = {X('vm')}",
          f"{t}fcon_prev = {X('fp')}",
          f"{t}half = {P('half')}",
          f"{t}mp = {P('mp')}",
          f"{t}mc = {P('mt')} - mp",
          f"{t}imt = {P('imt')}",
          f"{t}imc = {P('imc')}",
          f"{t}fm = {P('gv')} * uk",
          f"{t}am = fm * {P('imp')}",
          f"{t}fo = {P('gv')} * uo",
          # engaged: the contact force on cart 1, with this and the last sub-step's input
          f"{t}F1 = {f1}",
          f"{t}fcon = (mc * fm - mp * F1) * imt",
          f"{t}fcon_o = (mc * fo - mp * F1) * imt",
          # the contact force crossed zero inside the last sub-step: since then cart 1 and
          # the motor have moved apart under that sub-step's input, second-order correction
          f"{t}late = engaged and half != 0.0 and side * fcon_o < 0.0"
          " and side * fcon_prev > 0.0",
          f"{t}pull = engaged and (late or side * fcon < 0.0)",
          f"{t}opening = pull and half != 0.0",
          f"{t}side = -side if pull and half == 0.0 else side",
          f"{t}tau = h * fcon_o / (fcon_o - fcon_prev) if late else 0.0",
          f"{t}a1e = (F1 + fo) * imt",
          f"{t}dv1 = (F1 * imc - a1e) * tau",
          f"{t}dvm = (fo * {P('imp')} - a1e) * tau",
          f"{t}xm = x0 + side * half + 0.5 * dvm * tau if opening else xm",
          f"{t}vm = x{n} + dvm if opening else vm",
          f"{t}x0 += 0.5 * dv1 * tau",
          f"{t}x{n} += dv1",
          f"{t}fcon_prev = fcon if engaged else fcon_prev",
          f"{t}engaged = engaged and not opening",
          f"{t}if engaged:"]
    for r in R:
        prods = [(P('Ae', r * s + j), f"x{j}") for j in R]
        L.append(f"{t}    y{r} = {_fma_sum(f'{P(chr(98) + chr(101), r)} * uk', prods)}")
    L += [f"{t}else:"]
    for r in R:
        prods = [(P('Ad', r * s + j), f"x{j}") for j in R]
        L.append(f"{t}    y{r} = {_fma_sum('0.0', prods)}")
    # disengaged: the motor moves freely; a plastic impact when the gap closes, located
    # on the quadratic through delta0, its slope vrel0 and delta (Newton from the chord)
    L += [f"{t}delta0 = xm - x0",
          f"{t}vrel0 = vm - x{n}",
          f"{t}xm += vm * h + 0.5 * am * h * h",
          f"{t}vm += am * h",
          f"{t}delta = xm - y0",
          f"{t}hit = not engaged and abs(delta) >= half",
          f"{t}sd = 1.0 if delta > 0.0 else -1.0",
          f"{t}e0 = delta0 - sd * half",
          f"{t}tq = h * e0 / (delta0 - delta) if delta != delta0 else h",
          f"{t}tq = 0.0 if tq < 0.0 else (h if tq > h else tq)",
          f"{t}cq = (delta - delta0 - vrel0 * h) * ih2"]
    for _ in range(IMPACT_NEWTON):
        L += [f"{t}dg = vrel0 + 2.0 * cq * tq",
              f"{t}tq = tq - (e0 + (vrel0 + cq * tq) * tq) / dg if dg != 0.0 else tq",
              f"{t}tq = 0.0 if tq < 0.0 else (h if tq > h else tq)"]
    # momentum after the impact; since the impact (tau ago) cart 1's damper acted on the
    # common velocity, and cart 1 accelerated as engaged: second-order corrections
    L += [f"{t}tau = h - tq",
          f"{t}vc = (mp * vm + mc * y{n}) * imt",
          f"{t}jump = vc - y{n}",
          f"{t}vc += {P('ge', n)} * jump * tau * imt",
          f"{t}dacc = (F1 + fm + {P('ge', n)} * jump) * imt - F1 * imc",
          # if the contact force would pull right after the impact (the motor is braked
          # harder than cart 1), the two only share their momentum and part again
          f"{t}rebound = hit and sd * fcon < 0.0",
          f"{t}a1 = F1 * imc",
          f"{t}vcs = (mp * (vm - am * tau) + mc * (y{n} - a1 * tau)) * imt",
          f"{t}js = vcs - (y{n} - a1 * tau)",
          f"{t}stay = hit and not rebound",
          f"{t}y0 = y0 + (vc - y{n}) * tau - 0.5 * dacc * tau * tau if stay else y0",
          f"{t}y0 = y0 + js * tau if rebound else y0",
          f"{t}y{n} = vc if stay else (y{n} + js if rebound else y{n})",
          f"{t}vm = vcs + am * tau if rebound else vm",
          f"{t}xm = y0 + sd * half + 0.5 * (am - a1) * tau * tau if rebound else xm",
          f"{t}side = sd if hit else side",
          # no contact-force history inside this sub-step for the next opening check
          f"{t}fcon_prev = np.nan if hit else fcon_prev",
          f"{t}engaged = engaged or stay"]
    L += [f"{t}{X('x', r)} = y{r}" for r in R]
    L += [f"{t}{X('eng')} = 1.0 if engaged else 0.0",
          f"{t}{X('side')} = side",
          f"{t}{X('xm')} = xm",
          f"{t}{X('vm')} = vm",
          f"{t}{X('fp')} = fcon_prev"]
    return _compile(L, f"<bayesmodal backlash n={n} w={w}" + (" per-lane>" if per_lane else ">"))


def backlash_run(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, n_sub, h, x0):
    """Rack-pinion backlash with a plastic contact (see ``extensions.backlash``).

    Engaged (``|delta| = gap / 2`` on side ``side``): motor and cart 1 move together; the
    exact linear step ``(Ae, Be)`` applies.  The contact force on cart 1 is
    ``Fcon = ((m1 - m_p) g_v u - m_p F1) / m1`` with ``F1 = Ge z`` the other forces on
    cart 1; the contact opens when ``side * Fcon < 0``, with the motion since the zero
    crossing of ``Fcon`` inside the last sub-step (under that sub-step's input) added to
    cart 1 and the motor.  Disengaged: the carts follow the exact unforced step ``Adis``
    (cart 1 without the motor mass) and the motor is a free mass ``m_p`` under ``g_v u``;
    when ``|delta|`` reaches ``gap / 2`` the contact closes with a plastic impact that
    conserves momentum.  The impact time is the root of the quadratic through ``delta``,
    its slope at the start and its end value (two Newton steps from the chord), and for
    the ``tau`` since the impact cart 1 is corrected to second order: it moved with the
    engaged acceleration, and its damper acted on the common velocity.  If the contact
    force would pull right after the impact, the two only exchange momentum and stay
    apart.  With ``gap = 0`` the contact never opens (it only changes side) and the scheme
    is the linear simulator.  The error is second order in the sub-step.

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
    mc = m1 - m_p
    params = [Ae, Be, Adis, Ge, m1, m_p, 1.0 / m1, 1.0 / mc, 1.0 / m_p, g_v, 0.5 * gap]
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
