"""PSIS-LOO and WAIC: the information criteria of one run, and the ELPD change of two.

From the pointwise log-likelihood of the fitted data (the ``log_likelihood`` group of a
run's InferenceData, ArviZ's ``loo`` and ``waic``).  The rig records are autocorrelated
time series; leaving one sample out is then only an approximation of predictive
performance (neighbouring samples carry most of the left-out information).  With the
AR(1) likelihood the pointwise terms are the conditional innovation densities
``p(r_k | r_{k-1})``, which are the natural one-step-ahead units.
:mod:`bayesmodal.inference.compare` puts these criteria beside the evidence and the
predictive check.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .idata import arviz, to_inference_data, with_pointwise_loglik

__all__ = ["InformationCriteria", "information_criteria", "ElpdChange", "elpd_change"]


# ----------------------------------------------------------------------------- LOO / WAIC
@dataclass(frozen=True)
class InformationCriteria:
    """PSIS-LOO and WAIC of one fitted model (log scale: larger is better).

    Attributes
    ----------
    elpd_loo, se_loo, p_loo : float
        Expected log pointwise predictive density, its standard error, and the effective
        number of parameters.
    elpd_waic, se_waic, p_waic : float
    max_pareto_k : float
        Largest Pareto shape of the PSIS weights.
    n_bad_k : int
        Observations with ``k > 0.7`` (PSIS unreliable for them).
    n_obs : int
    notes : tuple of str
        Warnings issued by ArviZ while computing (kept, not shown as warnings).
    """

    elpd_loo: float
    se_loo: float
    p_loo: float
    elpd_waic: float
    se_waic: float
    p_waic: float
    max_pareto_k: float
    n_bad_k: int
    n_obs: int
    notes: tuple[str, ...] = ()


def _recorded(fn, *args, **kwargs):
    """Call ``fn`` and return (result, tuple of warning messages it raised)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args, **kwargs)
    return out, tuple(dict.fromkeys(str(w.message).strip() for w in caught))


def information_criteria(idata) -> InformationCriteria:
    """PSIS-LOO and WAIC from the ``log_likelihood`` group (variable ``y``).

    ArviZ's warnings (large Pareto k, WAIC variance) are recorded in ``notes`` and
    summarised by ``max_pareto_k`` / ``n_bad_k`` rather than raised.  A run saved without
    the group (``pointwise=False``) has it rebuilt from its draws
    (:func:`~.idata.with_pointwise_loglik`).
    """
    az = arviz()
    idata = _as_idata(idata)
    loo, n1 = _recorded(az.loo, idata, pointwise=True, var_name="y")
    waic, n2 = _recorded(az.waic, idata, var_name="y")
    k = np.asarray(loo.pareto_k).ravel()
    return InformationCriteria(
        elpd_loo=float(loo.elpd_loo),
        se_loo=float(loo.se),
        p_loo=float(loo.p_loo),
        elpd_waic=float(waic.elpd_waic),
        se_waic=float(waic.se),
        p_waic=float(waic.p_waic),
        max_pareto_k=float(np.max(k)),
        n_bad_k=int(np.sum(k > 0.7)),
        n_obs=int(k.size),
        notes=n1 + n2,
    )


# ----------------------------------------------------------------------------- ELPD change
@dataclass(frozen=True)
class ElpdChange:
    """Change in PSIS-LOO ELPD from a base model to another model on the same data.

    Attributes
    ----------
    base, other : str
        Labels of the two models (e.g. ``"linear"``, ``"coulomb_friction"``).
    elpd_base, elpd_other : float
        PSIS-LOO expected log pointwise predictive densities, nats.
    se_base, se_other : float
        Their standard errors, nats.
    delta : float
        ``elpd_other - elpd_base``, nats (positive: the other model predicts better).
    se : float
        Standard error of ``delta`` from the paired pointwise differences,
        ``sqrt(n var_i(elpd_other_i - elpd_base_i))`` (as ``arviz.compare``'s ``dse``).
    z : float
        ``delta / se``.
    decisive : bool
        ``|delta| >= min_delta`` and ``|z| >= min_z``: the difference is both larger than
        what Monte Carlo and model-size effects produce and several standard errors.
    preferred : str
        The model with the higher ELPD when ``decisive``, else ``"neither"``.
    reading : str
        The result in plain words.
    max_pareto_k : float
        Largest Pareto shape over both runs (PSIS is unreliable above 0.7).
    n_bad_k : int
        Pointwise terms with Pareto shape above 0.7 in either run.
    n_obs : int
        Pointwise terms (samples times outputs).
    """

    base: str
    other: str
    elpd_base: float
    elpd_other: float
    se_base: float
    se_other: float
    delta: float
    se: float
    z: float
    decisive: bool
    preferred: str
    reading: str
    max_pareto_k: float
    n_bad_k: int
    n_obs: int

    def as_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v)
                for k, v in self.__dict__.items()}


