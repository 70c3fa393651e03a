"""Many runs at once: local processes (spawn) or a Dask distributed cluster.

Each configuration is one task writing to its own folder under ``out_root``.  A task
never raises for a failing run: it returns a record with the error, so one broken
configuration does not stop the others.  Configurations that do not parse, or whose
folders collide, are reported without being dispatched.  The records are collected into
a :class:`BatchResult`, written to ``batch.json`` in ``out_root``.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

from .._blas import blas_share, limit_blas
from .._errors import ConfigError
from .._progress import progress_bar
from .config import load_config
from .folder import atomic_write_json
from .identify import identify, spec_from_config
from .runner import default_out_dir, execute_run, one_line, prepare_run

__all__ = ["BatchItem", "BatchResult", "run_one", "run_batch"]


@dataclass(frozen=True)
class BatchItem:
    """Outcome of one configuration of a batch.

    Attributes
    ----------
    config : str
        Configuration file.
    name : str
        Configuration name (file stem).
    out_dir : str or None
        Run folder (None when the configuration did not parse).
    state : str
        ``"finished"`` or ``"failed"``.
    action : str or None
        ``"fresh"``, ``"resume"`` or ``"none"`` (already finished) for a finished run.
    error : str or None
        ``"ErrorType: message"`` of a failed run.
    wall_time_s : float
    converged : bool or None
    omega_rad_s, zeta : list of float or None
        Posterior medians of the modal quantities.
    """

    config: str
    name: str
    out_dir: str | None
    state: str
    action: str | None = None
    error: str | None = None
    wall_time_s: float = 0.0
    converged: bool | None = None
    omega_rad_s: list | None = None
    zeta: list | None = None


@dataclass(frozen=True)
class BatchResult:
    """All outcomes of a batch, in the order the configurations were given.

    Attributes
    ----------
    items : tuple of BatchItem
    out_root : Path
    executor : str
        ``"local (N processes)"`` or ``"dask ADDRESS"``.
    wall_time_s : float
    """

    items: tuple[BatchItem, ...]
    out_root: Path
    executor: str
    wall_time_s: float

    @property
    def n_failed(self) -> int:
        return sum(it.state != "finished" for it in self.items)

    def as_dict(self) -> dict:
        return {"out_root": str(self.out_root), "executor": self.executor,
                "wall_time_s": self.wall_time_s, "n_runs": len(self.items),
                "n_failed": self.n_failed, "runs": [asdict(it) for it in self.items]}

    def table(self) -> str:
        """Plain-text summary table, one line per run (errors on their own lines)."""
        head = f"{'run':<24s} {'state':<9s} {'conv.':<6s} {'time (s)':>9s}  omega (rad/s)"
        lines = [head, "-" * len(head)]
        for it in self.items:
            conv = "-" if it.converged is None else ("yes" if it.converged else "no")
            om = ", ".join(f"{w:.4g}" for w in it.omega_rad_s) if it.omega_rad_s else ""
            lines.append(f"{it.name[:24]:<24s} {it.state:<9s} {conv:<6s} "
                         f"{it.wall_time_s:9.1f}  {om}")
            if it.error:
                lines.append(f"    error: {it.error}")
        lines.append(f"{len(self.items) - self.n_failed} of {len(self.items)} runs finished "
                     f"({self.executor}, {self.wall_time_s:.1f} s)")
        return "\n".join(lines)


def _failed(config: str, name: str, out_dir, exc: BaseException, t0: float) -> BatchItem:
    msg = one_line(exc)
    return BatchItem(config=config, name=name, out_dir=None if out_dir is None else str(out_dir),
                     state="failed", error=f"{type(exc).__name__}: {msg}",
                     wall_time_s=time.perf_counter() - t0)


def run_one(config: str, out_dir: str, resume: bool = False, force: bool = False) -> BatchItem:
    """Run one configuration into ``out_dir``; the task of a batch.

    Never raises for a failing run (the error is in the returned item, the traceback in
    the folder's ``run.log`` when the folder was reached).

    Returns
    -------
    BatchItem
    """

    t0 = time.perf_counter()
    name = Path(config).stem
    try:
        cfg = load_config(config)
        if cfg.identify is not None:  # the whole workflow: its final model's modes
            out = identify(spec_from_config(cfg), out_dir, force=force)
            fin = out.summary["final"]
            return BatchItem(config=config, name=name, out_dir=str(out.out_dir),
                             state="finished", action="identify",
                             wall_time_s=time.perf_counter() - t0,
                             converged=bool(fin["converged"]),
                             omega_rad_s=list(fin["modal"]["omega_rad_s"]["median"]),
                             zeta=list(fin["modal"]["zeta"]["median"]))
        prep = prepare_run(cfg)
        res = execute_run(prep, out_dir, resume=resume, force=force, progress=False)
    except Exception as exc:  # noqa: BLE001 - a batch reports every failure and goes on
        return _failed(config, name, out_dir, exc, t0)
    s = res.summary
    return BatchItem(config=config, name=name, out_dir=str(res.out_dir), state=res.state,
                     action=res.action, wall_time_s=time.perf_counter() - t0,
                     converged=bool(s["convergence"]["converged"]),
                     omega_rad_s=list(s["omega_rad_s"]["median"]),
                     zeta=list(s["zeta"]["median"]))


def _plan(configs, out_root: Path) -> tuple[list, dict]:
    """(tasks, early failures): parse every configuration, assign distinct folders."""

    tasks, early, seen = [], {}, {}
    for i, c in enumerate(configs):
        t0 = time.perf_counter()
        path = str(Path(c).resolve())
        try:
            cfg = load_config(path)
            out = default_out_dir(cfg, out_root).resolve()
        except ConfigError as exc:
            early[i] = _failed(str(c), Path(c).stem, None, exc, t0)
            continue
        if out in seen:
            early[i] = _failed(str(c), cfg.name, out, ConfigError(
                f"writes to the same folder {out} as {configs[seen[out]]}; set a distinct "
                "[outputs] dir"), t0)
            continue
        seen[out] = i
        tasks.append((i, path, str(out)))
    return tasks, early


def _progress(total: int, enabled: bool):
    return progress_bar(total, desc="runs", unit="run", enabled=enabled)


def run_batch(configs, *, out_root: str | os.PathLike = "runs", workers: int | None = None,
              scheduler: str | None = None, resume: bool = False, force: bool = False,
              progress: bool = False) -> BatchResult:
    """Run many configurations in parallel, each into its own folder under ``out_root``.

    Parameters
    ----------
    configs : sequence of path
        TOML run configurations.
    out_root : path
        Folder of the run folders and of ``batch.json``.
    workers : int, optional
        Local processes (default: the number of CPUs, at most the number of runs).
        Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``"tcp://host:8786"``); the runs become
        tasks of that cluster (needs ``dask[distributed]``, the ``dask`` extra).
    resume, force : bool
        Passed to every run (see :func:`~.runner.execute_run`).
    progress : bool
        Progress over finished runs on stderr (a tqdm bar on a terminal, else plain
        lines every 10 %).

    Returns
    -------
    BatchResult

    Examples
    --------
    >>> # res = run_batch(["runs/impulses_free.toml", "runs/steps.toml"], workers=2)
    >>> # print(res.table())
    """

    t0 = time.perf_counter()
    configs = [str(c) for c in configs]
    if not configs:
        raise ConfigError("no configurations given")
    root = Path(out_root)
    root.mkdir(parents=True, exist_ok=True)
    tasks, results = _plan(configs, root)
    bar = _progress(len(configs), progress)
    bar.update(len(results))
    try:
        if scheduler:
            executor = f"dask {scheduler}"
            results.update(_dask(tasks, scheduler, resume, force, bar))
        else:
            n = workers or os.cpu_count() or 1
            n = max(1, min(int(n), max(len(tasks), 1)))
            executor = f"local ({n} process{'es' if n > 1 else ''})"
            results.update(_local(tasks, n, resume, force, bar))
    finally:
        bar.close()
    res = BatchResult(items=tuple(results[i] for i in range(len(configs))), out_root=root,
                      executor=executor, wall_time_s=time.perf_counter() - t0)
    atomic_write_json(root / "batch.json", res.as_dict())
    return res


def _local(tasks, n_workers: int, resume: bool, force: bool, bar) -> dict:
    out = {}
    if not tasks:
        return out
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx, initializer=limit_blas,
                             initargs=(blas_share(n_workers),)) as pool:
        futs = {pool.submit(run_one, path, od, resume, force): (i, path, od)
                for i, path, od in tasks}
        for fut in as_completed(futs):
            i, path, od = futs[fut]
            try:
                out[i] = fut.result()
            except Exception as exc:  # noqa: BLE001 - e.g. a worker killed: report, go on
                out[i] = _failed(path, Path(path).stem, od, exc, time.perf_counter())
            bar.update(1)
    return out


def _dask(tasks, address: str, resume: bool, force: bool, bar) -> dict:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError as exc:
        raise ConfigError("--scheduler needs dask[distributed]: pip install "
                          "'bayesmodal[dask]'") from exc
    out = {}
    if not tasks:
        return out
    with Client(address, set_as_default=False) as client:
        futs = {}
        for i, path, od in tasks:
            f = client.submit(run_one, path, od, resume, force, pure=False,
                              key=f"bayesmodal-run-{i}-{Path(path).stem}-{os.getpid()}")
            futs[f] = (i, path, od)
        for fut in dask_completed(list(futs), loop=client.loop):
            i, path, od = futs[fut]
            try:
                out[i] = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker: report, go on
                out[i] = _failed(path, Path(path).stem, od, exc, time.perf_counter())
            bar.update(1)
    return out

