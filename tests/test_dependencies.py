"""Every third-party package the code imports is declared in ``pyproject.toml``.

The package's source is walked with :mod:`ast`; every import, at module level or inside a
function, and every optional reader loaded through ``_channels.require("module", "extra")``
is mapped to the distribution that installs it.  An import that runs whenever its module
runs must be a core dependency; an import inside ``try: ... except ImportError`` is an
optional path, and its error message must name the extra (``pip install
'bayesmodal[extra]'``) that lists the distribution.
"""

from __future__ import annotations

import ast
import functools
import importlib.metadata
import re
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "bayesmodal"

# Declared core dependencies that no module imports by name, with the reason they are needed.
RUNTIME_ONLY = {
    # ArviZ writes and reads posterior.nc through it (InferenceData.to_netcdf/from_netcdf)
    "netcdf4": "engine of arviz's to_netcdf / from_netcdf",
}

_IMPORT_ERRORS = {"ImportError", "ModuleNotFoundError"}
_EXTRA = re.compile(r"bayesmodal\[([A-Za-z0-9_-]+)\]")


def normalize(name: str) -> str:
    """PEP 503 name of a distribution: ``npTDMS`` -> ``nptdms``, ``tomli_w`` -> ``tomli-w``."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement_name(spec: str) -> str:
    return normalize(re.match(r"\s*([A-Za-z0-9._-]+)", spec).group(1))


def declared(pyproject: Path = ROOT / "pyproject.toml") -> tuple[set[str], dict[str, set[str]]]:
    """Core dependencies and extras of a ``pyproject.toml``, as normalized names."""
    project = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
    core = {_requirement_name(s) for s in project.get("dependencies", [])}
    extras = {k: {_requirement_name(s) for s in v}
              for k, v in project.get("optional-dependencies", {}).items()}
    return core, extras


@dataclass(frozen=True)
class Use:
    """One import of a third-party module: where, and the extra its guard names (if any)."""

    module: str          # top-level import name, e.g. "PIL"
    where: str           # "path:line"
    guarded: bool        # inside try/except ImportError, or loaded through require()
    extras: tuple[str, ...]  # extras named by the guard's error message


def _catches_import_error(handler: ast.ExceptHandler) -> bool:
    t = handler.type
    names = t.elts if isinstance(t, ast.Tuple) else [t]
    return any(isinstance(n, ast.Name) and n.id in _IMPORT_ERRORS for n in names)


def _extras_named(nodes) -> tuple[str, ...]:
    found = []
    for node in nodes:
        for sub in ast.walk(node):
            if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                found += _EXTRA.findall(sub.value)
    return tuple(found)


def third_party_uses(source: str, where: str) -> list[Use]:
    """The third-party imports of one module's source (stdlib and bayesmodal left out)."""
    uses: list[Use] = []

    def add(name: str, line: int, guard: tuple[str, ...] | None):
        top = name.split(".")[0]
        if top in sys.stdlib_module_names or top == "bayesmodal" or top == "__future__":
            return
        uses.append(Use(top, f"{where}:{line}", guard is not None, guard or ()))

    def visit(node, guard):
        if isinstance(node, ast.Try):
            handlers = [h for h in node.handlers if _catches_import_error(h)]
            inner = _extras_named(handlers) if handlers else None
            for child in node.body:
                visit(child, inner if handlers else guard)
            for child in [*node.handlers, *node.orelse, *node.finalbody]:
                visit(child, guard)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name, node.lineno, guard)
        elif isinstance(node, ast.ImportFrom) and not node.level:
            add(node.module, node.lineno, guard)
        elif (isinstance(node, ast.Call) and len(node.args) >= 2
              and getattr(node.func, "id", getattr(node.func, "attr", None)) == "require"
              and all(isinstance(a, ast.Constant) and isinstance(a.value, str)
                      for a in node.args[:2])):
            # _channels.require("nptdms", "tdms", path): an optional reader and its extra
            add(node.args[0].value, node.lineno, (node.args[1].value,))
        for child in ast.iter_child_nodes(node):
            visit(child, guard)

    visit(ast.parse(source), None)
    return uses


@functools.cache
def _installed() -> dict[str, list[str]]:
    return importlib.metadata.packages_distributions()


def distributions(module: str) -> set[str]:
    """Distributions that provide an import name (the name itself if none is installed)."""
    found = _installed().get(module)
    return {normalize(d) for d in found} if found else {normalize(module)}


