"""The package's import graph (``tests/_imports.py``, built from the source with ``ast``).

What it holds today, and what may not get worse:

- no cycle among the imports that run at import time (module level);
- counting the imports deferred into function bodies, the cycles are the ones listed in
  ``KNOWN_CYCLES`` (none today; docs/architecture.md lists them); a new cycle, or a known
  one that takes in another module, fails;
- the number of deferred imports of the package's own modules does not grow;
- the model layer (``bayesmodal.model``: the rig, the linear model, the simulator, the
  effects and their compiled kernels) loads nothing from the layers above it (data,
  fitting, inference, diagnosis, runs, plots, the command line, the run configuration,
  EMA, modal analysis), directly or through other modules, counting deferred imports.
"""

from __future__ import annotations

import re
from pathlib import Path

import _imports as ig

ROOT = Path(__file__).resolve().parents[1]

# Import statements of the package's own modules inside function bodies.  With no cycle
# left none is needed: the package's own modules load nothing optional at import time, and
# importing them all costs the command line 0.2 s of its 1.4 s start (``bayesmodal
# --help``).  A deferred import would need such a reason, written beside it here.
MAX_DEFERRED_OWN_IMPORTS = 0

# Strongly connected components of the graph with deferred imports, i.e. the modules that
# import one another through some chain.  With module-level imports alone there are none.
KNOWN_CYCLES: tuple = ()

MODEL_LAYER = ("bayesmodal.model",)
ABOVE_MODEL = ("bayesmodal.data", "bayesmodal.fit", "bayesmodal.inference",
               "bayesmodal.discrepancy", "bayesmodal.runs", "bayesmodal.plots",
               "bayesmodal.cli", "bayesmodal.runs.config", "bayesmodal.ema", "bayesmodal.modal")


def deferred_statements(edges) -> set[tuple[str, int]]:
    """(module, line) of each deferred import statement of a package module."""
    return {(e.source, e.line) for e in edges if e.deferred}


def new_cycles(found, known=KNOWN_CYCLES) -> list[list[str]]:
    """Components of ``found`` that lie inside no known component."""
    return [c for c in found if not any(set(c) <= set(k) for k in known)]


def layer_violations(adj, lower, upper) -> list[str]:
    """``"a loads b"`` for each module ``b`` of ``upper`` reachable from a module of
    ``lower`` (through any chain, including modules of ``lower`` themselves)."""
    out = []
    for m in sorted(adj.keys() | {t for ts in adj.values() for t in ts}):
        if ig.in_layer(m, lower):
            out += [f"{m} loads {t}" for t in sorted(ig.reachable(adj, m))
                    if ig.in_layer(t, upper)]
    return out


def format_cycle(component) -> str:
    """One line of docs/architecture.md's cycle list."""
    return " <-> ".join(m.removeprefix("bayesmodal.") for m in component)


def test_no_cycle_at_import_time():
    assert ig.cycles(ig.graph(ig.package_edges(), deferred=False)) == []


def test_no_new_cycle_through_deferred_imports():
    found = ig.cycles(ig.graph(ig.package_edges()))
    assert new_cycles(found) == []


def test_deferred_own_imports_do_not_grow():
    n = len(deferred_statements(ig.package_edges()))
    assert n <= MAX_DEFERRED_OWN_IMPORTS, (
        f"{n} deferred imports of bayesmodal modules (at most {MAX_DEFERRED_OWN_IMPORTS}): "
        "import at module level, or move the code so the import points down the layers")


def test_model_layer_loads_nothing_above_it():
    assert layer_violations(ig.graph(ig.package_edges()), MODEL_LAYER, ABOVE_MODEL) == []


def test_architecture_page_lists_the_cycles():
    page = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    for component in ig.cycles(ig.graph(ig.package_edges())):
        assert format_cycle(component) in page
    n = len(deferred_statements(ig.package_edges()))
    assert (f"{n} deferred" in page) or (n == 0 and "no deferred import" in page)


