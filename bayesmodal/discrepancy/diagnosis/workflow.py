"""``diagnose``: find what the linear simulation gets wrong, name the cause, measure the gain.

Steps (``posterior=False`` gives the same decision, only without the MCMC intervals):

1. fit the linear model (free damping) to the training experiment(s) by least squares;
2. calibrate the diagnostics on the null (``bayesmodal.discrepancy.diagnosis.null``): data simulated
   from the fitted linear model with its fitted AR(1) noise and the encoder quantisation,
   refitted and diagnosed like the data; the workflow statistic ``T`` (largest
   standardised diagnostic score) is compared with its null quantile, which keeps the
   false-positive rate of the whole workflow at ``alpha``;
3. no discrepancy: cause ``"none"``;
4. otherwise rank the candidate extensions by their signatures (the diagnostics that
   exceeded and suggest them), fit them by least squares
   (``bayesmodal.fit.fit_extension_lsq``) and score each by the drop of the
   AR(1)-whitened negative log-likelihood (noise profiled): likelihood-ratio statistic
   ``LR = 2 gain`` against ``chi2(k)`` at level ``alpha / n_candidates``, ranking key the
   BIC gain ``LR - k ln N``; with several training records a gain also counts when a
   z-test of the output error (which sees a level, autocorrelation-aware SE) finds it,
   each test at half the level (``scoring.Criterion``), and the leave-one-record-out
   gain must be significant too;
5. accept the best-scoring significant candidate whose residuals then pass its signature
   diagnostics and lower ``T``; report where it acts, its parameters, the fit percentages
   before and after (training and held-out experiments), the movement of the linear
   parameters and the change of a predictive criterion; with ``posterior=True`` sample
   the accepted model with emcee for credible intervals.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..._errors import ConfigError, DataError, ModelError
from ..._progress import announce, progress_bar
from ...data import Experiment
from ...fit._threads import fit_threads, thread_map
from ...fit.lsq import fit_lsq
from ...identified import require_identified
from ...inference.spec import RunDescription
from ...inference.threads import resolve_threads
from ...model.effects import EXTENSIONS, default_candidates
from ...model.simulate import simulate_linear
from ...model.system import LinearModel, Rig
from ...structure import check_structure
from ..checks import skipped_for
from ._result import CandidateScore, Diagnosis, Interval
from .candidates import REFINES
from .equivalence import equivalent_readings
from .final import FinalModel, final_model, first_of_several, fit_percents, outcomes
from .forward import RESIDUAL_BASED
from .gains import loro_gain
from .location import effect_location
from .null import (
    NullCalibration,
    calibrate_null,
    fit_noise,
    infer_quantum,
    run_diagnostics,
)
from .posterior import posterior_summary
from .scoring import ar1_pointwise, criterion_for, held_out_significant, laplace_sd
from .spec import DiagnoseSpec, with_diagnose_settings
from .starts import best_starts, linear_fit

__all__ = ["diagnose", "require_diagnosable", "DEFAULT_CANDIDATES"]

#: Candidate causes, in the catalogue's order (``Extension.default_candidate``).
DEFAULT_CANDIDATES = default_candidates()

def _train_indices(train, n: int) -> tuple[int, ...]:
    idx = (train,) if isinstance(train, (int, np.integer)) else tuple(train)
    if not idx:
        raise ConfigError("train must name at least one experiment")
    out = []
    for i in idx:
        if not isinstance(i, (int, np.integer)) or not (-n <= int(i) < n):
            raise ConfigError(f"train index {i!r} out of range for {n} experiment(s)")
        out.append(int(i) % n)
    if len(set(out)) != len(out):
        raise ConfigError(f"train indices repeat: {idx}")
    return tuple(out)


def require_diagnosable(rig: Rig, what: str = "diagnose") -> None:
    """Raise ModelError (one line with the fix) unless ``diagnose`` can work on ``rig``.

    Velocity and acceleration records (any sensors) are diagnosed in their own units,
    without the checks that read positions (``checks.diagnostics_for``); position
    records need a sensor on every moving cart, in cart order.

    Parameters
    ----------
    rig : Rig
    what : str
        Who asks, for the message.
    """
    if rig.positions_only and LinearModel(rig, "free").output_index is not None:
        # the checks of the measured motion read output j as the position of cart j
        raise ModelError(f"{what} needs a sensor on every moving cart, in cart order, on "
                         "position records; list the rig's [[sensors]] that way")


def _read_description(run, experiments, rig, train, rng):
    """The spec, rig and seed of a run description given to ``diagnose``."""
    if not isinstance(run, RunDescription):
        raise TypeError(f"spec must be a DiagnoseSpec or a run description (RunConfig), "
                        f"got {type(run).__name__}")
    n = 1 if isinstance(experiments, Experiment) else len(experiments)
    return (run.diagnose_spec(len(_train_indices(train, n))),
            run.make_rig() if rig is None else rig,
            run.diagnosis_seed if rng is None else rng)


def diagnose(
    experiments: Experiment | Sequence[Experiment],
    spec: DiagnoseSpec | RunDescription | None = None,
    *,
    rig: Rig | None = None,
    train: int | Sequence[int] = 0,
    rng=None,
    progress: bool = False,
    **settings,
) -> Diagnosis:
    """Diagnose the linear model's misfit, name the cause and measure the gain.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
        Measured (or simulated) experiments on the rig.
    spec : DiagnoseSpec, optional
        How the diagnosis searches (``bayesmodal.discrepancy.diagnosis.spec``): the
        candidates, the null calibration (``n_null``, ``alpha``), the fits (``n_starts``,
        ``max_nfev``, ``max_fits``, ``weights``), forward selection (``max_effects``,
        ``global_search``), the posterior (``posterior``, ``posterior_options``) and the
        encoder resolution (``quantum_m``).  Default ``DiagnoseSpec()``.  Or a run
        description (``bayesmodal.runs.RunConfig``): the diagnosis options of its
        ``[identify]`` table, its rig (where ``rig`` is not given) and that table's seed
        (where ``rng`` is not given).
    rig : Rig, optional
        Default ``Rig()`` (ECP 210 springs).
    train : int or sequence of int
        Index (or indices) of the experiments the models are fitted to; the others are
        held out and only predicted.
    rng : numpy.random.Generator or int, optional
        Seeds the null simulations and the sampler.
    progress : bool
        Progress lines on stderr: each stage as it starts, and progress over the null
        data sets, the candidate fits and the sampler steps (``bayesmodal._progress``).
    **settings
        Any field of ``DiagnoseSpec`` by name (``n_null=80``, ``posterior=False``),
        replacing the one of ``spec``; an unknown name is a ``TypeError``.

    Notes
    -----
    ``n_starts`` local fits per candidate start from the best points of a batched grid
    and the lowest training cost wins: the stick-slip and backlash costs have many local
    optima of nearly equal cost (on the measured impulses the best three friction starts
    end 6 % apart in cost and 3 points apart in their prediction of the held-out steps),
    so one start makes the reported gain depend on which basin the nearest start lies
    in.  ``weights="spread"`` weighs each training record as much as the others (with
    the plain sum of squares a point of fit on the ECP steps, held away from rest for
    seconds, weighs 4-5 times one on a pulse of the impulses); the linear fit, the start
    and the null's base stay unweighted, and the scores do not depend on it.  A
    saturation whose best start level is above every input is inactive and scored at
    that start without a fit.

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        No experiments, or experiments that do not match the rig.
    ConfigError
        Bad ``train`` or settings (``DiagnoseSpec`` checks its own when built).

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> if p:  # doctest: +SKIP
    ...     d = diagnose(load_experiment(p), posterior=False, rng=1)
    ...     d.cause
    'coulomb_friction'
    """
    if spec is not None and not isinstance(spec, DiagnoseSpec):
        spec, rig, rng = _read_description(spec, experiments, rig, train, rng)
    spec = with_diagnose_settings(spec, settings)
    with fit_threads(resolve_threads(spec.threads)):
        return _diagnosed(experiments, spec, rig, train, rng, progress)


def _diagnosed(experiments, spec: DiagnoseSpec, rig, train, rng, progress) -> Diagnosis:
    """``diagnose`` with its settings read (its steps, on the fits' threads)."""
    exps, rig = _checked_records(experiments, rig)
    tr = _train_indices(train, len(exps))
    held = tuple(i for i in range(len(exps)) if i not in tr)
    cands, skipped = _candidates(spec, rig)
    rng = np.random.default_rng(rng)
    train_exps = [exps[i] for i in tr]
    held_exps = [exps[i] for i in held]
    model = LinearModel(rig, "free")
    check_structure(model, train_exps)  # a layout no record identifies: before any fit
    q = infer_quantum(exps) if spec.quantum_m is None else float(spec.quantum_m)
    st = _null_stage(train_exps, held_exps, model, q, spec, rng, progress)
    signature = st.signature(cands)
    order = sorted(cands, key=lambda c: (-signature[c], cands.index(c)))
    gain = _gain_before(st, train_exps, held_exps)
    notes: list[str] = [skipped_for(model)] if skipped_for(model) else []
    if skipped:
        notes.append(f"left out (this rig cannot carry them): {', '.join(skipped)}")
    base = dict(
        statistic=st.t_max, threshold=st.cal.threshold, p_value=st.cal.p_value(st.t_max),
        tests=tuple(st.tests), experiments=tuple(e.name for e in exps), train=tr,
        n_null=st.cal.n_null, alpha=float(spec.alpha), rule=st.cal.rule,
        weights=spec.weights or "none")
    if not st.discrepancy:
        ranking = tuple(CandidateScore(
            name=c, signature=signature[c], fitted=False, gain_nll=np.nan,
            lr_statistic=np.nan, n_params=len(EXTENSIONS[c].specs(rig)), p_value=np.nan,
            score=np.nan, significant=False, passes=False, location=None, params={},
            message="not fitted: no discrepancy") for c in order)
        return Diagnosis(discrepancy=False, cause="none", location=None, location_label=None,
                         explained=True, tests_after=(), ranking=ranking, parameters={},
                         linear_parameters={}, gain=gain, interval_method="none",
                         notes=(*notes, "the diagnostics do not reject the linear model"),
                         detail={"calibration": st.cal, "linear": st.linear}, **base)
    scored, fits, after_tests = _fit_candidates(st, train_exps, rig, cands, order, signature,
                                                spec, progress)
    ranking = tuple(sorted(scored, key=lambda s: -s.score if np.isfinite(s.score) else np.inf))
    accepted = next((s for s in ranking if s.fitted and s.significant and s.passes), None)
    if accepted is not None:
        final = final_model(st, train_exps, rig, cands, accepted, fits, after_tests, spec,
                            rng, progress, notes)
    else:  # no single effect passes: forward selection from the most significant one
        accepted, final = first_of_several(st, train_exps, rig, cands, ranking, fits,
                                           after_tests, spec, rng, progress, notes)
    if accepted is None:
        notes.append("discrepancy found but no candidate extension is both significant and "
                     "passes its diagnostics")
        return Diagnosis(discrepancy=True, cause="none", location=None, location_label=None,
                         explained=False, tests_after=(), ranking=ranking, parameters={},
                         linear_parameters={}, gain=gain, interval_method="none",
                         notes=tuple(notes), detail={"calibration": st.cal,
                                                     "linear": st.linear, "fits": fits}, **base)
    notes.extend(equivalent_readings(final.effects, final.fit.params, rig,
                                     [e.v_volt for e in train_exps]))
    _gain_after(st, final, train_exps, held_exps, rig, gain, notes)
    parameters, method = _intervals(st, final, train_exps, held_exps, rig, spec, rng,
                                    progress, gain, notes)
    ef, causes = final.fit, final.causes
    linear = st.linear
    linear_parameters = {
        n: {"before": float(linear.theta[i]), "after": float(ef.theta[i]),
            "change_percent": float(100 * (ef.theta[i] - linear.theta[i])
                                    / abs(linear.theta[i])) if linear.theta[i] != 0
            else None}
        for i, n in enumerate(model.names)}
    return Diagnosis(
        discrepancy=True, cause=causes[0].cause if causes else accepted.name,
        location=causes[0].location if causes else accepted.location,
        location_label=causes[0].location_label if causes else final.label,
        explained=final.explained, tests_after=tuple(final.t_after), ranking=ranking,
        parameters=parameters, linear_parameters=linear_parameters, gain=gain,
        interval_method=method, notes=tuple(notes), causes=causes,
        effects=tuple(final.effects),
        detail={"calibration": st.cal, "linear": linear, "fits": fits, "extension_fit": ef,
                "forward": final.forward},
        **base)


def _checked_records(experiments, rig: Rig | None) -> tuple[list[Experiment], Rig]:
    """The records as a list and the rig, checked against each other."""
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    if not exps:
        raise DataError("no experiments given")
    rig = Rig() if rig is None else rig
    require_diagnosable(rig)
    for e in exps:
        if not isinstance(e, Experiment):
            raise DataError(f"expected Experiment objects, got {type(e).__name__}")
        rig.check_record(e)
    return exps, rig


def _candidates(spec: DiagnoseSpec, rig: Rig) -> tuple[tuple[str, ...], list[str]]:
    """The candidate effects this rig can carry, and those of the default catalogue it
    cannot (an effect asked for by name that the rig cannot carry is refused)."""
    cands = DEFAULT_CANDIDATES if spec.candidates is None else spec.candidates
    # effects this rig cannot carry (e.g. backlash where the motor drives two carts):
    # refused when asked for by name, left out of the default catalogue with a note
    why = {c: EXTENSIONS[c].unsupported(rig) for c in cands}
    if spec.candidates is not None and any(why.values()):
        raise ConfigError(next(w for w in why.values() if w))
    return tuple(c for c in cands if not why[c]), [c for c in cands if why[c]]


@dataclass(frozen=True)
class _NullStage:
    """The linear fit, its null calibration and the data's diagnostics (steps 1-2)."""

    linear: object
    y_lin: list
    cal: NullCalibration
    tests: list
    t_max: float
    crit: object
    shapes: list
    lin_pointwise: np.ndarray
    held_lin: list
    q: float
    model: LinearModel

    @property
    def discrepancy(self) -> bool:
        return bool(self.t_max > self.cal.threshold)

    def signature(self, cands) -> dict[str, float]:
        """Each candidate's signature: the scores of the diagnostics that suggest it."""
        out = {c: 0.0 for c in cands}
        for t in self.tests:
            for c in t.suggests:
                if c in out:
                    out[c] += max(t.z, 0.0)
        return out


def _null_stage(train_exps, held_exps, model, q, spec, rng, progress) -> _NullStage:
    """Fit the linear model, calibrate the diagnostics on its null, diagnose the data."""
    # the optimisers probe wild parameter values on the way (overflowing exponentials of
    # unstable trial systems); those trials are rejected, so the warnings are noise
    announce("diagnose: least-squares fit of the linear model", enabled=progress)
    with np.errstate(all="ignore"):
        linear = linear_fit(train_exps, model)
    require_identified(linear, train_exps, "the diagnosis")
    y_lin = [simulate_linear(model, linear.theta, e.v_volt, e.dt) for e in train_exps]
    noise = fit_noise([e.y_m - y for e, y in zip(train_exps, y_lin, strict=True)], q)
    cal = calibrate_null(train_exps, model, linear.theta, noise=noise, n_null=spec.n_null,
                         alpha=spec.alpha, rng=rng, progress=progress)
    diags = [run_diagnostics(e, model, linear.theta, quantum_m=q) for e in train_exps]
    tests, t_max = outcomes(cal, train_exps, diags)
    # one record: the AR(1) log density; several: it or the output error (sees a level)
    crit = criterion_for(train_exps)
    return _NullStage(
        linear=linear, y_lin=y_lin, cal=cal, tests=tests, t_max=t_max, crit=crit,
        shapes=[(e.n_samples, e.n_outputs) for e in train_exps],
        lin_pointwise=crit.pointwise([e.y_m - y for e, y in zip(train_exps, y_lin,
                                                                 strict=True)]),
        held_lin=[simulate_linear(model, linear.theta, e.v_volt, e.dt) for e in held_exps],
        q=q, model=model)


def _gain_before(st: _NullStage, train_exps, held_exps) -> dict:
    """The gain record before any extension: the linear model's fit percents."""
    fp_before = fit_percents(train_exps, st.y_lin)
    gain: dict = {"fit_percent_before": fp_before, "fit_percent_after": fp_before,
                  "experiments": [e.name for e in train_exps]}
    if held_exps:
        hb = fit_percents(held_exps, st.held_lin)
        gain.update(heldout_experiments=[e.name for e in held_exps],
                    heldout_fit_percent_before=hb, heldout_fit_percent_after=hb)
    gain.update(delta_elpd=None, delta_elpd_se=None, criterion=None)
    return gain


def _fit_candidates(st: _NullStage, train_exps, rig, cands, order, signature, spec,
                    progress):
    """Fit each candidate (the strongest signatures first), score it against the linear
    model and judge its residuals (step 4): the scores, and each fit with its residual
    tests."""
    model, linear, cal, crit = st.model, st.linear, st.cal, st.crit
    to_fit = order if spec.max_fits is None else order[: max(int(spec.max_fits), 1)]
    level = spec.alpha / len(cands)
    scored: list[CandidateScore] = []
    fits = {}
    after_tests = {}
    linear_refits: dict = {}  # the linear model's fold refits, shared by the candidates
    peak_volt = max(float(np.max(np.abs(e.v_volt))) for e in train_exps)
    bar = progress_bar(len(to_fit), desc="diagnose: candidate extensions", unit="fit",
                       enabled=progress)
    for c in order:
        ext = EXTENSIONS[c]
        k = len(ext.specs(rig))
        if c not in to_fit:
            scored.append(CandidateScore(c, signature[c], False, np.nan, np.nan, k, np.nan,
                                         -np.inf, False, False, None, {},
                                         "not fitted: weak signature"))
            continue
        if REFINES.get(c) in cands and spec.max_effects > 1:
            # a refinement (more parameters on the same element) enters by forward
            # selection, tested against the effect it refines
            scored.append(CandidateScore(c, signature[c], False, np.nan, np.nan, k, np.nan,
                                         -np.inf, False, False, None, {},
                                         f"not fitted at the first step: refines "
                                         f"{REFINES[c]} (forward selection tests it)"))
            continue
        bar.set_postfix_str(c)
        bar.update(1)
        try:
            with np.errstate(all="ignore"):
                def fit(theta0, ext=ext, c=c):
                    inactive = c == "input_saturation" and theta0[-1] >= peak_volt
                    return fit_lsq(train_exps, rig, extension=ext, theta0=theta0,
                                   linear=linear, max_nfev=1 if inactive else spec.max_nfev,
                                   weights=spec.weights)

                ef = None
                # the starts side by side on the fits' threads, the same fits as in turn
                for f in thread_map(fit, best_starts(ext, rig, linear.theta, train_exps,
                                                     spec.n_starts, spec.weights)):
                    if ef is None or f.cost < ef.cost:
                        ef = f
        except (ModelError, DataError, ValueError, FloatingPointError,
                np.linalg.LinAlgError) as exc:
            scored.append(CandidateScore(c, signature[c], False, np.nan, np.nan, k, np.nan,
                                         -np.inf, False, False, None, {},
                                         f"fit failed: {str(exc).splitlines()[0]}"))
            continue
        y_ext = [ext.simulate(rig, ef.theta, e.v_volt, e.dt) for e in train_exps]
        pw = crit.pointwise([e.y_m - y for e, y in zip(train_exps, y_ext, strict=True)])
        g, lr, p, score, sig = crit.test(pw, st.lin_pointwise, k, st.shapes, level)
        held_out = None
        if sig and len(train_exps) >= 2:
            # several records: the leave-one-record-out gain must be significant too
            held_out = loro_gain(train_exps, rig, None, linear.theta, ext, ef.theta, linear,
                                 weights=spec.weights, cache=linear_refits)
            sig = held_out_significant(held_out, level)
        lin_theta = ef.theta[: model.n_params]
        d_after = [run_diagnostics(e, model, lin_theta, quantum_m=st.q, y_pred=y)
                   for e, y in zip(train_exps, y_ext, strict=True)]
        t_after, tmax_after = outcomes(cal, train_exps, d_after)
        # only the diagnostics of the residual can pass or fail a model; the others
        # (free-decay envelope, amplitude dependence, stick) look at the measured motion
        # itself, which no model changes
        t_after = [t for t in t_after if t.name in RESIDUAL_BASED]
        tmax_after = max((t.z for t in t_after), default=-np.inf)
        sig_tests = {t.name for t in st.tests if c in t.suggests} & set(RESIDUAL_BASED)
        # pass: no residual diagnostic beyond its threshold, or (misfit beyond the
        # catalogue remaining) the workflow statistic falls and every residual diagnostic
        # that pointed at this cause falls too
        z_before = {t.name: t.z for t in st.tests}
        z_after = {t.name: t.z for t in t_after}
        clean = bool(tmax_after <= cal.threshold)
        passes = bool(clean or (tmax_after < st.t_max
                                and all(z_after[n] < z_before[n] for n in sig_tests)))
        loc, label = effect_location(ext, rig, ef.theta)
        ext_params = dict(zip(ext.extension_names(rig),
                              ef.theta[model.n_params:].tolist(), strict=True))
        fits[c] = (ef, y_ext, pw, tmax_after, label, held_out)
        after_tests[c] = t_after
        scored.append(CandidateScore(
            c, signature[c], True, g, lr, k, p, float(score), sig, passes, loc, ext_params,
            f"T after {tmax_after:.1f} (before {st.t_max:.1f}, threshold {cal.threshold:.1f})"
            + ("; residuals pass every diagnostic" if clean else "")))
    bar.close()
    return scored, fits, after_tests


def _gain_after(st: _NullStage, final: FinalModel, train_exps, held_exps, rig, gain: dict,
                notes: list) -> None:
    """Fill in the final model's fit percents and plug-in ELPD change (training and
    held-out records)."""
    ext, ef = final.ext, final.fit
    gain["model"] = "+".join(final.effects)
    gain["fit_percent_after"] = fit_percents(train_exps, final.y_ext)
    held_ext = [ext.simulate(rig, ef.theta, e.v_volt, e.dt) for e in held_exps]
    if held_exps:
        gain["heldout_fit_percent_after"] = fit_percents(held_exps, held_ext)
    # plug-in ELPD (lpd minus parameter count) with the SE of pointwise differences
    d = final.pointwise - st.lin_pointwise
    gain.update(delta_elpd=st.crit.total(d) - len(ext.specs(rig)),
                delta_elpd_se=st.crit.se(d, st.shapes),
                criterion="plug-in ELPD (AR(1) lpd at the least-squares fits minus the "
                          "number of extra parameters); SE from the pointwise differences")
    if held_exps:
        hd = ar1_pointwise([e.y_m - y for e, y in zip(held_exps, held_ext, strict=True)]) - \
            ar1_pointwise([e.y_m - y for e, y in zip(held_exps, st.held_lin, strict=True)])
        gain.update(heldout_delta_lpd=float(hd.sum()),
                    heldout_delta_lpd_se=float(np.sqrt(hd.size * np.var(hd))))


def _intervals(st: _NullStage, final: FinalModel, train_exps, held_exps, rig, spec, rng,
               progress, gain: dict, notes: list) -> tuple[dict, str]:
    """The final model's parameter intervals: its posterior (``spec.posterior``) or a
    Laplace approximation at the least-squares optimum; the posterior's ELPD change
    replaces the plug-in one in ``gain``."""
    ext, ef, model = final.ext, final.fit, st.model
    if spec.posterior:
        post = posterior_summary(exps=train_exps, ext=ext, rig=rig, fit=ef,
                                 linear=st.linear, rng=rng,
                                 options=spec.posterior_options or {}, heldout=held_exps,
                                 progress=progress)
        for key in ("delta_elpd", "delta_elpd_se", "criterion"):
            if post.get(key) is not None:
                gain[key] = post[key]
        gain["elpd_change"] = post.get("elpd")
        gain["posterior"] = post["fits"]
        notes.extend(post.get("notes", ()))
        # intervals of chains that did not converge are not a posterior summary
        return (post["parameters"],
                "posterior" if post["converged"] else "posterior_unconverged")
    sd = laplace_sd(ext, rig, ef.theta, train_exps)
    zq = stats.norm.ppf(0.95)
    # parameters whose prior range is non-negative keep the interval there (a Laplace
    # interval at a non-smooth optimum, e.g. Fs at Fc, can be very wide)
    specs = ext.specs(rig)
    parameters = {}
    for i, n in enumerate(ext.names(rig)):
        if i < model.n_params:
            continue
        lo = float(ef.theta[i] - zq * sd[i])
        if specs[i - model.n_params].bounds[0] >= 0:
            lo = max(lo, 0.0)
        parameters[n] = Interval(float(ef.theta[i]), lo, float(ef.theta[i] + zq * sd[i]))
    return parameters, "laplace"
