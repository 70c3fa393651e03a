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

import numpy as np
from scipy import stats

from ..._errors import ConfigError, DataError, ModelError
from ..._progress import announce, progress_bar
from ...data import Experiment
from ...fit.effects import WEIGHTINGS, fit_extension_lsq
from ...fit.linear import fit_lsq
from ...identified import require_identified
from ...metrics import fit_percent
from ...model.effects import EXTENSIONS, Extension, default_candidates, get_extension
from ...model.effects._base import cart_numbers
from ...model.effects._linear import kernel_order
from ...model.simulate import simulate_linear
from ...model.system import LinearModel, Rig
from ...structure import check_structure
from ._result import CandidateScore, Diagnosis, Interval, TestOutcome
from .forward import REFINES, RESIDUAL_BASED, Cause, forward_select, loro_gain
from .null import (
    NullCalibration,
    calibrate_null,
    diagnostic_statistics,
    fit_noise,
    infer_quantum,
    run_diagnostics,
)
from .posterior import posterior_summary
from .scoring import ar1_pointwise, criterion_for, held_out_significant, laplace_sd
from .starts import best_starts

__all__ = ["diagnose", "require_diagnosable", "DEFAULT_CANDIDATES"]

#: Candidate causes, in the catalogue's order (``Extension.default_candidate``).
DEFAULT_CANDIDATES = default_candidates()

#: Elements whose strength is at least this fraction of the strongest are reported too.
LOCATION_FRACTION = 0.25


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


def _outcomes(cal: NullCalibration, exps, diags_per_exp) -> tuple[list[TestOutcome], float]:
    stats_ = [diagnostic_statistics(d) for d in diags_per_exp]
    z = cal.scores(stats_)
    out = []
    for j, (name, i) in enumerate(cal.keys):
        d = diags_per_exp[i][name]
        exceeded = bool(z[j] > cal.threshold)
        out.append(TestOutcome(
            name=name, experiment=exps[i].name, statistic=float(d.statistic),
            threshold=cal.statistic_threshold(j), z=float(z[j]), exceeded=exceeded,
            suggests=tuple(d.suggests) if exceeded else (), location=d.location,
            summary=d.summary))
    t_max = float(np.max(z)) if z.size else -np.inf
    return out, t_max


def _location(ext: Extension, rig: Rig, theta) -> tuple[list[int] | None, str | None]:
    """The carts (by number), springs (by their place in ``rig.springs``) or sensors (by
    their place in ``rig.sensors``), 1-based, where the effect acts, and a label."""
    loc = ext.location_of(rig, theta)
    if loc.kind == "input" or loc.index is None:
        return None, loc.label
    order = kernel_order(rig)
    if loc.kind == "sensor":
        def number(i):
            return i + 1
    elif loc.kind == "spring":
        def number(i):
            return order.spring_index[i] + 1
    else:
        def number(i):
            return cart_numbers(rig)[i]
    if loc.kind == "drive":
        return [number(loc.index)], loc.label
    s = np.abs(np.asarray(loc.strength, float))
    if ext.name == "cubic_stiffness":
        s = s / np.asarray(rig.springs_n_m, float)[list(order.spring_index)]
    elif ext.name == "coulomb_friction":
        # the kinetic level acts whenever a cart slides and is well identified; a static
        # level on a cart without kinetic friction only matters while it sticks and can
        # take almost any value
        fc = np.asarray(ext.split(rig, np.asarray(theta, float))[1][: rig.n_carts])
        if fc.max() > 0:
            s = fc
    elif ext.name == "coulomb_directional":
        w = np.asarray(ext.split(rig, np.asarray(theta, float))[1])
        n = rig.n_carts
        fc = np.maximum(w[:n], w[n : 2 * n])
        if fc.max() > 0:
            s = fc
    idx = [number(int(i)) for i in np.flatnonzero(s >= LOCATION_FRACTION * s.max())] \
        if s.max() > 0 else [number(loc.index)]
    if len(idx) == 1 and idx[0] != number(loc.index):
        return idx, f"{loc.kind} {idx[0]}"
    kind = "carts" if loc.kind == "cart" else "springs"
    label = loc.label if len(idx) == 1 else f"{kind} {', '.join(map(str, idx))}"
    return idx, label


