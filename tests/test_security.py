"""Security: nothing is unpickled or evaluated, configurations are data only, output paths
stay inside the output root, and reports escape every string they embed."""

from __future__ import annotations

import ast
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from bayesmodal import ConfigError
from bayesmodal.cli import main
from bayesmodal.data import Experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs import default_out_dir, render_report
from bayesmodal.runs.config import load_config, parse_config

REPO = Path(__file__).resolve().parents[1]
SOURCES = sorted([*(REPO / "bayesmodal").rglob("*.py"), *(REPO / "scripts").rglob("*.py"),
                  *(REPO / "benchmarks").rglob("*.py"), *(REPO / "docs").rglob("*.py")])

#: Calls that deserialise or run arbitrary code.
FORBIDDEN_CALLS = {"eval", "pickle.load", "pickle.loads", "cPickle.load", "dill.load",
                   "dill.loads", "joblib.load", "marshal.load", "marshal.loads",
                   "shelve.open", "yaml.load", "yaml.unsafe_load", "torch.load",
                   "pandas.read_pickle", "pd.read_pickle", "np.lib.format.read_array",
                   "__import__"}
FORBIDDEN_MODULES = {"pickle", "cPickle", "dill", "shelve", "marshal", "cloudpickle"}
#: Modules allowed to call exec: they compile numba kernels from source text that the
#: package writes itself from integer sizes (no configuration or data string reaches it).
EXEC_ALLOWED = {"model/_kernels.py", "model/kernels/_codegen.py"}
#: Modules that call ``_compile`` of the modules above with generated kernel lines.
COMPILE_CALLERS = ("model/kernels/backlash.py", "model/kernels/coulomb.py",
                   "model/kernels/cubic.py",
                   "model/kernels/linear_input.py",
                   "model/kernels/lugre.py", "inference/noise/kalman.py")


def _name(node) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return f"{_name(node.value)}.{node.attr}"
    return ""


def scan(source: str, filename: str = "<src>") -> list[str]:
    """Problems in Python source: unpickling, eval/exec, np.load without
    ``allow_pickle=False``."""
    out = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import | ast.ImportFrom):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""]
            out += [f"{filename}:{node.lineno}: imports {m}" for m in mods
                    if m.split(".")[0] in FORBIDDEN_MODULES]
        if not isinstance(node, ast.Call):
            continue
        name = _name(node.func)
        if name in FORBIDDEN_CALLS:
            out.append(f"{filename}:{node.lineno}: calls {name}")
        if name == "exec" and not any(filename.endswith(f"bayesmodal/{a}") for a in EXEC_ALLOWED):
            out.append(f"{filename}:{node.lineno}: calls exec")
        if name in ("np.load", "numpy.load"):
            kw = {k.arg: k.value for k in node.keywords}
            val = kw.get("allow_pickle")
            if not (isinstance(val, ast.Constant) and val.value is False):
                out.append(f"{filename}:{node.lineno}: np.load without allow_pickle=False")
    return out


def test_scanner_catches_what_it_should():
    # negative controls: the scan finds each forbidden pattern
    bad = ("import pickle\nfrom dill import loads\nx = np.load(f)\ny = np.load(f, "
           "allow_pickle=True)\nz = eval('1')\nexec('1')\nyaml.load(s)\n")
    found = scan(bad, "bad.py")
    assert len(found) == 7, found
    assert scan("a = np.load(f, allow_pickle=False)\n") == []


def test_nothing_is_unpickled_or_evaluated():
    assert len(SOURCES) > 50
    problems = [p for f in SOURCES for p in scan(f.read_text(), str(f.relative_to(REPO)))]
    assert problems == []


