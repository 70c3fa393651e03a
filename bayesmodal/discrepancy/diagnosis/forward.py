"""Forward selection: after one accepted effect, look for the next one in what is left.

The first step of ``diagnose`` tests the linear model and accepts one effect.  Each
further step starts from the model accepted so far (the linear core plus the effects
found, a ``Combined`` model):

1. **Recalibrate.**  The residual diagnostics are calibrated on the *extended* model
   (``calibrate_null(..., extension_fit=...)``: its simulation plus the AR(1) noise of its
   own residuals, quantised, refitted with the extended model and diagnosed like the
   data).  If the largest standardised residual diagnostic ``T`` is at or below the
   recalibrated threshold, the residuals pass and the selection stops.
2. **Candidates.**  Every catalogued effect not in the model that combines with it
   (``Combined`` refuses two plant-side effects) is added, and refinements replace the
   effect they generalise (directional Coulomb levels replace equal ones).  Each gets the
   current fit with the candidate's start grid, evaluated in one batch, and is fitted by
   least squares from its ``n_starts`` cheapest points (``max_fits`` bounds the number of
   candidates fitted, cheapest start first: by default every one is, as in the first step,
   because a candidate whose grid holds its null value starts at the current cost, and
   such ties ordered a hidden dead band behind three effects that were not there).
   Exchanges join them: the model's plant-side effect replaced by another plant-side
   candidate together with one input-side candidate (two plant-side effects never
   combine, so a wrong one accepted first would otherwise lock the right one out; an
   exchange's ``k`` is the change in parameter count, and it is judged by the same rule,
   a likelihood ratio against a non-nested model made conservative by the BIC gain).
   When no candidate gains significantly (step 3), two input-side effects are tried
   together before the selection stops (``_input_pairs``; the test's family then holds
   the singles and the pairs): effects in the drive can mask each other, each alone
   scoring below the model and both together above it (an offset and a dead band on the
   measured records).
3. **Test.**  In sample, with one training record: the likelihood ratio
   ``LR = 2 (lpd_new - lpd_cur)`` of the AR(1)-whitened Gaussian likelihood (noise
   profiled per output) against ``chi2(k)`` (``k`` added parameters) at
   ``alpha / n_candidates``, and a positive BIC gain ``LR - k ln N``.  With several
   training records a gain counts when that test or a test of the output error finds
   it, each at half the level (``scoring.Criterion("either")``): the output error (a
   Gaussian per output with its variance profiled, ``z = gain / SE`` with an
   autocorrelation-aware SE, ``scoring.autocorr_se``) sees a level where the AR(1)
   score with ``phi`` near 1 does not (on the four ECP records an input offset that
   halves the cost scored 796 nats *below* the model without it).  For a pure addition
   ``lpd_cur`` is the current model at its best
   known point: its fit, or its value at the candidate's optimum without the added
   effects, whichever scores higher (``_reference``), so that a better optimum of the
   shared parameters found by the candidate's fit is not credited to the effect.  With
   two or more training records the criterion is the
   leave-one-record-out gain: both models are refitted on the other records (started
   from their full fits) and predict the held-out one; the sum over records of the
   held-out AR(1) gain must exceed ``z_(1 - alpha / (2 n_candidates))`` times its SE
   ``sqrt(n var(d_i))``, or the output-error gain the same quantile times its
   autocorrelation-aware SE (the in-sample test is kept as well).  The
   significant candidate of largest gain (held-out when available, else
   BIC) is accepted.  A candidate with stick-slip friction that gains in sample is first
   refitted by a global search (``effects.global_fit``), since its local fit may stop on
   a terrace of the cost far from its optimum (``global_search``).
4. **Simplify** (backward check).  After each acceptance, every refinement in the model
   is tested against the effect it refines, and every effect against the model without
   it (refitted from the current fit, or left at it where that scores higher; the same
   in-sample rule at ``alpha``, by the records' criterion); one whose
   parameters no longer gain significantly is replaced or removed, and the check
   repeats: an input offset added later can explain what first looked like unequal
   friction levels on the driven cart.  Before directional levels are kept, the
   equal-level model is also fitted by the global search.
5. **Stop** when the residuals pass, no candidate gains significantly, or the model holds
   ``max_effects`` effects.

This module holds the loop (``forward_select``) and the fitting and testing of one step's
candidates (``_evaluate``); the candidates and their starts are in ``candidates``, the
gains and their tests in ``gains``, the backward check in ``backward``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from ..._errors import DataError, ModelError
from ..._json import to_jsonable
from ..._progress import announce
from ...data import Experiment
from ...fit._threads import thread_map
from ...fit.effects import ExtensionFit
from ...fit.global_search import is_stick_slip
from ...fit.result import LSQResult
from ...metrics import fit_percent
from ...model.effects import EXTENSIONS, get_extension
from ...model.system import LinearModel, Rig
from ..checks import diagnostics_for
from .backward import _simplify
from .candidates import REFINES, _fit_from, _global_if_better, _input_pairs, _options, _starts
from .gains import _in_sample, _lpd, _reference, _simulate, loro_gain
from .null import NullCalibration, calibrate_null, fit_noise, run_diagnostics
from .scoring import held_out_significant

__all__ = ["Cause", "ForwardResult", "forward_select", "loro_gain", "REFINES",
           "RESIDUAL_BASED"]

#: Diagnostics computed from the residual (the others analyse the measured motion, which
#: no model changes, and take no part in a pass check).
RESIDUAL_BASED = ("whiteness", "input_correlation", "friction_signature",
                  "residual_spectrum", "gain_error", "input_bias", "drive_gain")


def residual_based(model) -> tuple[str, ...]:
    """The ``RESIDUAL_BASED`` diagnostics that apply to ``model``'s sensors."""
    return tuple(n for n in RESIDUAL_BASED if n in diagnostics_for(model))