def undeclared(uses, core: set[str], extras: dict[str, set[str]]) -> list[str]:
    """One line per import that ``pyproject.toml`` does not cover, naming the fix."""
    problems = []
    for u in uses:
        dists = distributions(u.module)
        if dists & core:
            continue
        if not u.guarded:
            problems.append(f"{u.where}: {u.module} ({', '.join(sorted(dists))}) is imported "
                            "unconditionally but is not in [project] dependencies; declare it "
                            "there, or guard the import with try/except ImportError naming "
                            "the extra that installs it")
            continue
        holders = sorted(k for k, v in extras.items() if dists & v)
        if not holders:
            problems.append(f"{u.where}: {u.module} ({', '.join(sorted(dists))}) is in no "
                            "extra of [project.optional-dependencies]; add it to one")
        elif not set(u.extras) & set(holders):
            problems.append(f"{u.where}: the ImportError for {u.module} names "
                            f"{list(u.extras) or 'no extra'}; name "
                            f"pip install 'bayesmodal[{holders[0]}]'")
    return problems


@functools.cache
def package_uses() -> tuple[Use, ...]:
    uses = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        uses += third_party_uses(path.read_text(encoding="utf-8"), rel)
    return tuple(uses)


def test_every_import_is_declared():
    core, extras = declared()
    assert undeclared(package_uses(), core, extras) == []


def test_every_core_dependency_is_used():
    core, _ = declared()
    imported = set().union(*(distributions(u.module) for u in package_uses()))
    unused = sorted(core - imported - set(RUNTIME_ONLY))
    assert unused == [], f"core dependencies no module imports: {unused}"


def test_the_walk_sees_the_known_imports():
    # the walk must find imports in function bodies and through require(), or the test above
    # could pass on an empty list
    uses = {(u.module, u.guarded) for u in package_uses()}
    assert ("xarray", False) in uses          # inside functions of inference/idata.py
    assert ("distributed", True) in uses      # guarded in inference/crossval.py
    assert ("nptdms", True) in uses           # through _channels.require


FAKE = '''
import numpy as np
from scipy import linalg

def f():
    import notdeclared_xyz

def g():
    try:
        import dynesty
    except ImportError as exc:
        raise ImportError("needs dynesty: pip install 'bayesmodal[evidence]'") from exc

def h():
    try:
        from distributed import Client
    except ImportError:
        raise ImportError("needs distributed: pip install 'bayesmodal[uff]'")

def k(path):
    return require("pyuff", "uff", path), require("othermod_xyz", "uff", path)
'''


def test_checker_flags_undeclared_and_wrongly_guarded_imports():
    # negative control: a source with an undeclared import, a guard naming the wrong extra
    # and an optional reader that no extra installs; numpy, scipy, the dynesty guard and
    # pyuff are declared correctly and must pass
    core, extras = declared()
    problems = undeclared(third_party_uses(FAKE, "fake.py"), core, extras)
    assert len(problems) == 3, problems
    assert "fake.py:6: notdeclared_xyz" in problems[0]
    assert "not in [project] dependencies" in problems[0]
    assert "fake.py:16" in problems[1] and "bayesmodal[dask]" in problems[1]
    assert "fake.py:21: othermod_xyz" in problems[2] and "in no extra" in problems[2]


def test_checker_reads_the_declarations(tmp_path):
    pyproject = tmp_path / "pyproject.toml"
    pyproject.write_text('[project]\nname = "x"\ndependencies = ["Tomli_W>=1", "numpy"]\n'
                         '[project.optional-dependencies]\nd = ["dask[distributed]>=2023"]\n')
    assert declared(pyproject) == ({"tomli-w", "numpy"}, {"d": {"dask"}})


def test_missing_dynesty_names_the_extra(monkeypatch):
    # a None entry in sys.modules makes `import dynesty` raise ImportError, as if absent
    from bayesmodal import ConfigError
    from bayesmodal.inference.evidence import nested_evidence
    from bayesmodal.inference.priors import PriorSet, Uniform

    monkeypatch.setitem(sys.modules, "dynesty", None)
    priors = PriorSet(("x",), (Uniform(-1.0, 1.0),), ("identity",))
    with pytest.raises(ConfigError, match=r"pip install 'bayesmodal\[evidence\]'"):
        nested_evidence(lambda th: -0.5 * th[:, 0] ** 2, priors, nlive=10, rng=1)