def _as_idata(run_or_idata):
    if hasattr(run_or_idata, "groups"):
        return with_pointwise_loglik(run_or_idata)

    return to_inference_data(run_or_idata, n_predictive=0)


def elpd_change(
    base,
    other,
    *,
    labels: tuple[str, str] | None = None,
    min_delta: float = 4.0,
    min_z: float = 2.0,
) -> ElpdChange:
    """Change in a Bayesian criterion (PSIS-LOO ELPD) between two runs on the same data.

    Parameters
    ----------
    base, other : InferenceData or PosteriorRun
        Two posterior runs on the same experiments (e.g. the linear model and an
        extended one).  InferenceData needs the ``log_likelihood`` group; a
        ``PosteriorRun`` is converted with ``to_inference_data(run, n_predictive=0)``.
    labels : tuple of str, optional
        Names of the two models; default from the runs' ``extension`` attribute
        (``"linear"`` for none).
    min_delta : float
        Smallest ``|delta|`` (nats) called decisive; below about 4 nats PSIS-LOO
        differences are within what noise and the number of parameters produce.
    min_z : float
        Smallest ``|delta| / se`` called decisive.

    Returns
    -------
    ElpdChange

    Raises
    ------
    ConfigError
        When the runs were not fitted to the same observations.

    Notes
    -----
    With the AR(1) likelihood each pointwise term is a one-step-ahead innovation density,
    so the ELPD scores one-step predictions of the records; the standard error treats the
    terms as exchangeable, which the residual autocorrelation makes optimistic when the
    noise model is white (see ``docs/inference.md``).
    """
    az = arviz()
    ia, ib = _as_idata(base), _as_idata(other)
    ya, yb = ia.observed_data["y"].values, ib.observed_data["y"].values
    if ya.shape != yb.shape or not np.array_equal(ya, yb):
        raise ConfigError("the two runs were not fitted to the same observations "
                          f"(shapes {ya.shape} and {yb.shape}); ELPD differences need one "
                          "data set")
    if labels is None:
        labels = tuple(str(i.posterior.attrs.get("extension", "")) or "linear"
                       for i in (ia, ib))
        if labels[0] == labels[1]:
            labels = (labels[0] + " (base)", labels[1] + " (other)")
    la, lb = labels
    (loo_a, na), (loo_b, nb) = (_recorded(az.loo, i, pointwise=True, var_name="y")
                                for i in (ia, ib))
    pa = np.asarray(loo_a.loo_i).ravel()
    pb = np.asarray(loo_b.loo_i).ravel()
    d = pb - pa
    delta = float(np.sum(d))
    se = float(np.sqrt(d.size * np.var(d)))
    z = delta / se if se > 0 else math.copysign(math.inf, delta) if delta else 0.0
    decisive = bool(abs(delta) >= min_delta and abs(z) >= min_z)
    preferred = (lb if delta > 0 else la) if decisive else "neither"
    ka, kb = np.asarray(loo_a.pareto_k).ravel(), np.asarray(loo_b.pareto_k).ravel()
    k = max(float(np.max(ka)), float(np.max(kb)))
    n_bad = int(np.sum((ka > 0.7) | (kb > 0.7)))
    if decisive:
        words = (f"The {preferred} model predicts the data decisively better: ELPD "
                 f"{'higher' if delta > 0 else 'lower'} by {abs(delta):.1f} nats for "
                 f"{lb} than for {la}, {abs(z):.1f} standard errors ({se:.1f} nats).")
    else:
        words = (f"No decisive difference: the ELPD of {lb} minus that of {la} is "
                 f"{delta:+.1f} +- {se:.1f} nats ({z:+.1f} standard errors; decisive needs "
                 f"at least {min_delta:g} nats and {min_z:g} standard errors).")
    if k > 0.7:
        words += (f" {n_bad} of {d.size} Pareto k exceed 0.7 (max {k:.2f}): PSIS-LOO is "
                  "unreliable for those samples.")
    return ElpdChange(
        base=la, other=lb,
        elpd_base=float(loo_a.elpd_loo), elpd_other=float(loo_b.elpd_loo),
        se_base=float(loo_a.se), se_other=float(loo_b.se),
        delta=delta, se=se, z=float(z), decisive=decisive, preferred=preferred,
        reading=words, max_pareto_k=k, n_bad_k=n_bad, n_obs=int(d.size),
    )
