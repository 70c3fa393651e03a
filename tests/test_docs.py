"""Docs that run: every ``python``, ``bash``, ``sh`` and ``console`` snippet of README.md,
runs/README.md, docs/*.md and docs/validation/*.md is executed as written.

A snippet runs in a subprocess (Python with ``PYTHONPATH`` at the repository root; shell
with ``bash -e``, with ``bayesmodal`` and ``python`` on ``PATH`` meaning this package and
this interpreter) in a fresh temporary folder.  An HTML comment on the line before the
fence changes that, e.g.::

    <!-- doctest: cwd=repo slow -->

Markers (space-separated; quote values with spaces):

``cwd=repo``
    Run in a scratch copy of the repository root (``docs/``, ``runs/*.toml``, ``scripts/``,
    ``benchmarks/``, ``data/``, ``README.md``, ``pyproject.toml`` copied; ``bayesmodal/``
    and ``tests/`` linked) with ``../shared/data`` beside it pointing at the measured data,
    so paths written relative to the repository root work and nothing is written into the
    checkout.  Without the marker a block runs in an empty temporary folder.
``slow``
    Marked ``@pytest.mark.slow`` (run by ``pytest -m slow``, which CI runs too).
``data``
    Needs the measured data (``../shared/data`` or ``$BAYESMODAL_DATA``): skipped with the
    reason when absent.  Snippets that mention ``find_data(`` or ``shared/data`` need it
    without the marker.
``skip="reason"``
    Not run, for the reason given (e.g. it installs packages).  Nothing else is skipped:
    an unmarked snippet that fails fails this test.
``timeout=S``
    Seconds before the snippet is killed (default 600, slow 1800).

Fences in other languages (``text``, none) are shown output or synopses and not run.
"""

from __future__ import annotations

import ast
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from bayesmodal.data import data_root

REPO = Path(__file__).resolve().parents[1]
RUN_LANGS = {"python", "bash", "sh", "console"}
MARKER_KEYS = {"cwd", "slow", "data", "skip", "timeout"}
_FENCE = re.compile(r"^(\s*)```+\s*([\w+-]*)")
_MARKER = re.compile(r"^\s*<!--\s*doctest:(.*?)-->\s*$")


@dataclass(frozen=True)
class Snippet:
    """One fenced code block of a page."""

    path: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    marker: dict = field(default_factory=dict)

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(REPO).as_posix()}:{self.line}"

    @property
    def needs_data(self) -> bool:
        return "data" in self.marker or "find_data(" in self.code or "shared/data" in self.code


def parse_marker(text: str) -> dict:
    """``'cwd=repo slow skip="why"'`` -> ``{"cwd": "repo", "slow": True, "skip": "why"}``."""
    out: dict = {}
    for tok in shlex.split(text):
        key, eq, val = tok.partition("=")
        out[key] = val if eq else True
    return out


def doc_pages() -> list[Path]:
    return [REPO / "README.md", REPO / "runs" / "README.md",
            *sorted((REPO / "docs").glob("*.md")),
            *sorted((REPO / "docs" / "validation").glob("*.md"))]