@dataclass(frozen=True)
class Cause:
    """One effect found, in the order found.

    Attributes
    ----------
    cause : str
        Effect name (``EXTENSIONS`` key).
    location : list of int or None
        1-based carts or springs; None for input-side effects.
    location_label : str or None
    parameters : Mapping
        The effect's least-squares parameters in the model it was accepted into, SI units.
    gain : Mapping
        ``in_sample``: ``delta_lpd`` (nats), ``lr_statistic``, ``n_params``, ``p_value``,
        ``bic_gain``, ``fit_percent`` (per training record and output after the step);
        ``held_out``: ``delta_lpd``, ``se``, ``z`` and ``records`` of the
        leave-one-record-out gain (None with one training record).
    replaces : str or None
        The effect this one refines and replaces in the model (``REFINES``), or the
        plant-side effect it was exchanged for (an exchange adds two causes, the new
        plant-side effect and an input-side one, each with the exchange's gain).
    """

    cause: str
    location: list[int] | None
    location_label: str | None
    parameters: Any
    gain: Any
    replaces: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "parameters", MappingProxyType(dict(self.parameters)))
        object.__setattr__(self, "gain", MappingProxyType(dict(self.gain)))

    def as_dict(self) -> dict:
        return to_jsonable({"cause": self.cause, "location": self.location,
                       "location_label": self.location_label,
                       "parameters": dict(self.parameters), "replaces": self.replaces,
                       "gain": {k: (dict(v) if isinstance(v, dict) else v)
                                for k, v in self.gain.items()}})


@dataclass(frozen=True)
class ForwardResult:
    """Outcome of the forward steps after the first accepted effect.

    Attributes
    ----------
    added : tuple of Cause
        Effects added after the first, in order.
    names : tuple of str
        Effects of the final model (a refinement replaces what it refines).
    fit : ExtensionFit
        Least-squares fit of the final model.
    calibration : NullCalibration or None
        The null calibration of the final model (None when ``max_effects`` stopped the
        selection before it was calibrated).
    tests : tuple of TestOutcome
        Residual diagnostics of the final model against that calibration.
    stop : str
        Why the selection stopped.
    steps : tuple of dict
        Per step: the candidates with their in-sample and held-out gains, and
        ``cost_ratio``, the least-squares cost of the candidate's fit over the current
        model's (the fit's own criterion, next to the score that tests it).
    simplified : tuple of (str, str or None)
        Effects replaced by what they refine (``(refined, simpler)``) or removed
        (``(effect, None)``) once a later effect made their parameters unnecessary.
    """

    added: tuple
    names: tuple[str, ...]
    fit: ExtensionFit
    calibration: NullCalibration | None
    tests: tuple
    stop: str
    steps: tuple = field(default=())
    simplified: tuple = field(default=())


