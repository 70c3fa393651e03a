"""Leave-one-record-out validation: sample on the other records, predict the one left out.

A credible interval is only as good as its check on data it was not fitted to.  For each
record ``r`` of a set, the posterior is sampled on the other records (same model, noise
model and per-record layout), and record ``r`` is predicted as a new record
(``bayesmodal.inference.predictive``): fit percent of the predictive median, coverage of
the 50 % and 90 % bands, band width relative to the record's spread, CRPS and the log
predictive density.  The sum of the held-out log predictive densities, with its standard
error over records (``sqrt(R) * sd(lpd_r)``, as for PSIS-LOO's pointwise terms), is the
criterion that answers "which model predicts the next experiment".

The folds (and the joint run on all records, for the per-record estimates next to the
joint posterior) are independent: they run in parallel on local processes, or as tasks of
a Dask cluster (``scheduler``), as ``bayesmodal batch`` does.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field

import numpy as np

from .._blas import blas_share, limit_blas
from .._errors import ConfigError, DataError
from ..data import Experiment
from ..fit.lsq import fit_lsq
from ..model.effects import get_extension
from ..model.rigs import rig_to_dict
from ..model.system import LinearModel, Rig
from .coverage_reference import calibration_summary
from .likelihood import Likelihood
from .moves import parse_moves
from .noise_choice import choose_noise
from .noise_spec import parse_noise
from .predictive import PredictiveScores, new_record_parameters, predict_new_record, score_samples
from .propagate import propagate_modes
from .record_layout import DEFAULT_LAYOUT, RecordLayout
from .record_priors import record_priors
from .sampling import sample_posterior
from .spec import LikelihoodSpec, RunDescription, SamplerSpec, burn_in_steps

__all__ = ["CrossvalSpec", "FoldResult", "CrossvalResult", "crossval", "run_fold"]


@dataclass(frozen=True)
class CrossvalSpec:
    """Everything that defines a leave-one-record-out study (one object, no long kwargs).

    Parameters
    ----------
    damping : {"free", "proportional"}
    noise : {"ar1", "white"}
    extension : str, optional
        A model extension name.
    layout : RecordLayout
        Per-record parameters (default :data:`~.records.DEFAULT_LAYOUT`).
    n_walkers, n_steps, burn : int
        Ensemble size (raised to twice the number of parameters of a fold if smaller),
        steps per walker, burn-in (default ``n_steps // 2``).
    n_predictive : int
        Posterior draws used to predict each held-out record.
    seed : int
    temperature : float
        Likelihood tempering ``L^(1/T)`` (1: the plain posterior).
    springs_n_m : tuple of float, optional
        The rig's springs (default: the ECP 210's).
    rig : Rig, optional
        A rig description (``bayesmodal.model.rigs``); overrides ``springs_n_m``.
    init : {"ball", "laplace"}
        How each fold's walkers start (``sample_posterior(init=...)``).
    moves : str
        emcee moves of each fold, a ``[sampler] moves`` string such as
        ``"de:0.8,de-jump:0.2"`` (default ``"de"``).
    prune, restart : int, optional
        Burn-in step at which stranded walkers join the others (``prune``) or every walker
        restarts around the best one (``restart``), as in ``sample_posterior``; each in
        ``[1, burn)``, at most one of them.
    """

    damping: str = "free"
    noise: str = "ar1"
    extension: str | None = None
    layout: RecordLayout = DEFAULT_LAYOUT
    n_walkers: int = 48
    n_steps: int = 4000
    burn: int | None = None
    n_predictive: int = 200
    seed: int = 1
    temperature: float = 1.0
    springs_n_m: tuple[float, ...] | None = None
    rig: object = None
    init: str = "ball"
    moves: str = "de"
    prune: int | None = None
    restart: int | None = None

    def __post_init__(self) -> None:

        # one-line errors here, not in each fold: the moves, and the burn-in step
        parse_moves(self.moves)
        burn_in_steps(self.restart, self.prune,
                      self.n_steps // 2 if self.burn is None else self.burn)
        if self.n_predictive < 2:
            raise ConfigError(f"n_predictive must be >= 2 draws, got {self.n_predictive}")
        if not (np.isfinite(self.temperature) and self.temperature > 0):
            raise ConfigError(f"temperature must be finite and > 0, got {self.temperature}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["layout"] = self.layout.to_dict()
        if self.rig is not None:
            d["rig"] = rig_to_dict(self.rig)
        return d


@dataclass(frozen=True)
class FoldResult:
    """One fold: the posterior on the training records and the held-out scores.

    ``scores`` is None for the joint run on all records.  ``estimates`` holds posterior
    medians and 90 % intervals of ``g_v`` (the held-out record's population draw or the
    record's own value), ``omega_rad_s`` and ``zeta``.
    """

    heldout: str | None
    training: tuple[str, ...]
    scores: PredictiveScores | None
    estimates: dict
    max_rhat: float
    min_ess: float
    converged: bool
    elapsed_s: float
    evaluations_per_s: float
    band: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in ("heldout", "training", "estimates", "max_rhat",
                                            "min_ess", "converged", "elapsed_s",
                                            "evaluations_per_s")}
        d["training"] = list(self.training)
        if self.scores is not None:
            d.update(self.scores.to_dict())
        return d


@dataclass(frozen=True)
class CrossvalResult:
    """A leave-one-record-out study.

    Attributes
    ----------
    spec : CrossvalSpec
    folds : tuple of FoldResult
        One per held-out record, in the records' order.
    joint : FoldResult or None
        The posterior on all records.
    own : dict
        Each record's own least-squares estimates (``g_v``, ``omega_rad_s``, ``zeta``).
    total_lpd, total_lpd_se : float
        Summed held-out log predictive density and its standard error over records.
    wall_time_s : float
    """

    spec: CrossvalSpec
    folds: tuple[FoldResult, ...]
    joint: FoldResult | None
    own: dict
    total_lpd: float
    total_lpd_se: float
    wall_time_s: float

    @property
    def calibration(self) -> dict | None:
        """Are the held-out coverages what calibrated bands would show?
        (:func:`~.coverage_reference.calibration_summary` over the folds; None when a
        fold has no coverage reference.)"""
        refs = [f.scores.reference for f in self.folds]
        if any(r is None for r in refs):
            return None
        pairs = list(zip(refs, self.folds, strict=True))
        return calibration_summary(
            [r.record_pit(f.scores.coverage_90) for r, f in pairs],
            window_probabilities=[r.window_probability() for r in refs],
            band_factor_pits=[r.record_band_factor_pit(f.scores.band_factor_90)
                              for r, f in pairs])

    def to_dict(self) -> dict:
        total = {"lpd": self.total_lpd, "lpd_se": self.total_lpd_se,
                 "n_records": len(self.folds)}
        if self.calibration is not None:
            total["calibration"] = self.calibration
        return {"spec": self.spec.to_dict(),
                "records": [f.to_dict() for f in self.folds],
                "joint": None if self.joint is None else self.joint.to_dict(),
                "own_lsq": self.own,
                "total": total,
                "wall_time_s": self.wall_time_s}

    def table(self) -> str:
        """Plain-text table: one row per held-out record and output."""
        rows = ["record                   cart  fit %   cov50  cov90  (calibrated)  width90  "
                "x90   (calibrated)  crps    lpd"]
        for f in self.folds:
            s = f.scores
            ref = s.reference
            for j in range(s.fit_percent.size):
                lpd = f"{s.lpd:.0f} +- {s.lpd_se:.1f}" if j == 0 else ""
                cr = xr = " " * 11
                if ref is not None:
                    c, x = ref.interval(0.9)[j], ref.band_factor_interval()[j]
                    cr, xr = f"{c[0]:4.2f}-{c[1]:4.2f}", f"{x[0]:4.2f}-{x[1]:4.2f}"
                rows.append(f"{s.name[:24]:<24} {j + 1:>4}  {s.fit_percent[j]:5.1f}  "
                            f"{s.coverage_50[j]:5.2f}  {s.coverage_90[j]:5.2f}  "
                            f"({cr:>9})  {s.width_90[j]:6.2f}  {s.band_factor_90[j]:5.2f} "
                            f"({xr:>9})  {s.crps[j]:5.3f}  {lpd}")
        rows.append(f"total held-out lpd: {self.total_lpd:.0f} +- {self.total_lpd_se:.0f} nats "
                    f"over {len(self.folds)} records")
        rows.append("x90: the factor on the 90 % band's half-widths that would cover 90 % "
                    "of the record (1 = calibrated, > 1 too narrow)")
        cal = self.calibration
        if cal is not None:
            rows.append("(calibrated): the central 90 % of what a calibrated band shows on "
                        "such a record (the predictive draws scored against the others)")
            rows.append(f"records whose coverage is outside that range: {cal['n_outside']} "
                        f"of {cal['n_records']} (below {cal['n_below']}, above "
                        f"{cal['n_above']}; p = {cal['p_value']:.2f} if calibrated); "
                        f"whose x90 is: {cal['n_band_factor_above']} above (misses further "
                        f"out), {cal['n_band_factor_below']} below")
            rows.append("calibrated bands would meet a fixed 80-95 % window on every "
                        f"record and cart with probability {cal['window_probability_all']:.3f}")
        return "\n".join(rows)


def _model(spec: CrossvalSpec):
    if spec.rig is not None:
        return LinearModel(spec.rig, spec.damping)
    rig = Rig() if spec.springs_n_m is None else Rig(tuple(spec.springs_n_m))
    return LinearModel(rig, spec.damping)


def _interval(x: np.ndarray) -> dict:
    """Median and 90 % equal-tailed interval along the first axis, as lists."""
    lo, med, hi = np.quantile(x, [0.05, 0.5, 0.95], axis=0)
    return {"median": np.atleast_1d(med).tolist(), "lo": np.atleast_1d(lo).tolist(),
            "hi": np.atleast_1d(hi).tolist()}


def _estimates(lik, draws: np.ndarray, *, new_record: bool, rng) -> dict:
    """Posterior g_v, omega and zeta (at the population centre, or drawn for a new
    record): medians and 90 % intervals."""

    # a new record's parameters: every hierarchical one drawn from its population, so
    # that with per-record masses or dampers the interval is the next experiment's
    mech = new_record_parameters(lik, draws, rng)[0] if new_record else lik.split(draws)[0]
    ms = propagate_modes(lik.model, mech[:, : lik.model.n_params], methods=("eig",))
    return {"g_v": _interval(mech[:, 0]), "omega_rad_s": _interval(ms.omega_rad_s),
            "zeta": _interval(ms.zeta)}


def run_fold(spec: CrossvalSpec, experiments: Sequence[Experiment], heldout: int | None,
             progress: bool = False) -> FoldResult:
    """Sample on all records but ``heldout`` and score the held-out record.

    With ``heldout=None`` the posterior is sampled on all records (the joint run); its
    ``estimates`` then hold each record's ``g_v`` under keys ``g_v[name]``.
    """

    exps = list(experiments)
    train = [e for i, e in enumerate(exps) if i != heldout]
    model = _model(spec)
    seed = spec.seed + (0 if heldout is None else 1000 * (heldout + 1))
    noise = spec.noise
    if isinstance(noise, str) and parse_noise(noise).kind == "ar:auto":  # from training only
        noise = choose_noise(train, model, fit_lsq(train, model))
    lik = Likelihood(model, tuple(train), noise, spec.extension, spec.layout)
    priors = record_priors(lik)
    burn = spec.n_steps // 2 if spec.burn is None else spec.burn
    # at least two walkers per parameter (emcee's requirement), even
    walkers = max(spec.n_walkers, 2 * len(lik.names))
    # the noise as given (a name, or the AR orders chosen above): ProcessNoise is not a
    # NoiseModel instance that sample_posterior could take back
    run = sample_posterior(
        train, model,
        LikelihoodSpec(noise=noise, extension=spec.extension, layout=spec.layout,
                       temperature=spec.temperature),
        SamplerSpec(n_walkers=walkers, n_steps=spec.n_steps, burn=burn,
                    moves=parse_moves(spec.moves), init=spec.init, prune=spec.prune,
                    restart=spec.restart, progress=progress, warn=False),
        priors=priors, rng=seed)
    rng = np.random.default_rng(seed + 7)
    flat = run.flat_draws
    take = rng.choice(flat.shape[0], size=min(spec.n_predictive, flat.shape[0]),
                      replace=False)
    draws = flat[take]
    d = run.diagnostics
    common = dict(max_rhat=float(d.max_rhat), min_ess=float(d.min_ess),
                  converged=bool(d.converged), elapsed_s=float(run.elapsed_s),
                  evaluations_per_s=float(run.evaluations_per_s))
    if heldout is None:
        est = _estimates(run.likelihood, draws, new_record=False, rng=rng)
        for k in getattr(run.likelihood, "record_keys", ()):
            if f"g_v[{k}]" in run.names:
                est[f"g_v[{k}]"] = _interval(draws[:, run.names.index(f"g_v[{k}]")])
        return FoldResult(None, tuple(e.name for e in train), None, est, **common)
    target = exps[heldout]
    y_hat, y_pred, ll = predict_new_record(run.likelihood, draws, target, rng=rng)
    scores = score_samples(target.name, target.y_m, y_pred, ll)
    q = np.quantile(y_pred, [0.05, 0.5, 0.95], axis=0)
    band = {"t_s": target.t_s, "y": target.y_m, "q05": q[0], "q50": q[1], "q95": q[2]}
    est = _estimates(run.likelihood, draws, new_record=True, rng=rng)
    return FoldResult(target.name, tuple(e.name for e in train), scores, est, band=band,
                      **common)


def _own_lsq(spec: CrossvalSpec, exps: Sequence[Experiment]) -> dict:
    """Each record's own least-squares estimates of g_v, omega and zeta, by the model the
    study samples (with its extension: a linear fit's damping ratios carry what the
    extension explains, e.g. dry friction read as viscous damping)."""

    model = _model(spec)
    ext = None if spec.extension is None else get_extension(spec.extension)
    out = {}
    for e in exps:
        fit = fit_lsq([e], model)
        theta, fp = fit.theta, fit.fit_percent
        if ext is not None:
            xfit = fit_lsq([e], model.rig, extension=ext, linear=fit,
                           damper_scales=(1.0, 0.3))
            theta, fp = xfit.theta[: model.n_params], xfit.fit_percent
        ms = propagate_modes(model, theta[None], methods=("eig",))
        out[e.name] = {"g_v": float(theta[0]),
                       "omega_rad_s": ms.omega_rad_s[0].tolist(), "zeta": ms.zeta[0].tolist(),
                       "fit_percent": np.asarray(fp).ravel().tolist()}
    return out


def _call(args):
    spec, exps, heldout = args
    return run_fold(spec, exps, heldout)


def crossval(experiments: Sequence[Experiment],
             spec: CrossvalSpec | RunDescription | None = None, *,
             workers: int | None = None, scheduler: str | None = None, joint: bool = True,
             progress=None) -> CrossvalResult:
    """Leave-one-record-out validation of a model on several records.

    Parameters
    ----------
    experiments : sequence of Experiment
        At least two records with distinct names.
    spec : CrossvalSpec or RunDescription, optional
        Model, noise, per-record layout and sampler settings, or a run description
        (``bayesmodal.runs.RunConfig``: its ``crossval_spec()``, the model, noise, layout
        and sampler of the run with the ``[crossval]`` walkers, steps and draws).
    workers : int, optional
        Local processes (default: the number of CPUs, at most the number of folds).
    scheduler : str, optional
        Address of a Dask distributed scheduler; the folds become its tasks.
    joint : bool
        Also sample all records together (for the per-record estimates).
    progress : callable, optional
        Called with a line of text when a fold finishes.

    Returns
    -------
    CrossvalResult

    Examples
    --------
    >>> # res = crossval([imp, steps, fast, slow], CrossvalSpec(n_steps=3000), workers=2)
    >>> # print(res.table())
    """
    if spec is None:
        spec = CrossvalSpec()
    elif not isinstance(spec, CrossvalSpec):
        if not isinstance(spec, RunDescription):
            raise TypeError(f"spec must be a CrossvalSpec or a run description (RunConfig), "
                            f"got {type(spec).__name__}")
        spec = spec.crossval_spec()
    exps = list(experiments)
    if len(exps) < 2:
        raise DataError(f"leave-one-record-out needs at least 2 records, got {len(exps)}; "
                        "give more DATA files")
    names = [e.name for e in exps]
    if len(set(names)) != len(names):
        raise DataError(f"record names must be distinct, got {names}")
    t0 = time.perf_counter()
    tasks = [(spec, exps, i) for i in range(len(exps))] + ([(spec, exps, None)] if joint else [])
    results = _map(tasks, workers, scheduler, progress)
    folds = tuple(results[: len(exps)])
    lpd = np.array([f.scores.lpd for f in folds])
    total = float(np.sum(lpd))
    se = float(np.sqrt(len(lpd)) * np.std(lpd, ddof=1)) if len(lpd) > 1 else float("nan")
    return CrossvalResult(spec, folds, results[len(exps)] if joint else None,
                          _own_lsq(spec, exps), total, se, time.perf_counter() - t0)


def _map(tasks, workers, scheduler, progress) -> list:
    say = progress or (lambda line: None)
    out = [None] * len(tasks)

    def label(i):
        h = tasks[i][2]
        return "joint (all records)" if h is None else f"held out {tasks[i][1][h].name}"

    if scheduler:
        try:
            from distributed import Client
        except ImportError as exc:
            raise ConfigError("--scheduler needs dask[distributed]: pip install "
                              "'bayesmodal[dask]'") from exc
        with Client(scheduler, set_as_default=False) as client:
            futs = [client.submit(_call, t, pure=False) for t in tasks]
            for i, f in enumerate(futs):
                out[i] = f.result()
                say(f"fold {label(i)} done")
        return out
    n = workers or os.cpu_count() or 1
    n = max(1, min(int(n), len(tasks)))
    if n == 1:
        for i, t in enumerate(tasks):
            out[i] = _call(t)
            say(f"fold {label(i)} done ({i + 1}/{len(tasks)})")
        return out
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=limit_blas,
                             initargs=(blas_share(n),)) as pool:
        futs = {pool.submit(_call, t): i for i, t in enumerate(tasks)}
        from concurrent.futures import as_completed

        for k, fut in enumerate(as_completed(futs)):
            i = futs[fut]
            out[i] = fut.result()
            say(f"fold {label(i)} done ({k + 1}/{len(tasks)})")
    return out
