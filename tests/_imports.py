"""The package's import graph, read from the source with :mod:`ast` (nothing is imported).

A node is a module's dotted name (``bayesmodal.inference.likelihood``; a package is its
``__init__``).  An edge ``a -> b`` is an import statement in ``a`` that loads ``b``:

- ``import bayesmodal.x.y`` and ``from bayesmodal.x import y`` load ``bayesmodal.x.y`` when
  that is a module, else ``bayesmodal.x``;
- relative imports are resolved against the importing module's package
  (``from ..inference import likelihood`` in ``bayesmodal.runs.runner``);
- the parent packages Python runs first (``bayesmodal.x`` before ``bayesmodal.x.y``) are not
  edges: they would put every module of a package with an eager ``__init__`` on a cycle
  with it, which says nothing about how the modules depend on one another.

Each edge records whether it is *deferred* (the statement sits in a function or method
body, so it runs on the first call rather than at import) and whether it sits under
``if TYPE_CHECKING:`` (never run; left out of the graph).
"""

from __future__ import annotations

import ast
import functools
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "bayesmodal"


@dataclass(frozen=True)
class Edge:
    """One import of a package module by another."""

    source: str      # importing module, dotted
    target: str      # imported module, dotted
    line: int        # line of the import statement in the source module
    deferred: bool   # inside a function body


def module_files(root: Path = ROOT / PACKAGE, package: str = PACKAGE) -> dict[str, Path]:
    """Dotted module name -> source file, for every ``.py`` file under ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join([package, *parts])] = path
    return out


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """Absolute dotted name of the module part of ``from ... import``."""
    if not node.level:
        return node.module
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def edges_of(module: str, source: str, modules, *, is_package: bool = False) -> list[Edge]:
    """Imports of package modules by one module's source.

    Parameters
    ----------
    module : str
        Dotted name of the module the source belongs to.
    source : str
        Its Python source.
    modules : collection of str
        Dotted names of all the package's modules, to tell a submodule from a name.
    is_package : bool
        True when the source is a package's ``__init__.py``.
    """
    top = module.split(".")[0]
    found: list[Edge] = []

    def target(name: str) -> str | None:
        # the longest prefix of ``name`` that is a module of the package
        parts = name.split(".")
        for k in range(len(parts), 0, -1):
            cand = ".".join(parts[:k])
            if cand in modules:
                return cand
        return None

    def add(name: str, line: int, deferred: bool):
        if name.split(".")[0] != top:
            return
        t = target(name)
        if t is not None and t != module:
            found.append(Edge(module, t, line, deferred))

    def visit(node, deferred: bool):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child, deferred)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name, node.lineno, deferred)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, is_package, node)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                # ``from pkg import sub`` loads the submodule; ``from mod import name`` the module
                add(full if full in modules else base, node.lineno, deferred)
        inner = deferred or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef,
                                              ast.Lambda))
        for child in ast.iter_child_nodes(node):
            visit(child, inner)

    visit(ast.parse(source), False)
    return found


@functools.cache
def package_edges() -> tuple[Edge, ...]:
    """Every import of a package module by another, over the whole package."""
    files = module_files()
    edges = []
    for name, path in files.items():
        edges += edges_of(name, path.read_text(encoding="utf-8"), files,
                          is_package=path.name == "__init__.py")
    # one edge per (source, target, line, deferred): ``from x import a, b`` is one import
    return tuple(dict.fromkeys(edges))


def graph(edges, *, deferred: bool = True) -> dict[str, set[str]]:
    """Adjacency sets; ``deferred=False`` keeps only the imports that run at import time."""
    adj: dict[str, set[str]] = defaultdict(set)
    for e in edges:
        if deferred or not e.deferred:
            adj[e.source].add(e.target)
    return dict(adj)


def cycles(adj: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module, each sorted, largest first.

    Every import cycle lies inside one of them, and a graph has no cycle exactly when this
    list is empty (no module imports itself: ``edges_of`` drops such edges).
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    nodes = sorted(set(adj) | {t for ts in adj.values() for t in ts})

    def strongconnect(v: str):
        # Tarjan's algorithm, iterative so a deep graph cannot hit the recursion limit
        work = [(v, iter(sorted(adj.get(v, ()))))]
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        while work:
            node, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(adj.get(w, ())))))
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))

    for v in nodes:
        if v not in index:
            strongconnect(v)
    return sorted(out, key=lambda c: (-len(c), c))


def reachable(adj: dict[str, set[str]], start: str) -> set[str]:
    """Modules ``start`` loads directly or through other modules (itself excluded)."""
    seen: set[str] = set()
    todo = list(adj.get(start, ()))
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo += adj.get(m, ())
    seen.discard(start)
    return seen


def in_layer(module: str, prefixes) -> bool:
    """True when ``module`` is one of ``prefixes`` or inside one of them (dotted)."""
    return any(module == p or module.startswith(p + ".") for p in prefixes)
