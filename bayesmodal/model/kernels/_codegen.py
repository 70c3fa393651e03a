"""Code generation and batching shared by the compiled effect kernels.

``_compile`` turns generated source into a cached numba function, ``_Rows`` names the rows
of the flat lane-innermost blocks, ``run_batched`` packs parameter sets into lanes, pads
and chunks them, and ``fma`` / ``_fma_sum`` / ``_sum`` write the arithmetic.  The layouts
are described in the package docstring (``bayesmodal.model.kernels``).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
import math
import os
import sys
import tempfile
import threading
from pathlib import Path

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .._kernels import (
    ALIGN_BYTES,
    MAX_WIDTH,  # noqa: F401  (the package exports it from here)
    aligned_empty,
)
from .._kernels import padded_width as _linear_width

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


@intrinsic
def select(typingctx, cond, a, b):
    """``a if cond else b`` as one LLVM ``select``, both operands evaluated: no branch.

    The generated kernels hold a hundred or more conditional expressions; as Python
    ``a if c else b`` each splits its block in two, and numba's SSA reconstruction and
    type inference, whose cost grows with the blocks, then took most of a kernel's
    compilation (Coulomb, three carts: 21 of 37 s).  The operands are unified to one
    type (int and float to float, as the conditional expression's result would be)."""
    out = typingctx.unify_pairs(a, b)
    if out is None or not isinstance(out, (types.Number, types.Boolean)):
        return None
    sig = out(cond, a, b)

    def codegen(context, builder, signature, args):
        c, x, y = args
        ct, xt, yt = signature.args
        pred = context.cast(builder, c, ct, types.boolean)
        return builder.select(pred, context.cast(builder, x, xt, signature.return_type),
                              context.cast(builder, y, yt, signature.return_type))

    return sig, codegen


#: Nodes an operand of a conditional expression may hold to become a ``select``: names,
#: constants and float arithmetic on them (no subscript, whose index may be valid only
#: when its branch is taken; no integer division or modulo, which may raise; calls only
#: to the pure functions below).
_SAFE_NODES = (ast.Name, ast.Constant, ast.BinOp, ast.UnaryOp, ast.Compare, ast.BoolOp,
               ast.Load, ast.Attribute, ast.Call, ast.IfExp, ast.operator, ast.unaryop,
               ast.cmpop, ast.boolop)
_SAFE_CALLS = {"abs", "fma", "math.copysign", "pow2_neg", "min", "max"}


def _is_safe(node: ast.AST) -> bool:
    for n in ast.walk(node):
        if not isinstance(n, _SAFE_NODES) or isinstance(n, (ast.FloorDiv, ast.Mod)):
            return False
        if isinstance(n, ast.Call) and ast.unparse(n.func) not in _SAFE_CALLS:
            return False
    return True


class _Selects(ast.NodeTransformer):
    """``a if c else b`` -> ``select(c, a, b)`` where both operands are safe to evaluate."""

    def visit_IfExp(self, node):
        self.generic_visit(node)
        if _is_safe(node.body) and _is_safe(node.orelse):
            return ast.copy_location(ast.Call(ast.Name("select", ast.Load()),
                                              [node.test, node.body, node.orelse], []),
                                     node)
        return node


def branch_free(src: str) -> str:
    """The generated source with its conditional expressions as ``select`` calls
    (``_Selects``): the same values, fewer blocks for numba to compile."""
    tree = _Selects().visit(ast.parse(src))
    return ast.unparse(ast.fix_missing_locations(tree)) + "\n"


@intrinsic
def pow2_neg(typingctx, k):
    """``2^-k`` for an integral ``k`` (a float64, ``0 <= k <= 1022``), its exponent bits
    written directly: ``(1023 - k) << 52`` read as a float64.  Exact; the conversion,
    subtraction and shift vectorise (AVX-512), where ``math.ldexp`` is a library call."""
    sig = types.float64(types.float64)

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        biased = builder.sub(ir.Constant(i64, 1023), builder.fptosi(args[0], i64))
        return builder.bitcast(builder.shl(biased, ir.Constant(i64, 52)), ir.DoubleType())

    return sig, codegen


def _fma_sum(init: str, products) -> str:
    """Code of ``init + sum(a * b)`` as a chain of fused multiply-adds."""
    expr = init
    for a, b in products:
        expr = f"fma({a}, {b}, {expr})"
    return expr


#: Narrowest kernel for a batch of more than ``SCALAR_MAX`` parameter sets.  The compiler
#: vectorises a lane loop only from 16 lanes (8-lane vectors, two per iteration): below
#: that the loop runs one lane at a time, and a 16-lane kernel is faster for 5 to 8 sets
#: (on 8 sets, per call: LuGre 3.8x, Coulomb 1.9x, backlash as fast; docs/performance.md).
MIN_VECTOR_WIDTH = 16
#: Batches of at most this many sets run one set at a time in the one-lane kernel:
#: padding 3-4 sets to 16 lanes costs the Coulomb kernel more than it gains, and a 2- or
#: 4-lane kernel is not vectorised either, so it only adds compiled variants (20 of the
#: default suite's 114 kernels, 15-25 s each for Coulomb) for a speed within the noise of
#: the one-lane kernel's (rig-like input, 2-4 sets: Coulomb 0.8-0.9x the time, LuGre
#: 0.8-1.1x, backlash 0.9-1.2x, cubic 1.2-1.5x of a kernel of 0.7-1.1 ms).
SCALAR_MAX = 4


def padded_width(nb: int) -> int:
    """Kernel width for a batch of ``nb`` parameter sets: 1 for at most ``SCALAR_MAX``
    sets (one chunk each), else a power of two from ``MIN_VECTOR_WIDTH`` to
    ``MAX_WIDTH``."""
    if nb <= SCALAR_MAX:
        return 1
    return max(_linear_width(nb), MIN_VECTOR_WIDTH)


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


#: Intrinsics the generated kernels may call, imported by every generated module.
_INTRINSICS = ("fma", "pow2_neg", "select")

#: One kernel built at a time: threads evaluating walkers side by side
#: (``bayesmodal.inference.threads``) ask for the same kernel at once, and a second thread
#: must not import the module the first has registered but not yet executed.
_COMPILE_LOCK = threading.Lock()


def _compile(lines: list[str], label: str):
    """Compile generated kernel source ``def kernel(...)`` with numba.

    The source (generated from integers only, shapes, never from user text) is written
    once to a file named by its hash, so that numba's on-disk cache keeps the compiled
    machine code between processes (a first compilation takes seconds per kernel).
    Thread-safe.
    """
    with _COMPILE_LOCK:
        src = branch_free("\n".join(lines) + "\n")
        imports = (f"import math\n\nimport numpy as np\n\n"
                   f"from {__name__} import {', '.join(_INTRINSICS)}\n\n")
        # the key covers the imports of the generated file (the module and the names of
        # the intrinsics), so that a file written by another layout of the package, older
        # or newer, is never imported again
        key = hashlib.sha256(f"{numba.__version__}\n{imports}\n{src}".encode()).hexdigest()[:20]
        folder = _kernel_dir()
        if folder is not None:
            path = folder / f"k_{key}.py"
            try:
                if not path.exists():
                    tmp = folder / f".k_{key}.{os.getpid()}.tmp"
                    header = f"# {label}\n# generated by {__name__}\n" + imports
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
        namespace: dict = {"np": np, "math": math, "fma": fma, "pow2_neg": pow2_neg,
                           "select": select}
        exec(compile(src, label, "exec"), namespace)  # noqa: S102
        return njit(**_JIT)(namespace["kernel"])


class _Rows:
    """Named rows of a flat lane-innermost block; ``rows(name, i)`` is the code of element i.

    With ``base`` (the name of a variable of the kernel) element i of lane ``b`` is at
    ``base + row * width + b``: blocks of ``width`` lanes packed one after the other
    (``_pack(..., block=width)``), ``base`` locating the block of lane ``b``.  ``zeros``:
    the ``(name, i)`` elements that are an exact zero in every lane (``nonzero``), whose
    products a kernel's sums may leave out."""

    def __init__(self, array: str, width: int, fields: list[tuple[str, int]],
                 base: str | None = None, zeros: frozenset = frozenset()):
        self.array, self.width, self.base = array, width, base
        self.zeros = frozenset(zeros)
        self.offset: dict[str, int] = {}
        n = 0
        for name, count in fields:
            self.offset[name] = n
            n += count
        self.size = n

    def __call__(self, name: str, i: int = 0) -> str:
        at = f"{(self.offset[name] + i) * self.width} + b"
        return f"{self.array}[{at}]" if self.base is None else f"{self.array}[{self.base} + {at}]"

    def nonzero(self, name: str, i: int = 0) -> bool:
        """False for an element that is an exact zero in every lane (``zeros``)."""
        return (name, i) not in self.zeros


def _aligned_lines(name: str, size: str, dtype: str = "np.float64") -> list[str]:
    """Kernel source allocating the flat array ``name`` of ``size`` elements (code) on
    ``ALIGN_BYTES`` (a view into a slightly larger allocation)."""
    return [f"    {name}_buf = np.empty({size} + {ALIGN_BYTES // 8}, {dtype})",
            f"    {name}_at = (-{name}_buf.ctypes.data % {ALIGN_BYTES}) // 8",
            f"    {name} = {name}_buf[{name}_at : {name}_at + {size}]"]


def _pack(arrays, lanes: np.ndarray, block: int | None = None) -> np.ndarray:
    """Rows of per-lane arrays (each (nb, ...)) as one flat (rows, width) block, or with
    ``block`` as consecutive (rows, block) blocks of ``block`` lanes each; aligned."""
    if block is not None and block < lanes.size:
        parts = [_pack(arrays, lanes[c : c + block]) for c in range(0, lanes.size, block)]
        out = aligned_empty(sum(p.size for p in parts))
        np.concatenate(parts, out=out)
        return out
    width = lanes.size
    cols = [np.asarray(a, dtype=float)[lanes].reshape(width, -1) for a in arrays]
    block_t = np.concatenate(cols, axis=1)
    out = aligned_empty(block_t.size)
    out.reshape(block_t.shape[1], width)[...] = block_t.T
    return out


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
    out = aligned_empty(lanes.size * u.shape[-1])
    out.reshape(u.shape[-1], lanes.size)[...] = u[lanes].T
    return out


def run_batched(kernel_for_width, params, state, u, n_out: int, *args,
                lane_block: int | None = None) -> np.ndarray:
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
    lane_block : int, optional
        Pack the parameters and the state in blocks of this many lanes (a kernel that
        takes its lanes block by block, ``_Rows`` with a ``base``); the input and the
        output keep the chunk's full width.

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
    Y = aligned_empty(n_chunks * N * n_out * width).reshape(n_chunks, N, n_out, width)
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        kernel(_pack(params, lanes, lane_block), _pack(state, lanes, lane_block),
               _pack_input(u, lanes), *args, Y[c].reshape(-1))
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



def interleave(blocks: list[list[str]]) -> list[str]:
    """Lines of several independent code blocks taken in turn, one line of each."""
    out = []
    for j in range(max(map(len, blocks), default=0)):
        out += [block[j] for block in blocks if j < len(block)]
    return out


def _sum(products) -> str:
    """Code of ``sum(a * b)`` (``0.0`` for no products)."""
    return " + ".join(f"{a} * {b}" for a, b in products) or "0.0"


def checked_outputs(outputs, n: int) -> tuple[tuple[int, int], ...]:
    """Sensors ``(k, order)`` as a tuple of integer pairs, degree of freedom ``0..n-1`` and
    order 0-2 (only these reach generated source)."""
    out = tuple((int(k), int(o)) for k, o in outputs)
    for k, o in out:
        if not (0 <= k < n and 0 <= o <= 2):
            raise ValueError(f"outputs must be (dof 0..{n - 1}, order 0..2) pairs, got "
                             f"{(k, o)}")
    return out


def checked_zeros(g_zeros, n: int) -> tuple[int, ...]:
    """``g_zeros`` as sorted distinct flat indices of off-diagonal entries of an ``(n, 2n)``
    matrix ``[-K, -C]`` (never a cart's own spring or damper; only these reach generated
    source)."""
    out = tuple(sorted({int(k) for k in g_zeros}))
    off_diagonal = {i * 2 * n + j for i in range(n) for j in range(2 * n) if j % n != i}
    if not set(out) <= off_diagonal:
        raise ValueError(f"g_zeros must be off-diagonal entries of the ({n}, {2 * n}) "
                         f"matrix G, got {out}")
    return out


def checked_columns(columns, n_acc: int, s: int) -> tuple[tuple[int, ...], ...]:
    """``columns`` as ``n_acc`` tuples of distinct state indices ``0..s-1`` (only these
    reach generated source)."""
    out = tuple(tuple(int(j) for j in c) for c in columns)
    if len(out) != n_acc or any(len(set(c)) != len(c) or not all(0 <= j < s for j in c)
                                for c in out):
        raise ValueError(f"columns must be {n_acc} tuples of distinct states 0..{s - 1}, "
                         f"got {columns!r}")
    return out


def sensor_lines(t: str, outputs, n: int, s: int, P: _Rows, feed: list[tuple[str, str]],
                 force: str | None = None, columns=None) -> list[str]:
    """Code writing each sensor's reading at the sample into ``Y[yo + o * width + b]``.

    A position or velocity sensor copies a state (``x{order * n + k}``, compile-time
    index); the ``a``-th acceleration sensor is ``fma``-summed from its rows ``oc`` (the
    state-matrix row, ``s`` entries), the feedthrough products ``feed`` (``(row, input)``
    pairs, e.g. ``("od", "uk")``), and with ``force`` its cart's nonlinear force
    ``{force}{k}`` times row ``oe`` (``1 / m_k``).  ``columns``: the states each
    acceleration row can involve (the rig's springs and dampers at that cart, compiled
    in), default all ``s``; ``oc`` then holds those entries only.
    """
    lines, a, at_c = [], 0, 0
    for o, (k, order) in enumerate(outputs):
        at = f"Y[yo + {o * P.width} + b]"
        if order < 2:
            lines.append(f"{t}{at} = x{order * n + k}")
            continue
        (row, inp), *more = feed
        cols = range(s) if columns is None else columns[a]
        prods = [(P(r, a), i) for r, i in more] + [(P("oc", at_c + c), f"x{j}")
                                                   for c, j in enumerate(cols)]
        at_c += len(cols)
        if force is not None:
            prods.append((P("oe", a), f"{force}{k}"))
        lines.append(f"{t}{at} = {_fma_sum(f'{P(row, a)} * {inp}', prods)}")
        a += 1
    return lines


def acceleration_rows(outputs, C, D, E=None, columns=None) -> list[np.ndarray]:
    """The parameter rows of ``sensor_lines`` from an output map (``C`` (nb, n_out, s),
    ``D`` (nb, n_out) or a list of such, ``E`` (nb, n_out, n)): the acceleration sensors'
    rows ``oc`` (their ``columns`` only, if given), then each of ``D``, then ``oe`` (each
    cart's own ``E`` entry)."""
    acc = [o for o, (_, order) in enumerate(outputs) if order == 2]
    if not acc:
        return []
    nb = C.shape[0]
    if columns is None:
        rows = [C[:, acc].reshape(nb, -1)]
    else:
        rows = [np.concatenate([C[:, o, list(c)] for o, c in zip(acc, columns, strict=True)],
                               axis=1)]
    rows += [d[:, acc] for d in (D if isinstance(D, (list, tuple)) else [D])]
    if E is not None:
        rows.append(np.stack([E[:, o, outputs[o][0]] for o in acc], axis=-1).reshape(nb, -1))
    return rows


def with_sensors(kernel, params: list, outputs, out_map, columns, n: int):
    """A runner's kernel, parameter rows and output count for ``outputs``: the position
    kernel and ``n`` rows without sensors; with them, the sensor map checked, the
    acceleration rows (``acceleration_rows`` of ``out_map``) appended to ``params`` and
    the kernel told its sensors."""
    if outputs is None:
        return kernel, params, n
    outputs = checked_outputs(outputs, n)
    params = params + acceleration_rows(outputs, *out_map, columns=columns)
    return functools.partial(kernel, outputs=outputs, columns=columns), params, len(outputs)
