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


#: The layers, lowest first (docs/architecture.md): a module imports only its own layer and
#: the ones before it.  ``base`` holds what every layer may use (errors, formatting).
LAYERS = ("base", "model", "data", "fit", "inference", "diagnosis", "plots", "runs", "cli")
#: The layer of each sub-package, and of each module at the package's root.
PACKAGE_LAYER = {"model": "model", "fit": "fit", "modal": "fit", "ema": "fit",
                 "inference": "inference", "discrepancy": "diagnosis", "plots": "plots",
                 "runs": "runs", "cli": "cli"}
ROOT_LAYER = {
    "_blas": "base", "_errors": "base", "_format": "base", "_progress": "base", "_version": "base",
    "_versions": "base", "_json": "base",
    "_channels": "data", "_ecp_export": "data", "_instruments": "data", "_readers": "data",
    "_release": "data", "_tdms": "data", "_uff": "data", "_window": "data", "data": "data",
    "reading": "data", "segments": "data", "inspection": "data", "structure": "data",
    "_columns": "data", "timebase": "data",
    "identified": "fit", "metrics": "fit", "static": "fit",
    "reproduce": "runs", "bench": "runs", "bench_sampler": "runs", "bench_stamps": "runs",
    "__main__": "cli"}


def layer_of(module: str) -> str | None:
    """The layer of a package module; None for the package's ``__init__`` (the public API,
    which may name anything) and for a module missing from the tables."""
    parts = module.split(".")
    if len(parts) == 1:
        return None
    return PACKAGE_LAYER.get(parts[1]) or ROOT_LAYER.get(parts[1])


def upward_imports(edges) -> list[str]:
    """``"a -> b"`` for each import of a module of a later layer."""
    out = []
    for s, t in sorted({(e.source, e.target) for e in edges}):
        a, b = layer_of(s), layer_of(t)
        if a is not None and b is not None and LAYERS.index(b) > LAYERS.index(a):
            out.append(f"{s} ({a}) -> {t} ({b})")
    return out


def test_every_module_has_a_layer():
    missing = [m for m in ig.module_files() if m != "bayesmodal" and layer_of(m) is None]
    assert not missing, f"add these modules to ROOT_LAYER or PACKAGE_LAYER: {missing}"


def test_layers_point_one_way():
    """model -> data -> fit -> inference -> diagnosis -> plots -> runs -> cli, counting
    imports inside functions."""
    assert upward_imports(ig.package_edges()) == []


def test_upward_import_check_catches_one():
    """Negative control: an import of the run layer from the inference layer is found."""
    edge = ig.Edge("bayesmodal.inference.sampling", "bayesmodal.runs.folder", 1, True)
    assert upward_imports([edge]) == [
        "bayesmodal.inference.sampling (inference) -> bayesmodal.runs.folder (runs)"]


def test_matplotlib_is_drawn_with_in_plots_only():
    """Inference, diagnosis and the layers below neither draw nor load matplotlib."""
    below = [m for m in ig.module_files() if layer_of(m) in
             ("model", "data", "fit", "inference", "diagnosis")]
    files = ig.module_files()
    found = [m for m in below if re.search(r"^\s*(import|from) matplotlib",
                                           files[m].read_text(encoding="utf-8"), re.M)]
    assert found == []


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
