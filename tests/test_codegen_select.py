"""The generated kernels' conditional expressions as branch-free ``select`` calls
(bayesmodal.model.kernels._codegen.branch_free): the same values as Python's
``a if c else b``, and left alone where evaluating both operands is not safe."""

import ast

import numpy as np

from bayesmodal.model.kernels._codegen import _compile, branch_free

LINES = [
    "def kernel(x, flags, out, idx):",
    "    for b in range(x.shape[0]):",
    "        s = flags[b] != 0.0",
    "        xb = x[b]",
    "        a = 1.0 if s else 0.0",                       # float constants
    "        k = 1 if s else 0",                           # int constants
    "        m = k if xb > 0.0 else 2.5",                  # int and float: float
    "        d = math.copysign(1.0, xb) if s else -xb * 3.0",
    "        h = s if xb < 1.0 else (xb > 2.0)",         # booleans
    "        j = idx[b]",
    "        g = x[j] if j >= 0 else 0.0",                 # a subscript: kept as a branch
    "        out[b, 0] = a",
    "        out[b, 1] = k",
    "        out[b, 2] = m",
    "        out[b, 3] = d",
    "        out[b, 4] = 1.0 if h else 0.0",
    "        out[b, 5] = g",
]


def _python(x, flags, idx):
    """The same function run by the interpreter, branches and all."""
    out = np.empty((x.size, 6))
    ns = {"math": __import__("math")}
    exec("\n".join(LINES), ns)  # noqa: S102
    ns["kernel"](x, flags, out, idx)
    return out


def test_selects_give_the_conditional_expressions_values():
    rng = np.random.default_rng(7)
    x = np.r_[rng.normal(0.0, 2.0, 200), 0.0, -0.0, np.inf, -np.inf]
    flags = (rng.random(x.size) < 0.5).astype(float)
    idx = np.where(rng.random(x.size) < 0.5, rng.integers(0, x.size, x.size), -(10**9))
    kernel = _compile(LINES, "<test select>")
    out = np.empty((x.size, 6))
    kernel(x, flags, out, idx)
    # exact: a select returns one of its operands, each computed as in the branch
    np.testing.assert_array_equal(out, _python(x, flags, idx))


def test_only_safe_operands_become_selects():
    src = branch_free("\n".join(LINES) + "\n")
    calls = [n for n in ast.walk(ast.parse(src))
             if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "select"]
    kept = [n for n in ast.walk(ast.parse(src)) if isinstance(n, ast.IfExp)]
    assert len(calls) == 6
    # negative control: the subscript whose index is valid only when its branch is taken
    assert len(kept) == 1 and isinstance(kept[0].body, ast.Subscript)