def snippets(path: Path) -> list[Snippet]:
    """Every fenced block of a Markdown page, with the doctest marker just above it."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, lang = m.group(1), m.group(2).lower()
        start, body = i, []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith("```"):
            body.append(lines[i][len(indent):] if lines[i].startswith(indent) else lines[i])
            i += 1
        i += 1
        j = start - 1
        while j >= 0 and not lines[j].strip():
            j -= 1
        mk = _MARKER.match(lines[j]) if j >= 0 else None
        out.append(Snippet(path, start + 1, lang, "\n".join(body) + "\n",
                           parse_marker(mk.group(1)) if mk else {}))
    return out


def runnable() -> list[Snippet]:
    return [s for p in doc_pages() for s in snippets(p) if s.lang in RUN_LANGS]


def _param(s: Snippet):
    marks = [pytest.mark.slow] if s.marker.get("slow") else []
    return pytest.param(s, id=s.id, marks=marks)


def _shims(tmp: Path) -> Path:
    """``bayesmodal`` and ``python`` commands that run this checkout with this interpreter
    (the docs assume the package is installed)."""
    bin_dir = tmp / "_bin"
    bin_dir.mkdir()
    for name, target in (("bayesmodal", f'"{sys.executable}" -m bayesmodal'),
                         ("python", f'"{sys.executable}"'), ("python3", f'"{sys.executable}"')):
        f = bin_dir / name
        f.write_text(f'#!/usr/bin/env bash\nexec {target} "$@"\n', encoding="utf-8")
        f.chmod(0o755)
    return bin_dir


def _repo_copy(tmp: Path) -> Path:
    """A scratch repository root with ``../shared/data`` beside it."""
    root = tmp / "repo"
    root.mkdir()
    ignore = shutil.ignore_patterns("_build", "__pycache__", "*.pyc")
    for name in ("docs", "scripts", "benchmarks", "data"):
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, root / name, ignore=ignore)
    for name in ("README.md", "pyproject.toml"):
        shutil.copy2(REPO / name, root / name)
    (root / "runs").mkdir()
    for f in (REPO / "runs").glob("*.toml"):
        shutil.copy2(f, root / "runs" / f.name)
    for name in ("bayesmodal", "tests"):
        (root / name).symlink_to(REPO / name)
    data = data_root()
    if data is not None:
        (tmp / "shared").mkdir()
        (tmp / "shared" / "data").symlink_to(data)
    return root


def _console_commands(code: str) -> str:
    """The ``$ `` lines of a console block (the rest is shown output)."""
    return "\n".join(ln[2:] for ln in code.splitlines() if ln.startswith("$ ")) + "\n"


@pytest.mark.parametrize("snippet", [_param(s) for s in runnable()])
def test_snippet_runs(snippet: Snippet, tmp_path):
    if "skip" in snippet.marker:
        pytest.skip(f"{snippet.id}: {snippet.marker['skip']}")
    if snippet.needs_data and data_root() is None:
        pytest.skip(f"{snippet.id}: needs the measured data (../shared/data beside the "
                    "repository or $BAYESMODAL_DATA), not found")
    cwd = _repo_copy(tmp_path) if snippet.marker.get("cwd") == "repo" else tmp_path / "work"
    cwd.mkdir(exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg",
           "PATH": f"{_shims(tmp_path)}{os.pathsep}{os.environ.get('PATH', '')}"}
    if snippet.lang == "python":
        script = tmp_path / "snippet.py"
        script.write_text(snippet.code, encoding="utf-8")
        cmd = [sys.executable, str(script)]
    else:
        code = _console_commands(snippet.code) if snippet.lang == "console" else snippet.code
        script = tmp_path / "snippet.sh"
        script.write_text(code, encoding="utf-8")
        cmd = ["bash", "-e", "-o", "pipefail", str(script)]
    timeout = float(snippet.marker.get("timeout", 1800 if snippet.marker.get("slow") else 600))
    try:
        res = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True,
                             timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{snippet.id}: still running after {timeout:.0f} s; mark it "
                    "slow/timeout=... or make it shorter")
    if res.returncode != 0:
        pytest.fail(f"{snippet.id} failed (exit {res.returncode}); mark it "
                    f"<!-- doctest: skip=\"reason\" --> only if it cannot run.\n"
                    f"--- stderr (tail) ---\n{res.stderr[-3000:]}\n"
                    f"--- stdout (tail) ---\n{res.stdout[-1500:]}")
    print(res.stdout[-2000:])  # shown with pytest -s / -rP: what the page quotes


def test_markers_are_well_formed():
    """Every marker sits on a runnable fence and uses known keys (a typo would silently
    change what runs)."""
    problems = []
    for page in doc_pages():
        lines = page.read_text(encoding="utf-8").splitlines()
        fences = {s.line: s for s in snippets(page)}
        for n, ln in enumerate(lines, 1):
            if not _MARKER.match(ln):
                continue
            nxt = next((k for k in range(n + 1, len(lines) + 1) if lines[k - 1].strip()), None)
            s = fences.get(nxt)
            where = f"{page.relative_to(REPO)}:{n}"
            if s is None:
                problems.append(f"{where}: marker not followed by a fence")
                continue
            if s.lang not in RUN_LANGS:
                problems.append(f"{where}: marker on a {s.lang or 'plain'} fence, which never runs")
            unknown = set(s.marker) - MARKER_KEYS
            if unknown:
                problems.append(f"{where}: unknown marker keys {sorted(unknown)}")
            if s.marker.get("cwd", "repo") != "repo":
                problems.append(f"{where}: cwd must be 'repo'")
            if s.marker.get("skip") is True or s.marker.get("skip") == "":
                problems.append(f"{where}: skip needs a reason, skip=\"...\"")
    assert not problems, "\n".join(problems)


def test_parser_finds_snippets_and_markers(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("text\n\n<!-- doctest: cwd=repo slow skip=\"it installs\" -->\n"
                    "```bash\necho hi\n```\n\n```text\nout\n```\n\n- item\n\n"
                    "  ```python\n  print(1)\n  ```\n", encoding="utf-8")
    got = snippets(page)
    assert [(s.line, s.lang, s.code) for s in got] == [
        (4, "bash", "echo hi\n"), (8, "text", "out\n"), (14, "python", "print(1)\n")]
    assert got[0].marker == {"cwd": "repo", "slow": True, "skip": "it installs"}
    assert got[1].marker == {} and got[2].marker == {}
    assert _console_commands("$ ls\nfile\n$ echo a\n") == "ls\necho a\n"


_LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)]*)?\)")


def _excluded_folders() -> list[str]:
    """``exclude_patterns`` of docs/conf.py (folders Sphinx never reads as pages)."""
    text = (REPO / "docs" / "conf.py").read_text(encoding="utf-8")
    m = re.search(r"^exclude_patterns\s*=\s*(\[.*?\])", text, re.M | re.S)
    return ast.literal_eval(m.group(1))


def test_docs_links_resolve():
    """Every relative Markdown link of docs/*.md names a file that exists, and a link to a
    page (.md) never points into a folder the site excludes: Sphinx fails on it
    (myst.xref_missing), which the slow site build found only after 18 minutes."""
    excluded = _excluded_folders()
    problems = []
    for page in sorted((REPO / "docs").glob("*.md")):
        for n, ln in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            for target in _LINK.findall(ln):
                if "://" in target or target.startswith("mailto:"):
                    continue
                where = f"{page.relative_to(REPO)}:{n}: {target}"
                path = (page.parent / target).resolve()
                if not path.exists():
                    problems.append(f"{where} does not exist")
                elif target.endswith(".md") and any(
                        Path(target).parts[0] == ex for ex in excluded):
                    problems.append(f"{where} is in an excluded folder; quote it as code")
    assert not problems, "\n".join(problems)


def test_docs_link_check_catches_excluded_page():
    """Negative control: the pattern finds a link into figures/ and its anchor is cut."""
    assert _LINK.findall("see [t](figures/t.md#x) and [u](u.md)") == ["figures/t.md", "u.md"]
    assert "figures" in _excluded_folders()


def _api_index_modules() -> list[str]:
    """Module names listed under the autosummary directive of docs/api/index.rst."""
    text = (REPO / "docs" / "api" / "index.rst").read_text(encoding="utf-8")
    return re.findall(r"^   (bayesmodal[\w.]*)\s*$", text, re.M)


def test_api_index_modules_import():
    """Every module the API reference lists imports: a module moved without its entry
    fails the slow site build (autosummary warning) only after an hour of CI."""
    import importlib
    names = _api_index_modules()
    assert "bayesmodal.inference" in names          # the pattern reads the list
    missing = []
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError as exc:
            missing.append(f"{name}: {exc}")
    assert not missing, "docs/api/index.rst lists modules that do not import:\n" + \
        "\n".join(missing)


@pytest.mark.slow
def test_site_builds_without_warnings(tmp_path):
    """The documentation site (docs/conf.py: numpydoc API reference and the Markdown
    pages) builds with warnings as errors, into a temporary folder."""
    pytest.importorskip("sphinx", reason="the docs extra (pip install -e .[docs]) is needed")
    pytest.importorskip("numpydoc", reason="the docs extra (pip install -e .[docs]) is needed")
    pytest.importorskip("myst_parser", reason="the docs extra (pip install -e .[docs]) is needed")
    src = tmp_path / "docs"
    shutil.copytree(REPO / "docs", src,
                    ignore=shutil.ignore_patterns("_build", "generated", "__pycache__"))
    # conf.py finds the package one level above the source folder
    (tmp_path / "bayesmodal").symlink_to(REPO / "bayesmodal")
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b",
                          "html", str(src), str(tmp_path / "html"),
                          "-d", str(tmp_path / "doctrees")],
                         env=env, capture_output=True, text=True, timeout=1800)
    assert res.returncode == 0, res.stderr[-5000:]
    assert (tmp_path / "html" / "api" / "index.html").is_file()
    api = (tmp_path / "html" / "api" / "generated" /
           "bayesmodal.inference.sampling.sample_posterior.html").read_text(encoding="utf-8")
    assert "SamplerSpec" in api and "Parameters" in api   # numpydoc rendered the docstring
