"""Re-run a recorded run and check that it reproduces its ``summary.json`` exactly.

A finished run folder records everything its result depends on: the configuration
(``config.json``, whose SHA-256 ``summary.json`` holds as ``run.config_hash``), the SHA-256
of every data file, the seed, and the versions of bayesmodal and its dependencies.
Timings live in ``timing.json``, so the same configuration on the same data with the same
versions gives the same ``summary.json``, byte for byte.  :func:`rerun_run` checks the
record (configuration hash, data digests), samples it again into a fresh folder and
compares.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from .._errors import ConfigError, DataError
from .._version import __version__
from ..data import file_sha256
from .config import PriorOverride, RunConfig
from .description import FLAT_NAMES
from .provenance import dependency_versions
from .runner import execute_run, prepare_run

__all__ = ["RerunResult", "rerun_run", "recorded_config", "json_differences"]


@dataclass(frozen=True)
class RerunResult:
    """Outcome of :func:`rerun_run`.

    Attributes
    ----------
    run_dir : Path
        The recorded run.
    rerun_dir : Path
        Folder of the new run.
    identical : bool
        ``summary.json`` of the new run equals the recorded one byte for byte.
    differences : tuple of str
        ``"key.path: recorded != rerun"`` for the first differing values (empty when
        identical).
    version_changes : dict
        ``{name: (recorded, installed)}`` for bayesmodal and each dependency whose version
        differs from the recorded one (a likely cause of differences).
    """

    run_dir: Path
    rerun_dir: Path
    identical: bool
    differences: tuple[str, ...]
    version_changes: dict

    def as_dict(self) -> dict:
        return {"run_dir": str(self.run_dir), "rerun_dir": str(self.rerun_dir),
                "identical": self.identical, "differences": list(self.differences),
                "version_changes": {k: list(v) for k, v in self.version_changes.items()}}


def _read_json(path: Path) -> dict:
    if not path.is_file():
        raise ConfigError(f"{path.parent}: no {path.name} (not a finished run folder)")
    try:
        obj = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: unreadable ({exc})") from exc
    if not isinstance(obj, dict):
        raise ConfigError(f"{path}: not a JSON object")
    return obj


def recorded_config(run_dir: str | os.PathLike) -> RunConfig:
    """The configuration a run folder records (``config.json``), checked against the hash
    in its ``summary.json``.

    Raises
    ------
    ConfigError
        When the folder holds no finished run, or ``config.json`` does not match the
        recorded configuration hash (edited after the run).
    """
    folder = Path(run_dir)
    summary = _read_json(folder / "summary.json")
    raw = _read_json(folder / "config.json")
    unknown = sorted(set(raw) - set(FLAT_NAMES) - {"name", "source", "identify"})
    if unknown:
        raise ConfigError(f"{folder / 'config.json'}: unknown field(s) {unknown}")
    kw = dict(raw)
    try:
        kw["priors"] = {k: PriorOverride(**v) for k, v in (raw.get("priors") or {}).items()}
        for key in ("data_files", "springs_n_m", "extensions", "heldout_files"):
            if key in kw:
                kw[key] = tuple(kw[key])
        cfg = RunConfig.from_flat(kw)
    except TypeError as exc:
        raise ConfigError(f"{folder / 'config.json'}: malformed ({exc})") from exc
    want = summary.get("run", {}).get("config_hash")
    same_record = json.loads(json.dumps(cfg.to_dict())) == summary.get("run", {}).get("config")
    if cfg.hash() != want or not same_record:
        raise ConfigError(
            f"{folder / 'config.json'}: its hash {cfg.hash()[:12]} is not the recorded "
            f"configuration hash {str(want)[:12]} (edited after the run?)")
    return cfg


def json_differences(a, b, path: str = "", limit: int = 20) -> list[str]:
    """Paths at which two JSON values differ, ``"path: a != b"``, at most ``limit``.

    Examples
    --------
    >>> json_differences({"x": [1, 2], "y": 1}, {"x": [1, 3], "y": 1})
    ['x[1]: 2 != 3']
    """
    out: list[str] = []

    def walk(x, y, p):
        if len(out) >= limit:
            return
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y), key=str):
                q = f"{p}.{k}" if p else str(k)
                if k not in x or k not in y:
                    out.append(f"{q}: {'missing' if k not in x else 'present'} != "
                               f"{'missing' if k not in y else 'present'}")
                else:
                    walk(x[k], y[k], q)
        elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
            for i, (u, v) in enumerate(zip(x, y, strict=True)):
                walk(u, v, f"{p}[{i}]")
        elif x != y or type(x) is not type(y):
            out.append(f"{p}: {x!r} != {y!r}")

    walk(a, b, path)
    return out


def _check_data(summary: dict, folder: Path) -> None:
    run = summary.get("run", {})
    for d in list(run.get("data", [])) + list(run.get("heldout_data", [])):
        p = Path(d["file"])
        if not p.is_file():
            raise DataError(f"{folder}: recorded data file {p} is missing")
        sha = file_sha256(p)
        if sha != d["sha256"]:
            raise DataError(f"{p}: changed since the run (SHA-256 {sha[:12]}, recorded "
                            f"{d['sha256'][:12]})")


def _version_changes(summary: dict) -> dict:
    run = summary.get("run", {})
    now = {"bayesmodal": __version__, **dependency_versions()}
    then = {"bayesmodal": run.get("bayesmodal_version"), **run.get("dependencies", {})}
    return {k: (then.get(k), now.get(k)) for k in sorted(set(now) | set(then))
            if then.get(k) != now.get(k)}


def rerun_run(run_dir: str | os.PathLike, out_dir: str | os.PathLike | None = None, *,
              progress: bool = False) -> RerunResult:
    """Re-run a recorded run from its own record and compare ``summary.json``.

    Parameters
    ----------
    run_dir : str or path
        A finished run folder (from ``bayesmodal run`` or :func:`~.runner.run_config`).
    out_dir : str or path, optional
        Folder of the new run (default ``<run_dir>-rerun`` beside it); files of an earlier
        rerun there are replaced.  Must not be ``run_dir``.
    progress : bool
        Progress bars.

    Returns
    -------
    RerunResult

    Raises
    ------
    ConfigError
        No finished run in ``run_dir``, an edited ``config.json``, or ``out_dir`` equal to
        ``run_dir``.
    DataError
        A recorded data file is missing or its SHA-256 changed.

    Examples
    --------
    >>> # res = rerun_run("runs/impulses_free"); res.identical, res.differences
    """

    folder = Path(run_dir)
    summary = _read_json(folder / "summary.json")
    cfg = recorded_config(folder)
    _check_data(summary, folder)
    out = Path(out_dir) if out_dir is not None else folder.with_name(folder.name + "-rerun")
    if out.resolve() == folder.resolve():
        raise ConfigError(f"{out}: the rerun must go to another folder than the run itself")
    execute_run(prepare_run(cfg), out, force=True, progress=progress)
    a = (folder / "summary.json").read_bytes()
    b = (out / "summary.json").read_bytes()
    diffs = () if a == b else tuple(json_differences(json.loads(a), json.loads(b)))
    if a != b and not diffs:
        diffs = ("summary.json: same values, different bytes",)
    return RerunResult(folder, out, a == b, diffs, _version_changes(summary))
