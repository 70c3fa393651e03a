"""The gain of a candidate model over the current one, as forward selection scores it.

In sample: the records' criterion (``scoring.criterion_for``) of the candidate's fit
against the current model at its best known point (``_reference``), tested by
``Criterion.test`` (``_in_sample``; ``_lr_keeps`` for the backward check).  Held out:
the leave-one-record-out gain (:func:`loro_gain`), both models refitted on the other
records and scored on the one left out.  The module docstring of ``forward`` describes
the rule these serve (step 3).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..._errors import DataError, ModelError
from ...data import Experiment
from ...fit._threads import thread_map
from ...fit.lsq import fit_lsq
from ...fit.result import LSQResult
from ...metrics import fit_percent
from ...model.simulate import simulate_linear
from ...model.system import LinearModel, Rig
from .scoring import Criterion, criterion_for

__all__ = ["loro_gain"]

#: Failures of a fit that make it no candidate (an inadmissible start, a diverging model).
_FIT_ERRORS = (ModelError, DataError, ValueError, FloatingPointError, np.linalg.LinAlgError)


def _simulate(ext, rig, theta, exps):
    if ext is None:
        model = LinearModel(rig, "free")
        return [simulate_linear(model, theta, e.v_volt, e.dt) for e in exps]
    return [ext.simulate(rig, theta, e.v_volt, e.dt) for e in exps]


def _lpd(exps, ys, crit: Criterion | None = None) -> np.ndarray:
    """Pointwise scores of the residuals of ``ys`` on ``exps`` by ``crit`` (default: the
    criterion of these records, ``criterion_for``)."""
    crit = criterion_for(exps) if crit is None else crit
    return crit.pointwise([e.y_m - y for e, y in zip(exps, ys, strict=True)])


def _shapes(exps) -> list[tuple[int, int]]:
    return [(e.n_samples, e.n_outputs) for e in exps]


def _refit(ext, rig, theta, exps, linear: LSQResult, max_nfev: int, weights=None
           ) -> np.ndarray:
    """Parameters refitted on ``exps`` from ``theta`` (the linear model when ``ext`` is
    None, unweighted); the start when the fit fails."""
    try:
        with np.errstate(all="ignore"):
            if ext is None:
                return fit_lsq(exps, LinearModel(rig, "free"), theta0=theta,
                               max_nfev=max_nfev).theta
            return fit_lsq(exps, rig, extension=ext, theta0=theta, linear=linear,
                           max_nfev=max_nfev, weights=weights).theta
    except _FIT_ERRORS:
        return np.asarray(theta, float)


def loro_gain(exps: Sequence[Experiment], rig: Rig, cur_ext, cur_theta, new_ext, new_theta,
              linear: LSQResult, max_nfev: int = 20,
              criterion: Criterion | None = None, weights=None,
              cache: dict | None = None) -> dict:
    """Leave-one-record-out gain of ``new_ext`` over ``cur_ext`` (None: the linear model).

    For every record, both models are refitted by least squares on the other records
    (started from their fits to all records) and predict the held-out record; the gain
    is the sum over records of the held-out score (``criterion``, default that of the
    records, ``criterion_for``: for two or more records the AR(1) log density and the
    output error, each output's noise profiled on each prediction's residual), new minus
    current; :func:`scoring.held_out_significant` tests it.  ``weights`` (None or
    ``"spread"``): the refits' weighting of their records (``fit_extension_lsq``).
    The folds run side by side on the fits' threads (``bayesmodal.fit._threads``), with
    the numbers of one thread.

    Parameters
    ----------
    exps : sequence of Experiment
        The training records (at least two).
    rig : Rig
    cur_ext, new_ext : Extension or None
        The current and the candidate model (None: the linear model).
    cur_theta, new_theta : ndarray
        Their fits to all of ``exps``, where each fold's refit starts.
    linear : LSQResult
        The linear fit to ``exps`` (the extended fits' reference).
    max_nfev : int
        Residual evaluations of each refit.
    criterion : Criterion, optional
    weights : {None, "spread"}
    cache : dict, optional
        Kept by the caller across calls that share ``exps``, ``cur_ext``, ``linear``,
        ``max_nfev`` and ``weights`` (the candidates of one forward step): the current
        model's refits by fold and start, which every candidate of the step compares with.

    Returns
    -------
    dict
        ``delta_lpd`` (nats), ``se`` (the criterion's standard error of the summed
        pointwise differences: ``autocorr_se`` for the output error), ``z``
        (``delta_lpd / se``), ``records`` (per held-out record, nats), ``criterion``;
        for ``"either"`` these are the AR(1) score's and ``output_error`` holds the
        output error's ``delta_lpd``, ``se``, ``z`` and ``records``;
        and ``fit_percent`` / ``fit_percent_current``: per held-out record, the fit
        percentage of each output of the new and the current model's prediction.  The
        refits start from fits that have seen the held-out record, so these are
        optimistic by the distance such a start leaves (up to 7 points on the measured
        records, docs/discrepancy.md section 6, which fits each fold from scratch).
    """
    crit = criterion_for(exps) if criterion is None else criterion
    cache = {} if cache is None else cache
    start = (getattr(cur_ext, "name", None), np.asarray(cur_theta, float).tobytes())

    def fold(r):
        others = [e for i, e in enumerate(exps) if i != r]
        th_c = cache.get((r, start))
        if th_c is None:
            th_c = _refit(cur_ext, rig, cur_theta, others, linear, max_nfev, weights)
        th_n = _refit(new_ext, rig, new_theta, others, linear, max_nfev, weights)
        return th_c, _simulate(new_ext, rig, th_n, [exps[r]]), _simulate(cur_ext, rig, th_c,
                                                                           [exps[r]])

    per, per_oe, pts, fp_new, fp_cur = [], [], [], [], []
    for r, (th_c, y_n, y_c) in enumerate(thread_map(fold, range(len(exps)))):
        cache[(r, start)] = th_c
        d = _lpd([exps[r]], y_n, crit) - _lpd([exps[r]], y_c, crit)
        per.append(crit.total(d))
        if d.ndim == 2:
            per_oe.append(float(d[1].sum()))
        pts.append(d)
        fp_new.append(fit_percent(exps[r].y_m, y_n[0]).tolist())
        fp_cur.append(fit_percent(exps[r].y_m, y_c[0]).tolist())
    out = crit.held_out(np.concatenate(pts, axis=-1), _shapes(exps))
    out.update(records=per, criterion=crit.name, fit_percent=fp_new,
               fit_percent_current=fp_cur)
    if per_oe:
        out["output_error"]["records"] = per_oe
    return out


def _restricted(new, theta_new, cur, rig) -> np.ndarray:
    """``cur``'s parameter vector taken from ``new``'s (``new`` holds every effect of
    ``cur``): the linear part and ``cur``'s own extension parameters at their values in
    ``theta_new``; the effects ``new`` adds are left out."""
    p = theta_new.size - len(new.specs(rig))
    own = dict(zip(new.extension_names(rig), theta_new[p:], strict=True))
    return np.r_[theta_new[:p], [own[k] for k in cur.extension_names(rig)]]


def _reference(new, f, ext, fit, rig, exps, cur_pw):
    """The current model's best known point for the test of a pure addition ``new``.

    The current fit, or the current model at ``new``'s optimum with the added effects
    left out, whichever scores higher (the records' criterion): a local fit of ``new`` can
    find a better optimum of the parameters the models share (a terrace of the
    stick-slip cost), and that gain is the current model's, not the effect's.  Measured
    on the four ECP records: a motor lag fitted at ``tau`` = 2e-14 s (no lag) gained
    21 538 nats in sample and 18 541 held out over the friction + dead band fit it
    started from.  Returns ``(theta, pointwise)`` of the reference."""
    try:
        th = ext.check(rig, _restricted(new, f.theta, ext, rig))
    except ModelError:
        return fit.theta, cur_pw
    with np.errstate(all="ignore"):
        pw = _lpd(exps, _simulate(ext, rig, th, exps))
    crit = criterion_for(exps)
    if np.all(np.isfinite(pw)) and crit.total(pw) > crit.total(cur_pw):
        return th, pw
    return fit.theta, cur_pw


def _in_sample(new, f, rig, exps, cur_pw, k, level):
    """``(gain, LR, p-value, BIC gain, significant)`` of the fit ``f`` of ``new`` over the
    current model (pointwise scores ``cur_pw``), ``k`` added parameters: the records'
    criterion (``criterion_for``) and its test (``Criterion.test``)."""
    with np.errstate(all="ignore"):
        pw = _lpd(exps, _simulate(new, rig, f.theta, exps))
    return criterion_for(exps).test(pw, cur_pw, k, _shapes(exps), level)


def _lr_keeps(cur, fit, simple, f, rig, exps, level) -> bool:
    """Does ``cur`` (at ``fit``) gain significantly over the nested ``simple`` (at ``f``)?
    The forward steps' in-sample rule at ``level`` (``Criterion.test``)."""
    k = len(cur.specs(rig)) - len(simple.specs(rig))
    simple_pw = _lpd(exps, _simulate(simple, rig, f.theta, exps))
    return _in_sample(cur, fit, rig, exps, simple_pw, k, level)[-1]
