"""Sizes that keep a module readable: at most 600 lines a module, 150 a function.

No module and no function is over its limit; the lists below held those that were, and
stay empty: a module or function that grows past the limit is split by concept (one
idea per module, docs/conventions.md), not listed.  The public entry points
``sample_posterior`` and ``diagnose`` take at most eight parameters (their settings are
one object each).
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 150

#: Modules over the limit today, with their line counts (may only fall).
LARGE_MODULES: dict[str, int] = {}
#: Functions over the limit today (``path:name``), with their line counts.
LARGE_FUNCTIONS: dict[str, int] = {}


def sizes(root: Path = ROOT / "bayesmodal"):
    """(module line counts, function line counts) over the package's source."""
    mods, funcs = {}, {}
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root.parent).as_posix()
        src = p.read_text(encoding="utf-8")
        mods[rel] = len(src.splitlines())
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                key = f"{rel}:{node.name}"
                funcs[key] = max(funcs.get(key, 0), node.end_lineno - node.lineno + 1)
    return mods, funcs


def over(measured: dict, limit: int, known: dict) -> list[str]:
    """What is over ``limit`` and either not in ``known`` or larger than listed there."""
    return [f"{k}: {n} lines (limit {limit}, listed {known.get(k)})"
            for k, n in sorted(measured.items()) if n > limit and n > known.get(k, limit)]


def test_no_module_grows_past_the_limit():
    mods, _ = sizes()
    assert over(mods, MAX_MODULE_LINES, LARGE_MODULES) == []


def test_no_function_grows_past_the_limit():
    _, funcs = sizes()
    assert over(funcs, MAX_FUNCTION_LINES, LARGE_FUNCTIONS) == []


def test_the_lists_hold_only_what_is_still_large():
    """A module or function that fell under the limit leaves the list."""
    mods, funcs = sizes()
    assert [k for k in LARGE_MODULES if mods.get(k, 0) <= MAX_MODULE_LINES] == []
    assert [k for k in LARGE_FUNCTIONS if funcs.get(k, 0) <= MAX_FUNCTION_LINES] == []


def test_the_check_catches_a_new_large_module():
    """Negative control."""
    assert over({"a.py": 601, "b.py": 600}, 600, {}) == ["a.py: 601 lines (limit 600, "
                                                        "listed None)"]
    assert over({"a.py": 700}, 600, {"a.py": 699}) != []


def test_the_entry_points_take_at_most_eight_parameters():
    from bayesmodal.discrepancy.diagnosis import diagnose
    from bayesmodal.inference import sample_posterior

    for f in (sample_posterior, diagnose):
        params = [p for p in inspect.signature(f).parameters.values()
                  if p.kind is not inspect.Parameter.VAR_KEYWORD]
        assert len(params) <= 8, f.__name__