def test_exec_sites_take_no_outside_text():
    # exec runs in `_compile(lines, label)`; every function that builds those lines takes
    # only integers and flags (sizes, options), so no configuration or data text reaches it
    for name in sorted(EXEC_ALLOWED):
        tree = ast.parse((REPO / "bayesmodal" / name).read_text())
        execs = [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
                 and any(isinstance(n, ast.Call) and _name(n.func) == "exec"
                         for n in ast.walk(f))]
        assert [f.name for f in execs] == ["_compile"], name
        builders = [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
                    and any(isinstance(n, ast.Call) and _name(n.func) == "_compile"
                            for n in ast.walk(f))]
        for fn in builders:
            kinds = [ast.unparse(a.annotation) if a.annotation else None for a in fn.args.args]
            assert kinds and all(k in ("int", "bool") for k in kinds), (name, fn.name, kinds)
    # modules that call those compilers (generated kernels kept in files of their own)
    # build their lines in functions of integers and flags only
    others = [f for f in (REPO / "bayesmodal").rglob("*.py")
              if str(f.relative_to(REPO / "bayesmodal")) not in EXEC_ALLOWED]
    callers = [f for f in others if re.search(r"\b_compile\(", f.read_text())]
    assert sorted(str(f.relative_to(REPO / "bayesmodal")) for f in callers) == sorted(
        COMPILE_CALLERS)
    # functions that check names against a module's constant whitelist and raise
    checkers = set()
    for f in callers:
        for fn in ast.walk(ast.parse(f.read_text())):
            if isinstance(fn, ast.FunctionDef):
                body = ast.unparse(fn)
                if re.search(r"not in [A-Z_]+\b", body) and "raise" in body:
                    checkers.add(fn.name)
    for f in callers:
        tree = ast.parse(f.read_text())
        builders = [fn for fn in ast.walk(tree) if isinstance(fn, ast.FunctionDef)
                    and any(isinstance(n, ast.Call) and _name(n.func) == "_compile"
                            for n in ast.walk(fn))]
        assert builders, f
        for fn in builders:
            kinds = [ast.unparse(a.annotation) if a.annotation else None for a in fn.args.args]
            # names are allowed only when checked against the module's constant whitelist
            # (e.g. the friction kernels' input stages) before any line is built: inline,
            # or by a checker as the function's first statement
            src = ast.unparse(fn)
            first = fn.body[0] if not isinstance(fn.body[0], ast.Expr) else fn.body[1]
            calls = {_name(n.func) for n in ast.walk(first) if isinstance(n, ast.Call)}
            names_ok = (re.search(r"not in [A-Z_]+\b", src) is not None
                        or bool(calls & checkers))
            # tuples of integers are allowed when each is turned into integers in range
            # before any line is built (the cubic kernel's spring ends, its sensors and
            # their states: ``checked_springs``, ``checked_outputs``, ``checked_columns``;
            # the friction kernel's zero entries of G: ``checked_zeros``)
            # and tuples of flags when each is turned into a bool first
            checked = {a.arg for a in fn.args.args if any(
                re.search(rf"{chk}\({a.arg}\b", src) for chk in (
                    "checked_springs", "checked_outputs", "checked_columns",
                    "checked_zeros"))}
            flags = {a.arg for a in fn.args.args
                     if re.search(rf"tuple\(\(?bool\(\w+\) for \w+ in {a.arg}\)", src)}
            assert kinds and all(
                k in ("int", "bool") or (k == "tuple[str, ...]" and names_ok)
                or (k in ("tuple[tuple[int, int], ...] | None",
                          "tuple[tuple[int, ...], ...] | None", "tuple[int, ...]")
                    and a.arg in checked)
                or (k == "tuple[bool, ...] | None" and a.arg in flags)
                for k, a in zip(kinds, fn.args.args, strict=True)), (f, fn.name, kinds)


# ---------------------------------------------------------------- configurations
PAYLOAD = "__import__('os').system('touch PWNED')"


@pytest.mark.parametrize("section,key,value", [
    ("model", "damping", PAYLOAD),
    ("model", "extensions", [PAYLOAD]),
    ("likelihood", "noise", PAYLOAD),
    ("sampler", "moves", PAYLOAD),
    ("outputs", "dir", "$(touch PWNED)/../../x"),
    ("priors", "m1", {"lo": 0.5, "hi": 2.0, "scale": PAYLOAD}),
    ("data", "files", [f"{PAYLOAD}.csv"]),
])
def test_configuration_strings_are_data_never_code(tmp_path, monkeypatch, section, key, value):
    monkeypatch.chdir(tmp_path)
    raw = {"data": {"files": ["rec.csv"]}, section: {key: value}}
    if section == "data":
        raw = {"data": {key: value}}
    with pytest.raises(ConfigError) as info:
        parse_config(raw, source="evil.toml", base=tmp_path, name="evil")
    assert f"[{section}.{key}]" in str(info.value)
    assert not (tmp_path / "PWNED").exists()