def _residual_tests(cal, exps, model, fit, q, outcomes):
    ys = _simulate(fit.extension, fit.rig, fit.theta, exps)
    lin = fit.theta[: model.n_params]
    diags = [run_diagnostics(e, model, lin, quantum_m=q, y_pred=y, names=residual_based(model))
             for e, y in zip(exps, ys, strict=True)]
    tests, t_max = outcomes(cal, exps, diags)
    return tests, t_max


def _step_record(ext, t_max, cal, rows) -> dict:
    """The record of one forward step (``ForwardResult.steps``): the model, its ``T`` and
    threshold, and each fitted candidate's gains."""
    return {"model": ext.name, "T": t_max, "threshold": cal.threshold,
            "candidates": [{key: r[key] for key in
                            ("cause", "delta_lpd", "lr", "n_params", "p_value",
                             "bic_gain", "cost_ratio", "held_out", "significant")}
                           for r in rows]}


def _causes(best, kept, names, fit, rig, exps, location, p) -> list[Cause]:
    """The causes of an accepted step: one per effect of ``kept`` (the effects the step
    added that the model ``names`` at ``fit`` still holds), each with its parameters,
    location and the gain of the accepted row ``best`` (``p`` linear parameters)."""
    out = []
    new = get_extension(list(names))
    own = dict(zip(new.extension_names(rig), fit.theta[p:], strict=True))
    fp = [fit_percent(e.y_m, y).tolist()
          for e, y in zip(exps, _simulate(new, rig, fit.theta, exps), strict=True)]
    for a in kept:
        c_ext = EXTENSIONS[a]
        c_par = {n: float(own[n]) for n in c_ext.extension_names(rig)}
        loc, label = location(c_ext, rig, np.r_[fit.theta[:p], list(c_par.values())])
        # the refined or exchanged effect (always one of the model's) is replaced by
        # the plant-side effect that takes its place, never by an input-side one
        replaces = best["dropped"] if c_ext.side != "input" else None
        out.append(Cause(
            cause=a, location=loc, location_label=label, parameters=c_par,
            gain={"in_sample": {"delta_lpd": best["delta_lpd"], "lr_statistic": best["lr"],
                                "n_params": best["n_params"], "p_value": best["p_value"],
                                "bic_gain": best["bic_gain"], "fit_percent": fp},
                  "held_out": best["held_out"]},
            replaces=replaces))
    return out