# -- the graph builder on small sources, with known answers ---------------------------

def _write(root: Path, files: dict[str, str]) -> dict[str, Path]:
    for rel, text in files.items():
        p = root / "pkg" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")
    return ig.module_files(root / "pkg", "pkg")


def _edges(files: dict[str, Path]) -> list[ig.Edge]:
    out = []
    for name, path in files.items():
        out += ig.edges_of(name, path.read_text(encoding="utf-8"), files,
                           is_package=path.name == "__init__.py")
    return out


def test_builder_resolves_relative_and_deferred_imports(tmp_path):
    files = _write(tmp_path, {
        "__init__.py": "from .low import f\n",
        "low.py": "import numpy\n\ndef f():\n    from .sub import high\n    return high\n",
        "sub/__init__.py": "",
        "sub/high.py": "from ..low import f\nfrom . import other\nimport pkg.sub.other\n",
        "sub/other.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                         "    from pkg.low import f\nfrom .. import low as _low\n"),
    })
    edges = {(e.source, e.target, e.deferred) for e in _edges(files)}
    assert edges == {
        ("pkg", "pkg.low", False),
        ("pkg.low", "pkg.sub.high", True),          # deferred, relative, submodule by name
        ("pkg.sub.high", "pkg.low", False),         # two levels up
        ("pkg.sub.high", "pkg.sub.other", False),   # `from . import other`, `import a.b.c`
        ("pkg.sub.other", "pkg.low", False),        # `from .. import low`; TYPE_CHECKING left out
    }
    adj = ig.graph(_edges(files))
    # negative control: the deferred import closes a cycle the module-level graph lacks
    ring = ["pkg.low", "pkg.sub.high", "pkg.sub.other"]
    assert ig.cycles(adj) == [ring]
    assert ig.cycles(ig.graph(_edges(files), deferred=False)) == []
    assert new_cycles(ig.cycles(adj), known=()) == [ring]
    # a known cycle that takes in one more module is a new one
    assert new_cycles(ig.cycles(adj), known=(("pkg.low", "pkg.sub.high"),)) == [ring]
    assert new_cycles(ig.cycles(adj), known=((*ring, "pkg.x"),)) == []
    assert deferred_statements(_edges(files)) == {("pkg.low", 4)}
    assert layer_violations(adj, ("pkg.low",), ("pkg.sub",)) == [
        "pkg.low loads pkg.sub.high", "pkg.low loads pkg.sub.other"]
    assert layer_violations(adj, ("pkg.sub.other",), ("pkg.sub.high",)) == [
        "pkg.sub.other loads pkg.sub.high"]   # through pkg.low's deferred import


def test_builder_sees_the_package():
    # the graph has edges the source plainly shows, or the tests above could pass on nothing
    edges = {(e.source, e.target, e.deferred) for e in ig.package_edges()}
    assert ("bayesmodal.model.simulate", "bayesmodal.model._kernels", False) in edges
    assert any(s.startswith("bayesmodal.cli.") and t.startswith("bayesmodal.runs")
               for s, t, _ in edges)
    assert len(ig.module_files()) > 100


def test_cycle_list_format_matches_the_page():
    # the lines the page test looks for are written as the page writes them
    assert format_cycle(("bayesmodal.fit", "bayesmodal.identified")) == "fit <-> identified"
    assert re.fullmatch(r"[\w.]+( <-> [\w.]+)+",
                        format_cycle(("bayesmodal._tdms", "bayesmodal._uff")))


def test_the_run_configuration_is_read_above_inference_only():
    # the TOML layer sits in runs/: the runs, the command line and the package root's
    # public API import it, nothing below them
    importers = {e.source for e in ig.package_edges() if e.target == "bayesmodal.runs.config"}
    assert importers, "the graph sees no import of the configuration"
    below = sorted(s for s in importers
                   if not s.startswith(("bayesmodal.runs", "bayesmodal.cli"))
                   and s != "bayesmodal")
    assert below == [], below
