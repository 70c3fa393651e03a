"""One posterior run from a configuration, into its own folder.

:func:`prepare_run` checks everything that can be checked before sampling (data readable
and matching the rig, priors, ensemble size, moves) and raises a ``ConfigError`` naming
the configuration key; :func:`execute_run` then samples with an atomic checkpoint
(:class:`~.checkpoint.AtomicCheckpoint`), writes the InferenceData, summary and plots
(``bayesmodal.runs.outputs.write_run``), the cross-checks, provenance and ``report.html``.

A folder holding a finished run is not overwritten unless ``force``; an interrupted or
failed run continues from its checkpoint with ``resume`` (same configuration hash only),
and ends with the chain the uninterrupted run would have produced.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import threading
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._errors import one_line
from .._progress import progress_bar
from .._version import __version__
from ..inference import (
    nested_evidence,
    posterior_matrix,
    sample_posterior,
    to_inference_data,
)
from ..inference.crossval import crossval
from ..inference.moves import parse_moves
from ..inference.temperature import calibrate_loro
from ..metrics import fit_percent
from ..plots.runs import plot_residual_acf, plot_residuals
from .checkpoint import AtomicCheckpoint, checkpoint_iteration, compact_checkpoint
from .config import RunConfig, load_config
from .crosscheck import lsce_check, residual_check
from .crossval import write_crossval
from .folder import RunExistsError, RunFolder, atomic_savefig, now_iso
from .heldout import heldout_scores
from .outputs import write_modal_plot, write_run
from .prepare import PreparedRun, default_out_dir, prepare_run
from .provenance import data_digests, dependency_versions
from .report import write_report

__all__ = ["PreparedRun", "RunOutcome", "prepare_run", "execute_run", "run_config",
           "default_out_dir", "parse_moves", "one_line", "LOGGER_NAME"]

#: Logger whose records go to ``run.log`` in the run folder.
LOGGER_NAME = "bayesmodal"

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunOutcome:
    """What :func:`execute_run` did.

    Attributes
    ----------
    name : str
        Configuration name.
    out_dir : Path
    state : str
        ``"finished"`` (also for a run that was already finished).
    action : str
        ``"fresh"``, ``"resume"`` or ``"none"`` (already finished, nothing done).
    summary : dict
        Content of ``summary.json``.
    wall_time_s : float
        Wall time of this call, s.
    """

    name: str
    out_dir: Path
    state: str
    action: str
    summary: dict
    wall_time_s: float


def _decide(folder: RunFolder, chash: str, resume: bool, force: bool) -> str:
    """``"fresh"``, ``"resume"`` or ``"none"`` for a folder (raises when it may not be
    touched)."""
    st = folder.status()
    if st is None:
        if folder.checkpoint_path.exists() and not force:
            raise RunExistsError(f"{folder.path} holds a checkpoint but no run status; "
                                 "use --force to start over")
        return "fresh"
    if force:
        return "fresh"
    same = st.get("config_hash") == chash
    if st["state"] == "finished":
        if resume and same:
            return "none"
        raise RunExistsError(
            f"{folder.path} holds a finished run"
            + ("" if same else " of a different configuration")
            + "; use --force to overwrite it or choose another --out")
    done = checkpoint_iteration(folder.checkpoint_path)
    if not resume:
        raise RunExistsError(
            f"{folder.path} holds a {st['state']} run ({done} of {st.get('steps', '?')} steps "
            "in its checkpoint); use --resume to continue it or --force to start over")
    if not same:
        raise RunExistsError(
            f"{folder.path} holds a run of a different configuration (hash "
            f"{st.get('config_hash', '?')[:12]}, now {chash[:12]}); use --force to start over")
    return "resume"


@contextlib.contextmanager
def _run_log(folder: RunFolder):
    """Send ``bayesmodal`` log records (INFO and up) of this thread to ``run.log`` for the
    block (a Dask worker with several threads may run two runs in one process)."""
    logger = logging.getLogger(LOGGER_NAME)
    handler = logging.FileHandler(folder.path / "run.log", mode="a", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    handler.setLevel(logging.INFO)
    me = threading.get_ident()
    handler.addFilter(lambda record: record.thread == me)
    old = logger.level
    logger.addHandler(handler)
    if logger.getEffectiveLevel() > logging.INFO:
        logger.setLevel(logging.INFO)
    try:
        yield logger
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old)
        handler.close()


class _Stages:
    """Progress over the named stages of a run (``bayesmodal._progress``; silent when
    disabled)."""

    def __init__(self, names, enabled: bool, title: str) -> None:
        self.bar = progress_bar(len(names), desc=title, unit="stage", enabled=enabled)

    @contextlib.contextmanager
    def stage(self, name: str):
        self.bar.set_postfix_str(name)
        log.info("stage: %s", name)
        t0 = time.perf_counter()
        yield
        log.info("stage done: %s (%.1f s)", name, time.perf_counter() - t0)
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


_STAGES = ("sampling", "posterior", "outputs", "cross-checks", "crossval", "report")


def _posterior_median(summary: dict, names) -> np.ndarray:
    return np.array([summary["parameters"][nm]["median"] for nm in names])


def _verdict_detail(diag: dict) -> str:
    if diag["converged"]:
        return (f"max R-hat {diag['max_rhat']:.3f}, min bulk ESS {diag['min_ess']:.0f}, "
                f"chain {diag['n_over_tau']:.0f} autocorrelation times long, acceptance "
                f"{diag['acceptance']:.2f}")
    return "; ".join(diag["problems"])


def _cross_checks(prep: PreparedRun, run, idata, summary: dict, folder: RunFolder,
                  progress: bool) -> dict:
    cfg = prep.config
    model = prep.model
    ext = run.likelihood.extension
    out: dict = {}
    names = run.likelihood.mech_names
    theta_med = _posterior_median(summary, names)
    lsq = run.lsq
    out["lsq"] = None if lsq is None else {
        "theta": dict(zip(names, lsq.theta.tolist(), strict=True)),
        "fit_percent": lsq.fit_percent.tolist(), "success": bool(lsq.success)}
    work = [("residuals", e) for e in prep.experiments]
    if cfg.outputs.ema:
        work += [("lsce", e) for e in prep.experiments]
    res_checks, lsce = [], []
    record_theta = _record_medians(run, idata)
    with progress_bar(len(work), desc="cross-checks", unit="check", enabled=progress,
                      leave=False) as bar:
        for kind, e in work:
            if kind == "residuals":
                th = record_theta.get(e.name, theta_med)
                res_checks.append(residual_check(e, model, th, extension=ext))
            else:
                chk = lsce_check(e, model.n_carts)
                if chk.error:
                    log.warning("LSCE on %s: %s", e.name, chk.error)
                lsce.append(chk)
            bar.update(1)
    omega_med = np.asarray(summary["omega_rad_s"]["median"], float)
    out["residuals"] = [c.as_dict() for c in res_checks]
    out["lsce"] = []
    for c in lsce:
        om, ze = c.matched(omega_med)
        d = c.as_dict()
        d.update({"omega_matched": om.tolist(), "zeta_matched": ze.tolist()})
        out["lsce"].append(d)
    if cfg.outputs.plots:
        if lsce:  # the modal-interval plot of write_run, now with the LSCE values
            write_modal_plot(idata, folder.path, lsce=[
                (c.experiment, *c.matched(omega_med)) for c in lsce if not c.error])
        atomic_savefig(plot_residuals(res_checks).flat[0].figure, folder.path / "residuals.png",
                       dpi=160)
        atomic_savefig(plot_residual_acf(res_checks).flat[0].figure,
                  folder.path / "residual_acf.png", dpi=160)
    return out


def _record_medians(run, idata) -> dict:
    """Several records: each record's own model parameters (posterior medians, its own
    g_v), so that its residual diagnostics see its gain.  The input offset v0 is not a
    model parameter of the single-record diagnostics and is left out."""
    lik = run.likelihood
    if lik.layout is None:
        return {}

    draws = posterior_matrix(idata, list(lik.names)).reshape(-1, lik.n_params)
    n_mech = len(lik.mech_names)
    return {e.name: np.median(lik.record_theta(draws, r)[0][:, :n_mech], axis=0)
            for r, e in enumerate(lik.experiments)}


def _evidence(prep: PreparedRun, run) -> dict | None:
    cfg = prep.config
    if not cfg.evidence.enabled:
        return None

    ev = nested_evidence(run.likelihood, prep.priors, nlive=cfg.evidence.nlive,
                         dlogz=cfg.evidence.dlogz, rng=cfg.sampler.seed)
    return {"log_z": ev.log_z, "log_z_err": ev.log_z_err,
            "information_nats": ev.information_nats, "n_calls": ev.n_calls,
            "elapsed_s": ev.elapsed_s, "nlive": cfg.evidence.nlive,
            "dlogz": cfg.evidence.dlogz}


def _extensions(prep: PreparedRun, run, summary: dict) -> dict:
    """The sampled extension: posterior medians and intervals of its parameters, fit
    percentages at the posterior median against the linear least-squares fit."""
    if prep.extension is None:
        return {}

    lik = run.likelihood
    ext = lik.extension
    rig = prep.model.rig
    names = lik.mech_names
    theta_med = ext.check(rig, _posterior_median(summary, names))
    fits = np.array([fit_percent(e.y_m, ext.simulate(rig, theta_med, e.v_volt, e.dt))
                     for e in prep.experiments])
    lsq = run.lsq
    lin_fit = None if lsq is None else np.asarray(lsq.linear.fit_percent)
    own = ext.extension_names(rig)
    out = {
        "method": "posterior (emcee) of the extended model; fit % at the posterior median",
        "params": {nm: summary["parameters"][nm]["median"] for nm in own},
        "intervals": {nm: [summary["parameters"][nm]["lo"], summary["parameters"][nm]["hi"]]
                      for nm in own},
        "location": ext.location_of(rig, theta_med).label,
        "fit_percent": fits.tolist(),
        "linear_fit_percent": None if lin_fit is None else lin_fit.tolist(),
        "improvement_percent": None if lin_fit is None else (fits - lin_fit).tolist(),
        "lsq_params": None if lsq is None else {
            nm: float(v) for nm, v in zip(names, lsq.theta, strict=True) if nm in own},
    }
    log.info("extension %s: fit %s %% at the posterior median (linear LSQ %s %%)",
             ext.name, np.round(fits, 2).tolist(),
             None if lin_fit is None else np.round(lin_fit, 2).tolist())
    return {ext.name: out}


#: The calibrated temperature of a run, kept in its folder for a resumed run.
TEMPERATURE_FILE = "temperature.json"


def _temperature(prep: PreparedRun, folder: RunFolder):
    """The likelihood temperature of the run, its calibration (``temperature = "loro"``:
    leave-one-record-out coverage, ``inference.temperature``) or None, and the
    leave-one-record-out study at that temperature the calibration measured (or None).

    The calibration is written to the run folder (``TEMPERATURE_FILE``, with the
    configuration hash) before sampling starts; a resumed run of the same configuration
    reads it back instead of repeating the studies, and continues its chain at the
    temperature it started with (its [crossval] check is then measured again)."""
    cfg = prep.config
    if cfg.likelihood.temperature != "loro":
        return float(cfg.likelihood.temperature), None, None

    path = folder.path / TEMPERATURE_FILE
    chash = cfg.hash()
    if path.is_file():
        kept = json.loads(path.read_text(encoding="utf-8"))
        if kept.get("config_hash") == chash:
            cal = kept["calibration"]
            log.info("temperature %.4g from %s (calibrated when the run started)",
                     cal["temperature"], path.name)
            return float(cal["temperature"]), cal, None
    cal, study = calibrate_loro(list(prep.experiments), cfg.crossval_spec(), joint=False,
                                progress=lambda line: log.info("temperature: %s", line))
    log.info("calibrated temperature %.4g (%s)", cal.temperature, cal.status)
    folder.write_json(TEMPERATURE_FILE, {"config_hash": chash, "calibration": cal.to_dict()})
    return cal.temperature, cal.to_dict(), study


def _crossval(prep: PreparedRun, folder: RunFolder, progress: bool,
              temperature: float = 1.0, study=None) -> dict:
    """Leave-one-record-out check of the configuration, written to ``crossval/``;
    ``study`` is that check already computed at ``temperature`` (by the calibration)."""
    def say(line: str) -> None:
        log.info("crossval: %s", line)

    res = study if study is not None else crossval(
        list(prep.experiments), replace(prep.config.crossval_spec(), temperature=temperature),
        joint=False, progress=say)
    write_crossval(res, folder.path / "crossval", plots=prep.config.outputs.plots)
    d = res.to_dict()
    return {"records": d["records"], "total": d["total"], "own_lsq": d["own_lsq"],
            "spec": d["spec"], "wall_time_s": d["wall_time_s"]}


def _pop_clock(cv: dict) -> dict:
    """The clock's numbers of the leave-one-record-out check (its wall time, each fold's
    time and evaluation rate), taken out of ``cv`` (summary.json's ``crossval``)."""
    return {"wall_time_s": cv.pop("wall_time_s", None),
            "records": [{k: r.pop(k, None) for k in ("elapsed_s", "evaluations_per_s")}
                        for r in cv.get("records", [])]}


def _config_text(cfg: RunConfig) -> str:
    p = Path(cfg.source)
    if p.is_file():
        return p.read_text(encoding="utf-8")
    return json.dumps(cfg.to_dict(), indent=2)


def _pipeline(prep: PreparedRun, folder: RunFolder, action: str, progress: bool,
              t_start: float, started: str, caught: list, start=None) -> dict:
    cfg = prep.config
    stages = _Stages(tuple(st for st in _STAGES if cfg.crossval.enabled or st != "crossval"),
                     progress, cfg.name)
    try:
        with stages.stage("sampling"):
            backend = AtomicCheckpoint(folder.checkpoint_path,
                                       every_s=cfg.outputs.checkpoint_every_s)
            steps_before = backend.iteration if backend.initialized else 0
            log.info("sampling %d walkers x %d steps (%d already in the checkpoint), seed %d",
                     cfg.sampler.walkers, cfg.sampler.steps, steps_before, cfg.sampler.seed)
            temperature, calibration, study = _temperature(prep, folder)
            # the model, moves and priors prepare_run checked, not built again
            run = sample_posterior(
                list(prep.experiments), prep.model,
                cfg.likelihood_spec(noise=prep.noise, temperature=temperature),
                cfg.sampler.spec(prep.moves, progress=progress, warn=False),
                priors=prep.priors, start=start, rng=cfg.seed, backend=backend)
            log.info("sampling done: %d evaluations in %.1f s", run.n_evaluations,
                     run.elapsed_s)
        with stages.stage("posterior"):
            idata = to_inference_data(run, n_predictive=cfg.outputs.predictive_draws,
                                      rng=cfg.sampler.seed,
                                      pointwise=cfg.outputs.pointwise_loglik)
        with stages.stage("outputs"):
            summary = write_run(idata, folder.path, plots=cfg.outputs.plots)
        with stages.stage("cross-checks"):
            summary["crosscheck"] = _cross_checks(prep, run, idata, summary, folder, progress)
            held = heldout_scores(prep, idata)
            if held is not None:
                summary["heldout"] = held
            ev = _evidence(prep, run)
            if ev is not None:
                summary["evidence"] = ev
            ext = _extensions(prep, run, summary)
            if ext:
                summary["extensions"] = ext
        if calibration is not None:
            summary["temperature_calibration"] = calibration
        if cfg.crossval.enabled:
            with stages.stage("crossval"):
                summary["crossval"] = _crossval(prep, folder, progress, temperature, study)
        diag = summary["diagnostics"]
        detail = _verdict_detail(diag)
        summary["convergence"] = {
            "converged": bool(diag["converged"]),
            "verdict": ("converged: " if diag["converged"] else "NOT converged: ") + detail,
            "detail": detail, "problems": list(diag["problems"])}
        summary["run"] = {
            "name": cfg.name,
            "config_source": cfg.source,
            "config_hash": cfg.hash(),
            "sampler_config_hash": summary["provenance"]["config_hash"],
            "config": cfg.to_dict(),
            "data": data_digests(cfg.data.files),
            "heldout_data": data_digests(cfg.data.heldout),
            "bayesmodal_version": __version__,
            "dependencies": dependency_versions(),
            "seed": cfg.sampler.seed,
            "walkers": cfg.sampler.walkers, "steps": cfg.sampler.steps,
            "burn": cfg.sampler.burn, "thin": cfg.sampler.thin,
            "moves": cfg.sampler.moves,
        }
        summary["warnings"] = [f"{w.category.__name__}: {w.message}" for w in caught]
        # what depends on the clock or on how the run was split goes to timing.json, so
        # that a rerun of the same configuration and data reproduces summary.json exactly
        timing = {"action": action, "steps_in_checkpoint_at_start": steps_before,
                  "started": started, "finished": now_iso(),
                  "wall_time_s": time.perf_counter() - t_start,
                  "performance": summary.pop("performance", None)}
        if isinstance(summary.get("evidence"), dict):
            timing["evidence_elapsed_s"] = summary["evidence"].pop("elapsed_s", None)
        if isinstance(summary.get("crossval"), dict):
            timing["crossval"] = _pop_clock(summary["crossval"])
        folder.write_json("timing.json", timing)
        folder.write_json("summary.json", summary)
        with stages.stage("report"):
            if cfg.outputs.report:
                write_report(folder.path, state="finished")
    finally:
        stages.close()
    return summary


def execute_run(prepared: PreparedRun, out_dir: str | os.PathLike, *, resume: bool = False,
                force: bool = False, progress: bool = False, start=None) -> RunOutcome:
    """Sample a prepared configuration into ``out_dir``.

    Parameters
    ----------
    prepared : PreparedRun
        From :func:`prepare_run`.
    out_dir : str or path
        The run folder (created).
    resume : bool
        Continue an interrupted or failed run of the same configuration from its
        checkpoint (a finished one is left as it is).
    force : bool
        Start over, deleting the run files already in the folder.
    progress : bool
        Progress bars (tqdm) on stderr.
    start : ndarray, shape (n_mechanical,), optional
        Where the sampler's start search begins (the model's parameters, e.g. a fit the
        caller already has); default the least-squares fit.  Ignored by a resumed chain.

    Returns
    -------
    RunOutcome

    Raises
    ------
    RunLockedError
        Another live process is writing the folder.
    RunExistsError
        The folder holds a run and neither ``resume`` nor ``force`` allows touching it.
    """
    cfg = prepared.config
    t0 = time.perf_counter()
    started = now_iso()
    folder = RunFolder(out_dir)
    chash = cfg.hash()
    with folder.lock():
        action = _decide(folder, chash, resume, force)
        if action == "none":
            summary = json.loads((folder.path / "summary.json").read_text(encoding="utf-8"))
            return RunOutcome(cfg.name, folder.path, "finished", "none", summary,
                              time.perf_counter() - t0)
        if action == "fresh":
            folder.clear()
        folder.remove_temporaries()
        with _run_log(folder) as logger, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            logger.info("run %s (%s) in %s: %s, config hash %s", cfg.name, cfg.source,
                        folder.path, action, chash[:16])
            folder.write_text("config.toml", _config_text(cfg))
            folder.write_json("config.json", cfg.to_dict())
            folder.write_status("running", config=cfg.name, config_hash=chash,
                                steps=cfg.sampler.steps, started=started, action=action)
            try:
                summary = _pipeline(prepared, folder, action, progress, t0, started, caught,
                                    start)
            except BaseException as exc:
                logger.exception("run failed")
                folder.write_status("failed", error=f"{type(exc).__name__}: {exc}",
                                    failed=now_iso())
                raise
            finally:
                for w in caught:
                    logger.warning("%s: %s", w.category.__name__, w.message)
            wall = time.perf_counter() - t0
            folder.write_status("finished", finished=now_iso(), wall_time_s=wall)
            if cfg.outputs.chain == "compact":
                # after "finished": a compacted chain is never resumed as a checkpoint
                try:
                    compact_checkpoint(folder.checkpoint_path, burn=cfg.sampler.burn,
                                       thin=cfg.sampler.thin)
                except OSError as exc:
                    logger.warning("chain.h5 kept in full: %s", exc)
            logger.info("run finished in %.1f s; converged: %s", wall,
                        summary["convergence"]["converged"])
    return RunOutcome(cfg.name, folder.path, "finished", action, summary, wall)


def run_config(config: str | os.PathLike | RunConfig, out_dir: str | os.PathLike | None = None,
               *, out_root: str | os.PathLike = "runs", resume: bool = False,
               force: bool = False, progress: bool = False) -> RunOutcome:
    """Load (if a path), check and run one configuration.

    Parameters
    ----------
    config : path or RunConfig
    out_dir : path, optional
        Run folder (default :func:`default_out_dir` under ``out_root``).
    out_root : path
    resume, force, progress
        See :func:`execute_run`.

    Returns
    -------
    RunOutcome

    Examples
    --------
    >>> # run_config("runs/impulses_free.toml", progress=True).summary["convergence"]
    """
    cfg = config if isinstance(config, RunConfig) else load_config(config)
    prep = prepare_run(cfg)
    out = Path(out_dir) if out_dir is not None else default_out_dir(cfg, out_root)
    return execute_run(prep, out, resume=resume, force=force, progress=progress)