def test_toml_cannot_smuggle_objects(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[data]\nfiles = ["rec.csv"]\n[sampler]\nseed = "!!python/object:os.system"'
                   '\n')
    with pytest.raises(ConfigError, match=r"\[sampler.seed\] must be int"):
        load_config(cfg, check_files=False)


@pytest.mark.parametrize("out_dir", ["../elsewhere", "a/../../b", "/etc/bayesmodal", "..\\x",
                                     "a/..", " "])
def test_output_dir_cannot_escape_the_root(out_dir):
    raw = {"data": {"files": ["rec.csv"]}, "outputs": {"dir": out_dir}}
    with pytest.raises(ConfigError, match=r"\[outputs.dir\]"):
        parse_config(raw, check_files=False)


@pytest.mark.parametrize("name", ["..", "."])
def test_config_named_dot_dot_cannot_escape(tmp_path, name):
    cfg = parse_config({"data": {"files": ["rec.csv"]}}, check_files=False, name=name)
    with pytest.raises(ConfigError, match="output root"):
        default_out_dir(cfg, tmp_path / "root")


def test_symbolic_link_out_of_the_root_is_refused(tmp_path, capsys):
    root = tmp_path / "root"
    root.mkdir()
    outside = tmp_path / "outside"
    outside.mkdir()
    os.symlink(outside, root / "link")
    cfg = parse_config({"data": {"files": ["rec.csv"]}, "outputs": {"dir": "link/run"}},
                       check_files=False, source="c.toml")
    with pytest.raises(ConfigError, match=r"\[outputs.dir\] 'link/run' leads to .*symbolic"):
        default_out_dir(cfg, root)
    ok = parse_config({"data": {"files": ["rec.csv"]}, "outputs": {"dir": "sub/run"}},
                      check_files=False)
    assert default_out_dir(ok, root) == root / "sub" / "run"


# ---------------------------------------------------------------- reports
EVIL = '<script>alert(1)</script><img src=x onerror=alert(2)>"\'&'
NAME = "<script>alert(1)<"  # a file name cannot hold "/"


def _taint(obj, depth=0):
    """Every string value replaced by EVIL (keys kept, so the report still finds them)."""
    if isinstance(obj, dict):
        return {k: _taint(v, depth + 1) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_taint(v, depth + 1) for v in obj]
    if isinstance(obj, str):
        return EVIL
    return obj


def test_report_escapes_every_embedded_string(tmp_path, capsys):
    model = LinearModel(Rig(), "free")
    t = np.arange(300) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(model, [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0], v, 0.005)
    y = y + np.random.default_rng(3).normal(size=y.shape) * 1e-5
    data = f"{NAME} onerror=x.csv"
    save_csv(Experiment(t, v, y, name="rec"), tmp_path / data)
    cfg = tmp_path / f"{NAME}.toml"
    cfg.write_text(f'# {EVIL}\n[data]\nfiles = ["{data}"]\n[sampler]\nwalkers = 30\n'
                   'steps = 40\nburn = 10\n[outputs]\nplots = false\nema = false\n'
                   'predictive_draws = 5\n')
    assert main(["run", str(cfg), "--out-root", str(tmp_path / "out"), "--quiet"]) == 0
    folder = tmp_path / "out" / NAME
    text = (folder / "report.html").read_text()
    assert NAME in json.loads((folder / "summary.json").read_text())["run"]["name"]
    assert "<script" not in text and "<img src=x" not in text
    assert "&lt;script&gt;alert(1)&lt;" in text  # the name is shown, escaped
    # now every string the report reads, replaced by markup
    for name in ("summary.json", "status.json", "timing.json"):
        p = folder / name
        p.write_text(json.dumps(_taint(json.loads(p.read_text()))))
    s = json.loads((folder / "summary.json").read_text())
    s["warnings"] = [EVIL]
    s["parameters"] = {EVIL: next(iter(s["parameters"].values()))}
    (folder / "summary.json").write_text(json.dumps(s))
    (folder / "config.toml").write_text(EVIL)
    text = render_report(folder)
    assert "<script" not in text and "<img src=x" not in text
    assert not re.search(r"onerror=alert\(2\)>", text)
    assert text.count("&lt;script&gt;alert(1)&lt;/script&gt;") >= 4