def _final_causes(causes, fwd, rig, model) -> tuple:
    """The causes found, restricted to the final model's effects: a refinement replaced by
    what it refines takes the simpler name, a removed effect is dropped, and every cause
    takes its parameters and location from the final fit (the first step's fit lacked the
    later effects: measured on a pair case, friction spread over two carts there that the
    final model puts on one).  Order: as found; gains: as measured when found."""
    p = model.n_params
    ext = get_extension(list(fwd.names))
    own = dict(zip(ext.extension_names(rig), fwd.fit.theta[p:], strict=True))
    out, seen = [], set()
    for c in causes:
        name = c.cause
        for eff, simpler in fwd.simplified:
            if name == eff and simpler is not None and simpler in fwd.names:
                name = simpler
        if name not in fwd.names or name in seen:
            continue
        seen.add(name)
        s_ext = EXTENSIONS[name]
        par = {n: float(own[n]) for n in s_ext.extension_names(rig)}
        loc, lab = _location(s_ext, rig, np.r_[fwd.fit.theta[:p], list(par.values())])
        out.append(Cause(cause=name, location=loc, location_label=lab, parameters=par,
                         gain=dict(c.gain),
                         replaces=c.replaces if name == c.cause else None))
    return tuple(out)


def _fit_percent(exps, sims) -> list[list[float]]:
    return [fit_percent(e.y_m, y).tolist() for e, y in zip(exps, sims, strict=True)]


def require_diagnosable(rig: Rig, what: str = "diagnose") -> None:
    """Raise ModelError (one line with the fix) unless ``diagnose`` can work on ``rig``.

    Parameters
    ----------
    rig : Rig
    what : str
        Who asks, for the message.
    """
    rig.require_positions(what)  # the effects simulate positions only
    if LinearModel(rig, "free").output_index is not None:
        # the diagnostics read output j as the position of cart j
        raise ModelError(f"{what} needs a sensor on every moving cart, in cart order; "
                         "list the rig's [[sensors]] that way")