def _evaluate(options, level, *, names, ext, fit, rig, exps, linear, cur_pw,
              max_fits, n_starts, max_nfev, loro_nfev, search, progress, weights) -> list:
    """Fit and test the ``options`` of one forward step (rows of :func:`_options`) against
    the current model ``ext`` at ``fit`` (module docstring, steps 2-3); one dict per
    fitted candidate."""
    p = fit.theta.size - len(ext.specs(rig))
    # screening: the cheapest batched start of every candidate; with ``max_fits`` only
    # that many, cheapest first, are fitted (default: every one)
    screened = []
    for added_, dropped, new_names, new in options:
        try:
            starts, cost0 = _starts(new, rig, names, fit.theta, added_, fit.theta[:p],
                                    exps, n_starts, weights)
        except (ModelError, DataError, ValueError):
            continue
        screened.append((cost0, added_, dropped, new_names, new, starts))
    screened.sort(key=lambda x: x[0])
    rows = []
    current_refits: dict = {}  # the current model's fold refits, shared by the candidates
    n_fit = len(screened) if max_fits is None else max(int(max_fits), 1)
    todo = screened[:n_fit]
    announce(f"diagnose: forward step {len(names) + 1}: fitting "
             f"{', '.join(row[4].name for row in todo)}", enabled=progress)
    # the candidates' local fits side by side on the fits' threads, the same fits as one
    # after another
    fits = thread_map(lambda row: _fit_from(row[4], rig, row[5], exps, linear, max_nfev,
                                            weights=weights), todo)
    for (_, added_, dropped, new_names, new, _), f in zip(todo, fits, strict=True):
        c = "+".join(added_) + (f" for {dropped}" if dropped and len(added_) > 1 else "")
        if f is None:
            continue
        k = len(new.specs(rig)) - len(ext.specs(rig))
        ref_theta, ref_pw = fit.theta, cur_pw
        if dropped is None:  # a pure addition: test the effect, not a better refit
            ref_theta, ref_pw = _reference(new, f, ext, fit, rig, exps, cur_pw)
        g, lr, pv, bic, sig = _in_sample(new, f, rig, exps, ref_pw, k, level)
        if sig and search is not None and is_stick_slip(new) and len(added_) == 1:
            # a gain of a stick-slip model is only as good as its fit: redo it from the
            # global search (the local fit may stop on a terrace, either side).  Not for
            # exchanges or pairs, fitted from local starts only: with the search, on
            # backlash + motor lag data (seed 20002) an exchange took the true backlash
            # out for friction, and a later step had to put it back
            announce(f"diagnose: forward step {len(names) + 1}: global search of "
                     f"{new.name}", enabled=progress)
            fg = _global_if_better(new, rig, f, exps, linear, max_nfev, search, weights)
            if fg is not None:
                f = fg
                if dropped is None:
                    ref_theta, ref_pw = _reference(new, f, ext, fit, rig, exps, cur_pw)
                g, lr, pv, bic, sig = _in_sample(new, f, rig, exps, ref_pw, k, level)
        ho = None
        if sig and len(exps) >= 2:
            ho = loro_gain(exps, rig, ext, ref_theta, new, f.theta, linear, loro_nfev,
                           weights=weights, cache=current_refits)
            sig = sig and held_out_significant(ho, level)
        rows.append({"cause": c, "added": added_, "dropped": dropped, "names": new_names,
                     "fit": f, "delta_lpd": g, "lr": lr, "n_params": k, "p_value": pv,
                     "bic_gain": bic, "cost_ratio": f.cost / fit.cost, "held_out": ho,
                     "significant": sig})
    return rows


