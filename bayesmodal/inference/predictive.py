"""Predicting a record the posterior has not seen, and scoring the prediction.

A new record of the rig is predicted with the parameters it shares with the training
records and, for its own per-record parameters, with values it does not know yet: a
hierarchical parameter is drawn from its population (``log p_new ~ N(log mu_p, tau_p^2)``,
or normal for the input offset), an independent one is the value of a training record
drawn at random, and noise parameters that are per record likewise.  Each posterior draw
thus gives a noise-free prediction ``yhat_s`` and, with a draw from its noise model, a
predictive sample ``y_s = yhat_s + e_s``.

Scores per output (:class:`PredictiveScores`):

- ``fit_percent`` of the predictive median (``bayesmodal.metrics.fit_percent``);
- ``coverage_50``, ``coverage_90``: fraction of the record's samples inside the central
  50 % and 90 % bands of the predictive samples (pointwise quantiles);
- ``width_90``: mean width of the 90 % band divided by the record's standard deviation;
- ``band_factor_90``: the factor by which the 90 % band's two half-widths (median to
  5 % and to 95 % quantile) must be multiplied for the band to cover exactly 90 % of the
  record's samples: 1 for a calibrated band, above 1 when it under-covers, below 1 when
  it over-covers (the width an honest band of this record would have is
  ``band_factor_90 * width_90``);
- ``crps``: the continuous ranked probability score of the predictive ensemble, averaged
  over samples, divided by the record's standard deviation (0 is perfect; a point
  forecast with no spread scores its mean absolute error), from the sorted-ensemble form
  ``CRPS = mean|Y - y| - 1/2 mean|Y - Y'|``;
- ``reference``: what coverage and band factor a *calibrated* band would show on a
  record like this one, from the ensemble scored against itself
  (:mod:`.coverage_reference`): ``coverage_90_expected`` (the central 90 % range),
  ``coverage_90_pit`` (the record's rank in it), ``band_factor_90_expected``,
  ``band_factor_90_pit``, ``record_pit_90``, ``record_band_factor_pit_90`` and
  ``window_probability_90``;
- ``lpd``: the log predictive density of the whole record (all outputs),
  ``log mean_s p(y | theta_s, new-record draws)``, with its Monte Carlo standard error
  (delta method on the mean of the likelihood ratios).  Per-record parameters drawn from
  a population make this an importance estimate whose error the SE shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from .._errors import DataError
from ..data import Experiment
from ..metrics import fit_percent
from .coverage_reference import (
    MIN_REFERENCE_DRAWS,
    CoverageReference,
    coverage_reference,
    reference_fields,
)
from .noise import kalman_loglik, simulate_process_noise
from .record_layout import SIGNED

__all__ = ["PredictiveScores", "band_factor", "new_record_parameters", "predict_new_record",
           "score_samples", "crps_ensemble"]


@dataclass(frozen=True)
class PredictiveScores:
    """Scores of a predictive ensemble against a record.

    Attributes
    ----------
    name : str
    fit_percent, coverage_50, coverage_90, width_90, crps : ndarray, shape (n_out,)
        See the module docstring (coverages as fractions, width and CRPS relative to the
        record's standard deviation per output).
    band_factor_90 : ndarray, shape (n_out,)
        Scale of the 90 % band about its median that covers 90 % of the record.
    reference : CoverageReference or None
        The coverages a calibrated band would show on such a record (None below
        :data:`~.coverage_reference.MIN_REFERENCE_DRAWS` draws).
    lpd : float
        Log predictive density of the record, nats.
    lpd_se : float
        Monte Carlo standard error of ``lpd``, nats.
    n_draws : int
    """

    name: str
    fit_percent: np.ndarray
    coverage_50: np.ndarray
    coverage_90: np.ndarray
    width_90: np.ndarray
    crps: np.ndarray
    lpd: float
    lpd_se: float
    n_draws: int
    band_factor_90: np.ndarray | None = None
    reference: CoverageReference | None = None

    def reference_dict(self) -> dict:
        """The reference in ``summary.json`` form ({} without one;
        :func:`~.coverage_reference.reference_fields`)."""
        if self.reference is None:
            return {}
        return reference_fields(self.reference, {0.5: self.coverage_50, 0.9: self.coverage_90},
                                self.band_factor_90)

    def to_dict(self) -> dict:
        keys = ("fit_percent", "coverage_50", "coverage_90", "width_90", "crps",
                "band_factor_90")
        return {"name": self.name,
                **{k: np.asarray(getattr(self, k)).tolist() for k in keys
                   if getattr(self, k) is not None},
                **self.reference_dict(),
                "lpd": self.lpd, "lpd_se": self.lpd_se, "n_draws": self.n_draws}


def crps_ensemble(samples: np.ndarray, y: np.ndarray) -> np.ndarray:
    """CRPS of an ensemble forecast, pointwise.

    Parameters
    ----------
    samples : ndarray, shape (S, ...)
        Ensemble members.
    y : ndarray, shape (...)
        Observation.

    Returns
    -------
    ndarray, shape (...)
        ``mean_i |x_i - y| - 1/(2 S^2) sum_ij |x_i - x_j|``; the pair sum is
        ``2 sum_i (2 i - S - 1) x_(i)`` over the sorted members (1-based ``i``).

    Examples
    --------
    A one-member ensemble scores its absolute error:

    >>> float(crps_ensemble(np.array([[1.0]]), np.array([3.0]))[0])
    2.0
    """
    x = np.sort(np.asarray(samples, dtype=float), axis=0)
    s = x.shape[0]
    first = np.mean(np.abs(x - y[None]), axis=0)
    w = (2 * np.arange(1, s + 1) - s - 1).reshape((s,) + (1,) * (x.ndim - 1))
    pair = 2.0 * np.sum(w * x, axis=0) / s**2
    return first - 0.5 * pair


def new_record_parameters(lik, theta: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """Parameters of a record not seen in training, one set per posterior draw.

    Parameters
    ----------
    lik : Likelihood
        The training likelihood.
    theta : ndarray, shape (S, P)
        Posterior draws.
    rng : numpy.random.Generator

    Returns
    -------
    mech : ndarray, shape (S, n_mech)
    v0 : ndarray, shape (S,), V
    noise : ndarray, shape (S, n_noise)
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    s = theta.shape[0]
    if lik.layout is None:  # one parameter set for every record
        mech, sigma, phi = lik.split(theta)
        noise = sigma if phi is None else np.concatenate([sigma, phi], axis=1)
        return mech, np.zeros(s), noise
    n_mech = len(lik.mech_names)
    # start from a random training record's own parameters, then redraw the hierarchical
    pick = rng.integers(lik.n_records, size=s)
    full = np.empty((s, n_mech + len(lik._index["noise"][0])))
    v0 = np.zeros(s)
    for r in range(lik.n_records):
        sel = pick == r
        if np.any(sel):
            f, v = lik.record_theta(theta[sel], r)
            full[sel], v0[sel] = f, v
    for p, kind in lik.layout.kinds:
        if kind != "hierarchical":
            continue
        mu, tau = lik.population(theta, p)
        z = rng.standard_normal(s)
        value = mu + tau * z if p in SIGNED else mu * np.exp(tau * z)
        if p == "v0":
            v0 = value
        else:
            full[:, lik.mech_names.index(p)] = value
    return full[:, :n_mech], v0, full[:, n_mech:]


def predict_new_record(lik, theta: np.ndarray, experiment: Experiment, *, rng=None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predictive samples of a record from posterior draws of other records.

    Parameters
    ----------
    lik : Likelihood
        The likelihood the draws were sampled with.
    theta : ndarray, shape (S, P)
    experiment : Experiment
        Its input and sample interval are used, and its outputs for the log density.
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    y_hat : ndarray, shape (S, N, n_out)
        Noise-free predictions, m.
    y_pred : ndarray, shape (S, N, n_out)
        Predictive samples (prediction plus a draw of the noise model), m.  AR(1) noise
        is drawn conditioned on the record's first residual (its known start at rest),
        other noise models from their stationary start.
    loglik : ndarray, shape (S,)
        ``log p(y | draw s)`` of the record under each draw, nats.
    """
    rng = np.random.default_rng(rng)
    if experiment.n_outputs != lik.n_outputs:
        raise DataError(f"{experiment.name}: {experiment.n_outputs} outputs, the model has "
                        f"{lik.n_outputs}")
    mech, v0, noise = new_record_parameters(lik, theta, rng)
    y_hat = lik.predict_mech(mech, v0, experiment)
    R = experiment.y_m[:, :, None] - np.moveaxis(y_hat, 0, -1)
    if getattr(lik, "noise", "") == "process":  # the random force goes through the dynamics
        n = lik.n_outputs
        q, sig = noise[:, :n], noise[:, n:]
        y_pred = simulate_process_noise(lik.model, mech, q, sig, experiment.v_volt,
                                        experiment.dt, rng, v0=v0)
        ll = kalman_loglik(lik.model, mech, q, sig, experiment.v_volt, experiment.y_m,
                           experiment.dt, initial="rest", v0=v0)
        return y_hat, y_pred, np.where(np.isfinite(ll), ll, -np.inf)
    # AR(1): the draws start from the record's known first residual (records start at
    # rest, where model and rig agree: 0 on the ECP files), not from the stationary
    # spread, which is unbounded for phi at 1 (a random-walk discrepancy; the friction
    # model's posterior puts a third of its draws above phi = 0.99999)
    start = R[0].T if lik.noise == "ar1" else None
    # (with noise_scale "response": the level sized by the record's simulated response)
    s = lik.scale_of(experiment, theta)
    e = lik.noise_simulate(noise, experiment.n_samples, rng, s, start, record=experiment)
    with np.errstate(all="ignore"):
        ll = lik.noise_loglik(R, noise, s, record=experiment)
    return y_hat, y_hat + e, np.where(np.isfinite(ll), ll, -np.inf)


def score_samples(name: str, y: np.ndarray, y_pred: np.ndarray, loglik: np.ndarray
                  ) -> PredictiveScores:
    """Scores of predictive samples ``y_pred`` (S, N, n_out) against ``y`` (N, n_out).

    With at least ``MIN_REFERENCE_DRAWS`` draws the scores carry the ensemble's coverage
    reference (:func:`~bayesmodal.inference.coverage_reference.coverage_reference`)."""
    q = np.quantile(y_pred, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    sd = np.std(y, axis=0)
    cov50 = np.mean((y >= q[1]) & (y <= q[3]), axis=0)
    cov90 = np.mean((y >= q[0]) & (y <= q[4]), axis=0)
    width = np.mean(q[4] - q[0], axis=0) / sd
    crps = np.mean(crps_ensemble(y_pred, y), axis=0) / sd
    s = loglik.size
    lpd = float(logsumexp(loglik) - np.log(s))
    w = np.exp(loglik - np.max(loglik))
    # delta method: se(log mean w) = sd(w) / (sqrt(S) mean(w))
    lpd_se = float(np.std(w, ddof=1) / (np.sqrt(s) * np.mean(w))) if s > 1 else float("nan")
    ref = coverage_reference(y_pred) if y_pred.shape[0] >= MIN_REFERENCE_DRAWS else None
    return PredictiveScores(name, fit_percent(y, q[2]), cov50, cov90, width, crps, lpd,
                            lpd_se, int(s), band_factor(y, q[0], q[2], q[4]), ref)


def band_factor(y: np.ndarray, lower: np.ndarray, median: np.ndarray, upper: np.ndarray,
                prob: float = 0.9) -> np.ndarray:
    """Scale of a band about its median that covers ``prob`` of the observations.

    Parameters
    ----------
    y, lower, median, upper : ndarray, shape (N, n_out)
        Observations and the band's lower edge, centre and upper edge per sample.
    prob : float
        Coverage the scaled band is to reach.

    Returns
    -------
    ndarray, shape (n_out,)
        The smallest ``c`` with ``median - c (median - lower) <= y <= median + c (upper -
        median)`` for a fraction ``prob`` of the samples (the ``prob`` quantile of each
        sample's own factor ``(y - median) / (upper - median)`` above the centre,
        ``(median - y) / (median - lower)`` below it).  A band of zero half-width needs an
        infinite factor wherever ``y`` is off its centre.

    Examples
    --------
    Observations 0.5, 1 and 2 half-widths off the centre: the band must be kept at its
    width (``c = 1``) to hold at least half of them:

    >>> y = np.array([[0.5], [-1.0], [2.0]])
    >>> z, one = np.zeros((3, 1)), np.ones((3, 1))
    >>> float(band_factor(y, -one, z, one, prob=0.5)[0])
    1.0
    """
    y, lower, median, upper = (np.asarray(a, dtype=float) for a in (y, lower, median, upper))
    up, down = upper - median, median - lower
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(y >= median, (y - median) / up, (median - y) / down)
    need = np.where(y == median, 0.0, need)   # on the centre: inside any band
    return np.quantile(need, prob, axis=0, method="inverted_cdf")