def diagnose(
    experiments: Experiment | Sequence[Experiment],
    *,
    rig: Rig | None = None,
    train: int | Sequence[int] = 0,
    candidates: Sequence[str] | None = None,
    n_null: int = 40,
    alpha: float = 0.05,
    posterior: bool = True,
    rng=None,
    quantum_m: float | None = None,
    max_fits: int | None = None,
    posterior_options: dict | None = None,
    max_nfev: int = 40,
    n_starts: int = 3,
    max_effects: int = 3,
    global_search: bool = True,
    progress: bool = False,
    weights: str | None = None,
) -> Diagnosis:
    """Diagnose the linear model's misfit, name the cause and measure the gain.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
        Measured (or simulated) experiments on the rig.
    rig : Rig, optional
        Default ``Rig()`` (ECP 210 springs).
    train : int or sequence of int
        Index (or indices) of the experiments the models are fitted to; the others are
        held out and only predicted.
    candidates : sequence of str, optional
        Extensions considered (default ``DEFAULT_CANDIDATES``, the whole catalogue).
    n_null : int
        Null data sets of the calibration (at least ``1/alpha - 1``; 40 by default).
    alpha : float
        Family-wise false-positive rate of the discrepancy decision; the candidates'
        likelihood-ratio tests use ``alpha / n_candidates``.
    posterior : bool
        Sample the accepted extended model with emcee for credible intervals and the
        ELPD change (slow).  The decision never depends on it.
    rng : numpy.random.Generator or int, optional
        Seeds the null simulations and the sampler.
    quantum_m : float, optional
        Encoder resolution used by the null simulations, m; default: inferred
        (``infer_quantum``: one ECP count when the positions are whole counts, else 0).
    max_fits : int, optional
        Fit only the ``max_fits`` candidates with the strongest signatures (default all),
        in the first step and in every forward step (there: the cheapest batched starts).
    posterior_options : dict, optional
        Passed to the sampler (``n_steps``, ``n_walkers``...).
    max_nfev : int
        Residual evaluations allowed to each candidate's least-squares fit (started from
        the best of a batched grid, the fits converge in 10-40).  A saturation whose best
        start level is above every input is inactive there and has no gradient: it is
        scored at that start without a fit.
    n_starts : int
        Local fits per candidate, from the ``n_starts`` best points of the batched grid;
        the lowest training cost wins.  The stick-slip and backlash costs have many
        local optima of nearly equal cost (on the measured impulses the best three
        friction starts end 6 % apart in cost and 3 points apart in their prediction of
        the held-out steps), so one start makes the reported gain depend on which basin
        the nearest start happens to lie in.
    max_effects : int
        Largest number of effects forward selection puts in the model
        (``bayesmodal.discrepancy.diagnosis.forward``); 1 stops after the first cause.
    global_search : bool
        In forward selection, fit every model with stick-slip friction also by
        differential evolution and a least-squares polish
        (``bayesmodal.fit.global_search``), not only from local starts.
    progress : bool
        Progress lines on stderr: each stage as it starts, and progress over the null
        data sets, the candidate fits and the sampler steps (``bayesmodal._progress``).
    weights : {None, "spread"}
        How the extended models' least-squares fits weigh several training records:
        None, the plain sum of squared residuals (a record counts in proportion to its
        spread: on the ECP records a point of fit on the steps, whose positions are held
        away from rest for seconds, weighs 4-5 times one on a pulse of the impulses and
        5-7 times one on a sweep), or ``"spread"``, each record as much as the others
        (``effects.fit.record_weights``; the cost of ``fit_records_lsq``, per record
        instead of per record and cart).  The linear fit, the start and the null's
        base, stays unweighted; the scores (AR(1) log density, output error) do not
        depend on it.  One record: the same either way.

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        No experiments, or experiments that do not match the rig.
    ConfigError
        Bad ``train``, ``candidates``, ``n_null`` or ``alpha``.

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> if p:  # doctest: +SKIP
    ...     d = diagnose(load_experiment(p), posterior=False, rng=1)
    ...     d.cause
    'coulomb_friction'
    """
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    if not exps:
        raise DataError("no experiments given")
    rig = Rig() if rig is None else rig
    require_diagnosable(rig)
    for e in exps:
        if not isinstance(e, Experiment):
            raise DataError(f"expected Experiment objects, got {type(e).__name__}")
        if e.n_outputs != rig.n_outputs:
            raise DataError(f"{e.name}: {e.n_outputs} outputs but the rig has "
                            f"{rig.n_outputs} sensors")
    tr = _train_indices(train, len(exps))
    held = tuple(i for i in range(len(exps)) if i not in tr)
    cands = tuple(DEFAULT_CANDIDATES if candidates is None else candidates)
    unknown = [c for c in cands if c not in EXTENSIONS]
    if unknown or not cands:
        raise ConfigError(f"unknown candidate extension(s) {unknown}; known: "
                          f"{sorted(EXTENSIONS)}")
    # effects this rig cannot carry (e.g. backlash where the motor drives two carts):
    # refused when asked for by name, left out of the default catalogue with a note
    why = {c: EXTENSIONS[c].unsupported(rig) for c in cands}
    if candidates is not None and any(why.values()):
        raise ConfigError(next(w for w in why.values() if w))
    skipped = [c for c in cands if why[c]]
    cands = tuple(c for c in cands if not why[c])
    if weights is not None and weights not in WEIGHTINGS:
        raise ConfigError(f"weights must be None or one of {WEIGHTINGS}, got {weights!r}")
    rng = np.random.default_rng(rng)
    train_exps = [exps[i] for i in tr]
    held_exps = [exps[i] for i in held]
    model = LinearModel(rig, "free")
    check_structure(model, train_exps)  # a layout no record identifies: before any fit
    q = infer_quantum(exps) if quantum_m is None else float(quantum_m)
    if q < 0 or not np.isfinite(q):
        raise ConfigError(f"quantum_m must be finite and >= 0, got {quantum_m!r}")
    if isinstance(n_starts, bool) or not isinstance(n_starts, (int, np.integer)) or n_starts < 1:
        raise ConfigError(f"n_starts must be a positive integer, got {n_starts!r}")
    if (isinstance(max_effects, bool) or not isinstance(max_effects, (int, np.integer))
            or max_effects < 1):
        raise ConfigError(f"max_effects must be a positive integer, got {max_effects!r}")

    # 1. linear fit and its noise model
    # the optimisers probe wild parameter values on the way (overflowing exponentials of
    # unstable trial systems); those trials are rejected, so the warnings are noise
    announce("diagnose: least-squares fit of the linear model", enabled=progress)
    with np.errstate(all="ignore"):
        linear = fit_lsq(train_exps, model)
    require_identified(linear, train_exps, "the diagnosis")
    y_lin = [simulate_linear(model, linear.theta, e.v_volt, e.dt) for e in train_exps]
    noise = fit_noise([e.y_m - y for e, y in zip(train_exps, y_lin, strict=True)], q)

    # 2. null calibration and the data's diagnostics
    cal = calibrate_null(train_exps, model, linear.theta, noise=noise, n_null=n_null,
                         alpha=alpha, rng=rng, progress=progress)
    diags = [run_diagnostics(e, model, linear.theta, quantum_m=q) for e in train_exps]
    tests, t_max = _outcomes(cal, train_exps, diags)
    p_mc = cal.p_value(t_max)
    discrepancy = bool(t_max > cal.threshold)

    # signatures
    signature = {c: 0.0 for c in cands}
    for t in tests:
        for c in t.suggests:
            if c in signature:
                signature[c] += max(t.z, 0.0)
    order = sorted(cands, key=lambda c: (-signature[c], cands.index(c)))
    # one record: the AR(1) log density; several: it or the output error (sees a level)
    crit = criterion_for(train_exps)
    shapes = [(e.n_samples, e.n_outputs) for e in train_exps]
    lin_pointwise = crit.pointwise([e.y_m - y for e, y in zip(train_exps, y_lin, strict=True)])
    fp_before = _fit_percent(train_exps, y_lin)
    held_lin = [simulate_linear(model, linear.theta, e.v_volt, e.dt) for e in held_exps]
    gain: dict = {"fit_percent_before": fp_before, "fit_percent_after": fp_before,
                  "experiments": [e.name for e in train_exps]}
    if held_exps:
        hb = _fit_percent(held_exps, held_lin)
        gain.update(heldout_experiments=[e.name for e in held_exps],
                    heldout_fit_percent_before=hb, heldout_fit_percent_after=hb)
    gain.update(delta_elpd=None, delta_elpd_se=None, criterion=None)
    notes: list[str] = []
    if skipped:
        notes.append(f"left out (this rig cannot carry them): {', '.join(skipped)}")
    base = dict(
        statistic=t_max, threshold=cal.threshold, p_value=p_mc, tests=tuple(tests),
        experiments=tuple(e.name for e in exps), train=tr, n_null=cal.n_null,
        alpha=float(alpha), rule=cal.rule, weights=weights or "none")

    if not discrepancy:
        ranking = tuple(CandidateScore(
            name=c, signature=signature[c], fitted=False, gain_nll=np.nan,
            lr_statistic=np.nan, n_params=len(EXTENSIONS[c].specs(rig)), p_value=np.nan,
            score=np.nan, significant=False, passes=False, location=None, params={},
            message="not fitted: no discrepancy") for c in order)
        return Diagnosis(discrepancy=False, cause="none", location=None, location_label=None,
                         explained=True, tests_after=(), ranking=ranking, parameters={},
                         linear_parameters={}, gain=gain, interval_method="none",
                         notes=("the diagnostics do not reject the linear model",),
                         detail={"calibration": cal, "linear": linear}, **base)

    # 4. fit the candidates
    to_fit = order if max_fits is None else order[: max(int(max_fits), 1)]
    level = alpha / len(cands)
    scored: list[CandidateScore] = []
    fits = {}
    after_tests = {}
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
        if REFINES.get(c) in cands and max_effects > 1:
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
                ef = None
                for theta0 in best_starts(ext, rig, linear.theta, train_exps, n_starts,
                                          weights):
                    inactive = c == "input_saturation" and theta0[-1] >= peak_volt
                    f = fit_extension_lsq(train_exps, ext, rig, theta0=theta0, linear=linear,
                                          max_nfev=1 if inactive else max_nfev,
                                          weights=weights)
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
        g, lr, p, score, sig = crit.test(pw, lin_pointwise, k, shapes, level)
        held_out = None
        if sig and len(train_exps) >= 2:
            # several records: the leave-one-record-out gain must be significant too
            held_out = loro_gain(train_exps, rig, None, linear.theta, ext, ef.theta, linear,
                                 weights=weights)
            sig = held_out_significant(held_out, level)
        lin_theta = ef.theta[: model.n_params]
        d_after = [run_diagnostics(e, model, lin_theta, quantum_m=q, y_pred=y)
                   for e, y in zip(train_exps, y_ext, strict=True)]
        t_after, tmax_after = _outcomes(cal, train_exps, d_after)
        # only the diagnostics of the residual can pass or fail a model; the others
        # (free-decay envelope, amplitude dependence, stick) look at the measured motion
        # itself, which no model changes
        t_after = [t for t in t_after if t.name in RESIDUAL_BASED]
        tmax_after = max((t.z for t in t_after), default=-np.inf)
        sig_tests = {t.name for t in tests if c in t.suggests} & set(RESIDUAL_BASED)
        # pass: no residual diagnostic beyond its threshold, or (misfit beyond the
        # catalogue remaining) the workflow statistic falls and every residual diagnostic
        # that pointed at this cause falls too
        z_before = {t.name: t.z for t in tests}
        z_after = {t.name: t.z for t in t_after}
        clean = bool(tmax_after <= cal.threshold)
        passes = bool(clean or (tmax_after < t_max
                                and all(z_after[n] < z_before[n] for n in sig_tests)))
        loc, label = _location(ext, rig, ef.theta)
        ext_params = dict(zip(ext.extension_names(rig),
                              ef.theta[model.n_params:].tolist(), strict=True))
        fits[c] = (ef, y_ext, pw, tmax_after, label, held_out)
        after_tests[c] = t_after
        scored.append(CandidateScore(
            c, signature[c], True, g, lr, k, p, float(score), sig, passes, loc, ext_params,
            f"T after {tmax_after:.1f} (before {t_max:.1f}, threshold {cal.threshold:.1f})"
            + ("; residuals pass every diagnostic" if clean else "")))
    bar.close()
    ranking = tuple(sorted(scored, key=lambda s: -s.score if np.isfinite(s.score) else np.inf))
    accepted = next((s for s in ranking if s.fitted and s.significant and s.passes), None)

    if accepted is None:
        notes.append("discrepancy found but no candidate extension is both significant and "
                     "passes its diagnostics")
        return Diagnosis(discrepancy=True, cause="none", location=None, location_label=None,
                         explained=False, tests_after=(), ranking=ranking, parameters={},
                         linear_parameters={}, gain=gain, interval_method="none",
                         notes=tuple(notes),
                         detail={"calibration": cal, "linear": linear, "fits": fits},
                         **base)

    c = accepted.name
    ext = EXTENSIONS[c]
    ef, y_ext, pw, tmax_after, label, held_out = fits[c]
    t_after = after_tests[c]
    first = Cause(
        cause=c, location=accepted.location, location_label=label,
        parameters=dict(accepted.params),
        gain={"in_sample": {"delta_lpd": accepted.gain_nll,
                            "lr_statistic": accepted.lr_statistic,
                            "n_params": accepted.n_params, "p_value": accepted.p_value,
                            "bic_gain": accepted.score,
                            "fit_percent": _fit_percent(train_exps, y_ext)},
              "held_out": held_out})
    causes, effects, fwd = (first,), (c,), None
    if max_effects > 1:
        fwd = forward_select(
            train_exps, rig, c, ef, cands, linear=linear, quantum_m=q, n_null=n_null,
            alpha=alpha, rng=rng, outcomes=_outcomes, location=_location,
            max_effects=int(max_effects), max_fits=max_fits, n_starts=n_starts,
            max_nfev=max_nfev, global_search=bool(global_search), progress=progress,
            weights=weights)
        causes = _final_causes(causes + fwd.added, fwd, rig, model)
        for eff, simpler in fwd.simplified:
            notes.append(f"{eff} {'simplified to ' + simpler if simpler else 'removed'} "
                         "once later effects were in the model")
        effects = fwd.names
        # the residuals of the final model, judged against the null recalibrated on it
        t_after = list(fwd.tests)
        notes.append("forward selection: " + " -> ".join(x.cause for x in causes)
                     + f"; stopped: {fwd.stop}")
        if fwd.fit is not ef:
            # intervals, fit percents and the ELPD change describe the final model, not
            # the first step's: a refinement or an exchange may have replaced it, or a
            # backward check refitted it from a later model's better optimum
            ext, ef = get_extension(list(effects)), fwd.fit
            y_ext = [ext.simulate(rig, ef.theta, e.v_volt, e.dt) for e in train_exps]
            pw = crit.pointwise([e.y_m - y for e, y in zip(train_exps, y_ext, strict=True)])
    n_extra = len(ext.specs(rig))
    gain["model"] = "+".join(effects)
    # explained only when the final model's residuals pass every residual diagnostic
    explained = not any(t.exceeded for t in t_after)
    if not explained:
        rest = sorted({t.name for t in t_after if t.exceeded})
        notes.append(f"after {'+'.join(effects)}, still beyond threshold: {', '.join(rest)} "
                     "(misfit the catalogue does not explain)")
    gain["fit_percent_after"] = _fit_percent(train_exps, y_ext)
    held_ext = [ext.simulate(rig, ef.theta, e.v_volt, e.dt) for e in held_exps]
    if held_exps:
        gain["heldout_fit_percent_after"] = _fit_percent(held_exps, held_ext)
    # plug-in ELPD (lpd minus parameter count) with the SE of pointwise differences
    d = pw - lin_pointwise
    gain.update(delta_elpd=crit.total(d) - n_extra,  # the AR(1) row with several records
                delta_elpd_se=crit.se(d, shapes),
                criterion="plug-in ELPD (AR(1) lpd at the least-squares fits minus the "
                          "number of extra parameters); SE from the pointwise differences")
    if held_exps:
        hd = ar1_pointwise([e.y_m - y for e, y in zip(held_exps, held_ext, strict=True)]) - \
            ar1_pointwise([e.y_m - y for e, y in zip(held_exps, held_lin, strict=True)])
        gain.update(heldout_delta_lpd=float(hd.sum()),
                    heldout_delta_lpd_se=float(np.sqrt(hd.size * np.var(hd))))
    names = ext.names(rig)
    lin_names = model.names
    linear_parameters = {
        n: {"before": float(linear.theta[i]), "after": float(ef.theta[i]),
            "change_percent": float(100 * (ef.theta[i] - linear.theta[i])
                                    / abs(linear.theta[i])) if linear.theta[i] != 0
            else None}
        for i, n in enumerate(lin_names)}
    parameters, method = None, "laplace"
    if posterior:

        post = posterior_summary(exps=train_exps, ext=ext, rig=rig, fit=ef,
                                 linear=linear, rng=rng, options=posterior_options or {},
                                 heldout=held_exps, progress=progress)
        if post is not None:
            parameters = post["parameters"]
            # intervals of chains that did not converge are not a posterior summary
            method = "posterior" if post["converged"] else "posterior_unconverged"
            for key in ("delta_elpd", "delta_elpd_se", "criterion"):
                if post.get(key) is not None:
                    gain[key] = post[key]
            gain["elpd_change"] = post.get("elpd")
            gain["posterior"] = post["fits"]
            notes.extend(post.get("notes", ()))
        else:
            notes.append("the sampler has no extension support here: intervals are from a "
                         "Laplace approximation at the least-squares optimum")
    if parameters is None:
        sd = laplace_sd(ext, rig, ef.theta, train_exps)
        zq = stats.norm.ppf(0.95)
        # parameters whose prior range is non-negative keep the interval there (a Laplace
        # interval at a non-smooth optimum, e.g. Fs at Fc, can be very wide)
        specs = ext.specs(rig)
        parameters = {}
        for i, n in enumerate(names):
            if i < model.n_params:
                continue
            lo = float(ef.theta[i] - zq * sd[i])
            if specs[i - model.n_params].bounds[0] >= 0:
                lo = max(lo, 0.0)
            parameters[n] = Interval(float(ef.theta[i]), lo, float(ef.theta[i] + zq * sd[i]))
    return Diagnosis(
        discrepancy=True, cause=causes[0].cause if causes else c,
        location=causes[0].location if causes else accepted.location,
        location_label=causes[0].location_label if causes else label,
        explained=explained, tests_after=tuple(t_after), ranking=ranking, parameters=parameters,
        linear_parameters=linear_parameters, gain=gain, interval_method=method,
        notes=tuple(notes), causes=causes, effects=tuple(effects),
        detail={"calibration": cal, "linear": linear, "fits": fits, "extension_fit": ef,
                "forward": fwd},
        **base)
