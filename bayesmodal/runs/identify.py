"""From records to modal parameters a user can trust: one workflow, stage by stage.

:func:`identify` takes the linear model's run configuration (its records, rig, noise and
sampler) and, each stage in its own place in the output folder, so that an interrupted
workflow continues where it stopped:

1. ``linear/``: the linear model's posterior, residual checks and leave-one-record-out
   check (``bayesmodal run`` of that configuration);
2. ``diagnosis.json``: what the linear model gets wrong and why (``diagnose``: forward
   selection of the effects by held-out gain, on the training records);
3. ``final/``: the joint posterior of the model the diagnosis found (the linear core with
   its effects), warm-started from the diagnosis' fit, with its own leave-one-record-out
   check; skipped when the diagnosis found nothing;
4. ``identify.json`` and ``report.html``: the rig's modal parameters from that model
   with intervals, the linear model's beside them, the causes with their held-out gains,
   and each held-out record's own estimate against the interval for it.

What the diagnosis does on its own where the records call for it (``DiagnosisSpec``):
the records are weighed by their spread when there are several (otherwise the record
held longest away from rest outweighs the others), the record that drives the carts
furthest is cut at its rests (so that an effect only it reaches, such as an end stop, is
tested on parts of itself), and the end stop of the driven cart is a candidate wherever
the rig has one driven cart.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .._json import to_jsonable
from ..discrepancy.diagnosis import (
    diagnose,
    require_diagnosable,
)
from ..inference.threads import resolve_threads
from ..model.effects import EXTENSIONS, get_extension
from ..model.system import LinearModel, param_kinds
from ..segments import split_at_rest, split_records
from .config import RunConfig
from .folder import RunFolder, atomic_write_json, now_iso
from .identify_spec import IDENTIFY_FINAL_KEYS, DiagnosisSpec, FinalSpec
from .identify_summary import summarize, write_identify_report
from .runner import execute_run, prepare_run

__all__ = ["DiagnosisSpec", "FinalSpec", "IdentifySpec", "IdentifyOutcome", "identify",
           "final_config", "warm_start", "diagnosis_records", "sampled_effects",
           "spec_from_config"]

#: Stages in order, as named in progress lines and ``identify.json``.
STAGES = ("linear", "diagnosis", "final", "summary")


@dataclass(frozen=True)
class IdentifySpec:
    """One identification: the linear run, the diagnosis and the final model's sampler.

    Attributes
    ----------
    linear : RunConfig
        The linear model's run configuration (records, rig, noise, layout, sampler).
    diagnosis : DiagnosisSpec
    final : FinalSpec
    """

    linear: RunConfig
    diagnosis: DiagnosisSpec = field(default_factory=DiagnosisSpec)
    final: FinalSpec = field(default_factory=FinalSpec)

    def diagnosis_key(self) -> str:
        """What the diagnosis depends on: the linear configuration and its options."""
        blob = json.dumps({"linear": self.linear.hash(), "diagnosis": asdict(self.diagnosis)},
                          sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()


@dataclass(frozen=True)
class IdentifyOutcome:
    """What :func:`identify` produced.

    Attributes
    ----------
    out_dir : Path
    summary : dict
        ``identify.json``'s content.
    stage_s : dict
        Wall time of each stage this call ran, s (0 for a stage reused from the folder).
    """

    out_dir: Path
    summary: dict
    stage_s: dict


def _set_aside(path: Path, tag: str, progress: bool) -> None:
    """Keep a stage's output made with other inputs under ``<name>.<tag>`` (never lost),
    so that the stage runs again."""
    target = path.with_name(f"{path.stem}.{tag}{path.suffix}")
    k = 1
    while target.exists():
        k += 1
        target = path.with_name(f"{path.stem}.{tag}-{k}{path.suffix}")
    path.rename(target)
    _say(progress, f"{path.name} was made with other inputs: kept as {target.name}")


def _stale_run(path: Path, config: RunConfig | None, progress: bool) -> None:
    """Set ``path`` aside when it holds a run of another configuration than ``config``
    (any run when ``config`` is None: the stage is not run this time)."""
    status = path / "status.json"
    if not status.is_file():
        return
    old = json.loads(status.read_text(encoding="utf-8")).get("config_hash", "")
    if config is None or old != config.hash():
        _set_aside(path, (old or "old")[:8], progress)


def _say(progress: bool, text: str) -> None:
    if progress:
        print(f"identify: {text}", file=sys.stderr, flush=True)


def diagnosis_records(experiments, rig, spec: DiagnosisSpec):
    """The records the diagnosis fits: cut as ``spec.split`` says, with the training
    indices (all of them).

    Parameters
    ----------
    experiments : sequence of Experiment
        The run's records.
    rig : Rig
        Tells which output reads the driven cart.
    spec : DiagnosisSpec

    Returns
    -------
    experiments : list of Experiment
    train : list of int
    split : list of str
        Names of the records cut at rest (empty when none was).
    """
    exps = list(experiments)
    train = list(range(len(exps)))
    if spec.split == "none" or len(exps) < 2:
        return exps, train, []
    drive = _driven_output(rig)
    peaks = [float(np.max(np.abs(e.y_m[:, drive]))) for e in exps]
    k = int(np.argmax(peaks))
    if sum(p == peaks[k] for p in peaks) > 1:
        return exps, train, []
    if len(split_at_rest(exps[k])) < 2:
        return exps, train, []
    cut, train = split_records(exps, [k], train)
    return cut, train, [exps[k].name]


def _driven_output(rig) -> int:
    """The output reading the driven cart (the first driven one), else the first."""
    driven = np.flatnonzero(rig.input_vector())
    hits = np.flatnonzero(rig.sensor_dofs == driven[0]) if driven.size else []
    return int(hits[0]) if len(hits) else 0


def sampled_effects(effects) -> tuple[str, ...]:
    """The effects the posterior samples for the diagnosis' ``effects``: each replaced by
    its ``sampled_as`` twin where it has one (stick-slip friction by LuGre friction).

    Parameters
    ----------
    effects : sequence of str
        Registry names (``Diagnosis.effects``).

    Returns
    -------
    tuple of str
    """
    return tuple(EXTENSIONS[e].sampled_as or e for e in effects)


def warm_start(rig, effects: tuple[str, ...], diagnosis: dict) -> np.ndarray:
    """The final model's parameter vector at the diagnosis' fit: its linear parameters
    within the found model, and every effect parameter the diagnosis fitted (a twin's
    extra parameters at their null values).

    Parameters
    ----------
    rig : Rig
    effects : tuple of str
        The sampled effects (``sampled_effects``).
    diagnosis : dict
        ``Diagnosis.as_dict()``.

    Returns
    -------
    ndarray, shape (n_params,)
    """
    ext = get_extension(list(effects))
    lin_names = ext.linear_model(rig).names
    lin = np.array([diagnosis["linear_parameters"][n]["after"] for n in lin_names])
    theta = ext.null_theta(rig, lin)
    names = ext.names(rig)
    for name, iv in diagnosis["parameters"].items():
        if name in names:
            theta[names.index(name)] = iv["median"]
    return ext.check(rig, theta)


def final_config(spec: IdentifySpec, effects: tuple[str, ...],
                 walkers: int | None = None) -> RunConfig:
    """The run configuration of the found model: the linear one with ``effects`` and the
    final sampler (``spec.final``).

    Parameters
    ----------
    spec : IdentifySpec
    effects : tuple of str
        The sampled effects (``sampled_effects``).
    walkers : int, optional
        The ensemble size (default ``spec.final.walkers``; :func:`identify` raises it to
        twice the number of sampled parameters where needed).

    Returns
    -------
    RunConfig
        Named ``<linear name>_final``.
    """
    f = spec.final if walkers is None else replace(spec.final, walkers=int(walkers))
    base = spec.linear
    per_record = dict(base.records.per_record if f.per_record is None else f.per_record)
    if f.population:  # every mass of the linear core per record
        core = LinearModel(base.make_rig(), "free")
        for name, kind in zip(core.names, param_kinds(core), strict=True):
            if kind == "mass" and name not in per_record:
                per_record[name] = "hierarchical"
    cv = base.crossval
    return replace(
        base, name=f"{base.name}_final",
        model=replace(base.model, extensions=tuple(effects)),
        sampler=replace(base.sampler, walkers=f.walkers, steps=f.steps, burn=f.burn,
                        thin=f.retained_thin, prune=f.prune, moves=f.moves, init=f.init,
                        threads=resolve_threads(f.threads), restart=None),
        records=replace(base.records, per_record=per_record),
        crossval=replace(cv, enabled=cv.enabled if f.crossval is None else f.crossval,
                         steps=cv.steps if f.crossval_steps is None else f.crossval_steps),
        outputs=replace(base.outputs, dir=""))


def spec_from_config(config: RunConfig) -> IdentifySpec:
    """The workflow a run configuration asks for in its ``[identify]`` table.

    Parameters
    ----------
    config : RunConfig
        With ``identify`` set (``[identify] enabled = true``); the linear run is the
        configuration without that table.

    Returns
    -------
    IdentifySpec
    """
    opts = dict(config.identify or {})
    if "burn" in opts and "prune" not in opts:  # stranded walkers pruned within the burn-in
        opts["prune"] = min(FinalSpec.prune, opts["burn"] // 2) or None
    final = FinalSpec(**{k: v for k, v in opts.items() if k in IDENTIFY_FINAL_KEYS})
    return IdentifySpec(replace(config, identify=None), config.diagnosis, final)


def _final_prepared(spec: IdentifySpec, effects: tuple[str, ...]):
    """The final run's configuration, checked against its data, with at least
    ``spec.final.walkers`` walkers and twice its parameters (emcee's least): with a
    population layer and several records the parameters outgrow a fixed ensemble."""
    counted = prepare_run(final_config(spec, effects, walkers=2 * 10**6))  # to count
    need = 2 * counted.priors.n_params
    walkers = max(spec.final.walkers, need + need % 2)
    cfg = final_config(spec, effects, walkers=walkers)
    return cfg, replace(counted, config=cfg)


def _diagnose(spec: IdentifySpec, prep, folder: RunFolder, progress: bool) -> dict:
    """The diagnosis stage: ``diagnosis.json`` (reused when its key matches)."""
    path = folder.path / "diagnosis.json"
    key = spec.diagnosis_key()
    if path.is_file():
        old = json.loads(path.read_text(encoding="utf-8"))
        if old.get("key") == key:
            return old
        _set_aside(path, str(old.get("key", "old"))[:8], progress)
    rig = prep.model.rig
    d = spec.diagnosis
    exps, train, cut = diagnosis_records(prep.experiments, rig, d)
    # the fits' threads: the final stage's (``FinalSpec.threads``, one per core); the same
    # diagnosis on any count
    dspec = replace(d.diagnose_spec(rig, len(train), posterior=False),
                    threads=spec.final.threads)
    t0 = time.perf_counter()
    res = diagnose(exps, dspec, rig=rig, train=train, rng=d.seed, progress=progress)
    out = {"key": key, "finished": now_iso(), "elapsed_s": time.perf_counter() - t0,
           "split_at_rest": cut, "weights": d.resolved_weights(len(train)),
           "candidates": list(dspec.candidates), "diagnosis": res.as_dict()}
    atomic_write_json(path, to_jsonable(out))
    return out


def identify(spec: IdentifySpec, out_dir: str | Path, *, force: bool = False,
             progress: bool = False) -> IdentifyOutcome:
    """Run the identification workflow into ``out_dir`` (module docstring), resuming
    every stage already done there.

    Parameters
    ----------
    spec : IdentifySpec
    out_dir : str or path
        The workflow's folder (created): ``linear/``, ``diagnosis.json``, ``final/``,
        ``identify.json``, ``report.html``.
    force : bool
        Start every stage over (the folder's runs are deleted).  Without it, a stage whose
        inputs changed (another configuration, other diagnosis options, another model
        found) runs again and its old output is kept beside it as ``<name>.<hash>``.
    progress : bool
        One line per stage on stderr, and the stages' own progress.

    Returns
    -------
    IdentifyOutcome

    Raises
    ------
    ConfigError
        The linear configuration does not fit its data, or a stage's folder holds a run
        of another configuration (``force`` to start over).
    """
    folder = RunFolder(out_dir)
    folder.path.mkdir(parents=True, exist_ok=True)
    stage_s: dict[str, float] = {}
    if spec.linear.identify is not None:
        spec = replace(spec, linear=replace(spec.linear, identify=None))
    prep = prepare_run(spec.linear)
    # before the first posterior: the diagnosis must be able to work on this rig
    require_diagnosable(prep.model.rig, "identify (its diagnosis)")

    _say(progress, f"1/4 linear model posterior -> {folder.path / 'linear'}")
    if not force:
        _stale_run(folder.path / "linear", spec.linear, progress)
    t0 = time.perf_counter()
    linear = execute_run(prep, folder.path / "linear", resume=not force, force=force,
                         progress=progress)
    stage_s["linear"] = time.perf_counter() - t0 if linear.action != "none" else 0.0

    _say(progress, "2/4 diagnosis: what the linear model gets wrong")
    t0 = time.perf_counter()
    if force:
        (folder.path / "diagnosis.json").unlink(missing_ok=True)
    diag = _diagnose(spec, prep, folder, progress)
    stage_s["diagnosis"] = time.perf_counter() - t0

    effects = sampled_effects(diag["diagnosis"]["effects"])
    final = None
    if effects:
        cfg, prep_final = _final_prepared(spec, effects)
        _say(progress, f"3/4 the found model's posterior ({'+'.join(effects)}) -> "
             f"{folder.path / 'final'}")
        start = warm_start(prep.model.rig, effects, diag["diagnosis"])
        if not force:
            _stale_run(folder.path / "final", cfg, progress)
        t0 = time.perf_counter()
        final = execute_run(prep_final, folder.path / "final", resume=not force,
                            force=force, progress=progress, start=start)
        stage_s["final"] = time.perf_counter() - t0 if final.action != "none" else 0.0
    else:
        _say(progress, "3/4 no effect found: the linear model is the final model")
        _stale_run(folder.path / "final", None, progress)
        stage_s["final"] = 0.0

    _say(progress, "4/4 summary and report")
    t0 = time.perf_counter()
    summary = summarize(linear.summary, diag, None if final is None else final.summary,
                        effects)
    stage_s["summary"] = time.perf_counter() - t0
    summary["stage_s"] = stage_s
    atomic_write_json(folder.path / "identify.json", to_jsonable(summary))
    write_identify_report(folder.path, summary)
    return IdentifyOutcome(folder.path, summary, stage_s)
