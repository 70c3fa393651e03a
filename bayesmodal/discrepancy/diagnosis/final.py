"""The model a diagnosis ends with: the accepted first effect, then forward selection.

``final_model`` runs forward selection from the first step's accepted effect and judges
the final model's residuals; ``first_of_several`` starts it from the most significant
effect when none passes alone.  ``outcomes`` turns diagnostics into calibrated test
outcomes (shared with the first step in ``workflow``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...metrics import fit_percent
from ...model.effects import EXTENSIONS, Extension, get_extension
from ._result import TestOutcome
from .forward import RESIDUAL_BASED, Cause, forward_select
from .location import effect_location, final_causes
from .null import NullCalibration, diagnostic_statistics


def outcomes(cal: NullCalibration, exps, diags_per_exp) -> tuple[list[TestOutcome], float]:
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


def fit_percents(exps, sims) -> list[list[float]]:
    return [fit_percent(e.y_m, y).tolist() for e, y in zip(exps, sims, strict=True)]


@dataclass(frozen=True)
class FinalModel:
    """The model the diagnosis ends with (step 5 and forward selection)."""

    ext: Extension
    fit: object
    y_ext: list
    pointwise: np.ndarray
    causes: tuple
    effects: tuple
    t_after: list
    label: str | None
    forward: object
    explained: bool


def final_model(st, train_exps, rig, cands, accepted, fits, after_tests, spec,
                 rng, progress, notes: list) -> FinalModel:
    """The accepted first cause, then forward selection from it; appends its notes."""
    model = st.model
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
                            "fit_percent": fit_percents(train_exps, y_ext)},
              "held_out": held_out})
    causes, effects, fwd = (first,), (c,), None
    if spec.max_effects > 1:
        fwd = forward_select(
            train_exps, rig, c, ef, cands, linear=st.linear, quantum_m=st.q,
            n_null=spec.n_null, alpha=spec.alpha, rng=rng, outcomes=outcomes,
            location=effect_location, max_effects=int(spec.max_effects), max_fits=spec.max_fits,
            n_starts=spec.n_starts, max_nfev=spec.max_nfev,
            global_search=bool(spec.global_search), progress=progress,
            weights=spec.weights)
        causes = final_causes(causes + fwd.added, fwd, rig, model)
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
            pw = st.crit.pointwise([e.y_m - y for e, y in zip(train_exps, y_ext,
                                                              strict=True)])
    # explained only when the final model's residuals pass every residual diagnostic
    explained = not any(t.exceeded for t in t_after)
    if not explained:
        rest = sorted({t.name for t in t_after if t.exceeded})
        notes.append(f"after {'+'.join(effects)}, still beyond threshold: {', '.join(rest)} "
                     "(misfit the catalogue does not explain)")
    return FinalModel(ext, ef, y_ext, pw, causes, tuple(effects), t_after, label, fwd,
                       explained)


def first_of_several(st, train_exps, rig, cands, ranking, fits, after_tests,
                      spec, rng, progress, notes: list):
    """When no single effect passes: forward selection from the most significant one.

    Two effects can each leave the residuals worse structured than the linear model while
    both together explain them (friction with a drive dead band on one cart: each alone
    raised the workflow statistic from 16 to 24 and 33, ``benchmarks/detection_layouts.py``
    seed 20007).  The most significant single effect is then taken as the first step of
    forward selection; the result is kept only if it holds two effects or more and its
    largest residual statistic falls below the linear model's (the first half of a single
    candidate's pass rule; the second, that every check pointing at the candidate falls,
    is not applied), so that a record no model of the catalogue improves still ends with
    ``none``.  Returns ``(accepted, final)``, or ``(None, None)``.
    """
    if spec.max_effects < 2:
        return None, None
    first = next((s for s in ranking if s.fitted and s.significant), None)
    if first is None:
        return None, None
    trial: list[str] = []
    final = final_model(st, train_exps, rig, cands, first, fits, after_tests, spec, rng,
                         progress, trial)
    t_final = max((t.z for t in final.t_after if t.name in RESIDUAL_BASED), default=-np.inf)
    if len(final.effects) < 2 or not t_final < st.t_max:
        return None, None
    notes.append(f"no single effect passes its diagnostics; forward selection from the "
                 f"most significant one ({first.name}) lowers the workflow statistic from "
                 f"{st.t_max:.1f} to {t_final:.1f}")
    notes.extend(trial)
    return first, final