def forward_select(
    exps: Sequence[Experiment],
    rig: Rig,
    first: str,
    first_fit: ExtensionFit,
    candidates: Sequence[str],
    *,
    linear: LSQResult,
    quantum_m: float,
    n_null: int,
    alpha: float,
    rng,
    outcomes,
    location,
    max_effects: int = 3,
    max_fits: int | None = None,
    n_starts: int = 3,
    max_nfev: int = 40,
    loro_nfev: int = 20,
    refit_nfev: int = 10,
    global_search: bool = True,
    progress: bool = False,
    weights: str | None = None,
) -> ForwardResult:
    """Add effects to ``first`` one at a time (module docstring).

    Parameters
    ----------
    exps : sequence of Experiment
        The training records.
    rig : Rig
    first : str
        The effect accepted by the first step; ``first_fit`` its least-squares fit.
    candidates : sequence of str
        Effects that may be added (and refinements, ``REFINES``).
    linear : LSQResult
        The linear fit to ``exps``.
    quantum_m : float
        Encoder quantum of the null data, m.
    n_null, alpha : int, float
        Null data sets and family-wise false-positive rate of each recalibration.
    rng : numpy.random.Generator
    outcomes, location : callable
        The workflow's judging of diagnostics against a calibration and its location
        rule (``final.outcomes``, ``location.effect_location``).
    max_effects : int
        Largest number of effects in the model (the first included).
    max_fits : int, optional
        Candidates fitted per step: the ones whose cheapest batched start costs least
        (default: all).
    n_starts, max_nfev : int
        Local fits per candidate and their evaluation budget.
    loro_nfev : int
        Evaluations of each leave-one-record-out refit (from the full-data fit).
    refit_nfev : int
        Evaluations of each null refit of the recalibration.
    global_search : bool
        Refit a stick-slip model by ``fit_extension_global`` (differential evolution,
        then the least-squares polish; ``bayesmodal.fit.global_search``)
        where the decision rests on it: a candidate with friction whose local fit gains
        significantly, and the equal-level model of a backward check that would keep
        directional levels.  The lower cost is kept: local fits stop on the terraces of
        the stick-slip cost.  About 20 s per search whatever the records' size.
    progress : bool
    weights : {None, "spread"}
        How the least-squares fits (and their null refits) weigh the records
        (``fit_extension_lsq``); the scores do not depend on it.

    Returns
    -------
    ForwardResult
    """
    model = LinearModel(rig, "free")
    p = model.n_params
    # the searches' seed: a child of rng, which leaves rng's own stream (the null data) as
    # it was
    search = rng.spawn(1)[0] if global_search else None
    names = (first,)
    fit = first_fit
    added: list[Cause] = []
    steps: list[dict] = []
    simplified: list[tuple[str, str]] = []
    rejected: set[str] = set()
    cal, tests = None, ()
    while True:
        ext = get_extension(list(names))
        ys = _simulate(ext, rig, fit.theta, exps)
        noise = fit_noise([e.y_m - y for e, y in zip(exps, ys, strict=True)], quantum_m)
        announce(f"diagnose: recalibrating the null on {ext.name}", enabled=progress)
        cal = calibrate_null(exps, model, fit.theta[:p], noise=noise, n_null=n_null,
                             alpha=alpha, rng=rng, names=residual_based(model),
                             refit_nfev=refit_nfev, extension_fit=fit, weights=weights)
        tests, t_max = _residual_tests(cal, exps, model, fit, quantum_m, outcomes)
        if t_max <= cal.threshold:
            stop = f"the residuals of {ext.name} pass (T = {t_max:.1f} <= {cal.threshold:.1f})"
            break
        if len(names) >= max_effects:
            stop = f"max_effects = {max_effects} reached (T = {t_max:.1f} > {cal.threshold:.1f})"
            break
        options = _options(names, candidates, rejected)
        pairs = _input_pairs(names, candidates, rejected) if len(names) + 2 <= max_effects \
            else []
        level = alpha / max(len(options), 1)
        cur_pw = _lpd(exps, ys)

        step = dict(names=names, ext=ext, fit=fit, rig=rig, exps=exps, linear=linear,
                    cur_pw=cur_pw, max_fits=max_fits, n_starts=n_starts,
                    max_nfev=max_nfev, loro_nfev=loro_nfev, search=search,
                    progress=progress, weights=weights)
        rows = _evaluate(options, level, **step)
        if pairs and not any(r["significant"] for r in rows):
            # a second look: input-side effects in pairs (_input_pairs), the family of
            # tests now holding the singles and the pairs
            level = alpha / (len(options) + len(pairs))
            rows += _evaluate(pairs, level, **step)
        steps.append(_step_record(ext, t_max, cal, rows))
        good = [r for r in rows if r["significant"]]
        if not good:
            stop = (f"no candidate gains significantly after {ext.name} "
                    f"(T = {t_max:.1f} > {cal.threshold:.1f})")
            break
        best = max(good, key=lambda r: r["held_out"]["delta_lpd"] if r["held_out"]
                   else r["bic_gain"])
        before = set(names)  # the model's effects before this step
        names, fit = best["names"], best["fit"]
        names, fit, changes = _simplify(names, fit, rig, exps, linear, alpha, max_nfev,
                                        search, weights)
        # an added refinement simplified to the effect it refines (not in the model
        # before this step) is found under that name: seed 20016 of the friction + offset
        # pair case found directional levels, simplified them to equal ones, and had
        # lost friction from the causes while the final model held it
        renamed = {a: b for a, b in changes if b is not None}
        kept = [renamed.get(a, a) for a in best["added"]]
        kept = [a for a in kept if a in names and a not in before]
        if changes:
            simplified.extend(changes)
            steps[-1]["simplified"] = [f"{a} -> {b}" for a, b in changes]
            gone = [a for a in best["added"] if a not in names]
            rejected.update(gone)  # an effect just added that is not needed after all
            if not kept:
                continue
        added.extend(_causes(best, kept, names, fit, rig, exps, location, p))
    return ForwardResult(added=tuple(added), names=names, fit=fit, calibration=cal,
                         tests=tuple(tests), stop=stop, steps=tuple(steps),
                         simplified=tuple(simplified))
