"""The residuals and weights of the least-squares cost, shared by every layout of
:func:`bayesmodal.fit.fit_lsq`.

A model with effects is simulated by its extension (``Extension.simulate``); the linear
free-damping model of a several-record fit by the effects' kernel with no effect
(``simulate_model``), so that it and its extensions run the same arithmetic.  Records
weigh by a number each (``experiment_weights``: all 1, given numbers, or ``"spread"``,
:func:`record_weights`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..model.effects._base import Extension
from ..model.effects._input import linear_lanes_run
from ..model.system import LinearModel, Rig
from .linear import barrier_residuals

__all__ = ["extension_residuals", "admissible_residuals", "extension_cost", "WEIGHTINGS",
           "record_weights", "root_weights", "experiment_weights", "simulate_model",
           "new_record_theta"]


def extension_residuals(
    extension: Extension, rig: Rig, theta: np.ndarray, experiments: Sequence[Experiment]
) -> np.ndarray:
    """Stacked residuals ``y - yhat`` for a batch of parameter sets.

    Parameters
    ----------
    extension : Extension
    rig : Rig
    theta : ndarray, shape (nb, n_params)
    experiments : sequence of Experiment

    Returns
    -------
    ndarray, shape (nb, sum_e N_e * n_outputs), m
    """
    parts = []
    for e in experiments:
        yh = extension.simulate(rig, theta, e.v_volt, e.dt)
        parts.append((e.y_m[None] - yh).reshape(theta.shape[0], -1))
    return np.concatenate(parts, axis=1)


def admissible_residuals(
    extension: Extension, rig: Rig, theta: np.ndarray, experiments: Sequence[Experiment]
) -> np.ndarray:
    """``extension_residuals`` where a parameter set is admissible, and a barrier elsewhere.

    A trial point of the least-squares fit outside the admissible region (a rule across
    parameters that the optimiser's box cannot state, e.g. backlash's ``m_p < m1``) gets
    ``bayesmodal.fit.barrier_residuals``, a cost far above any fit's: the trust region
    shrinks instead of the fit stopping with an error (measured inside
    forward selection, pair benchmark seed 20002).

    Parameters
    ----------
    extension : Extension
    rig : Rig
    theta : ndarray, shape (nb, n_params) or (n_params,)
    experiments : sequence of Experiment

    Returns
    -------
    ndarray, shape (nb, sum_e N_e * n_outputs), m
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    ok = extension.valid(rig, theta)
    r = barrier_residuals(experiments, theta.shape[0])
    if np.any(ok):
        r[ok] = extension_residuals(extension, rig, theta[ok], experiments)
    return r


def extension_cost(
    extension: Extension, rig: Rig, theta: np.ndarray, experiments: Sequence[Experiment],
    weights: Sequence[float] | str | None = None,
) -> np.ndarray:
    """The cost ``fit_extension_lsq`` minimises: half the weighted sum of squared residuals.

    Parameters
    ----------
    extension : Extension
    rig : Rig
    theta : ndarray, shape (nb, n_params)
    experiments : sequence of Experiment
    weights : sequence of float or "spread", optional
        One non-negative weight per experiment (default all 1), or ``"spread"``
        (:func:`record_weights`).

    Returns
    -------
    ndarray, shape (nb,), m^2
        ``0.5 * sum_e w_e * sum_k |y_e,k - yhat_e,k(theta)|^2``.
    """
    experiments = as_list(experiments)
    w = experiment_weights(weights, experiments)
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    total = np.zeros(theta.shape[0])
    for we, e in zip(w, experiments, strict=True):
        r = e.y_m[None] - extension.simulate(rig, theta, e.v_volt, e.dt)
        total += 0.5 * we * np.sum(r**2, axis=(1, 2))
    return total


#: Named weightings of several records in a least-squares cost (``weights=``); see
#: :func:`record_weights`.
WEIGHTINGS = ("spread",)


def record_weights(experiments: Experiment | Sequence[Experiment]) -> np.ndarray:
    """The ``"spread"`` weighting: each record weighs as much as the others in the cost.

    A record's weight is the inverse of its spread, the sum over its outputs and samples
    of the squared deviation of the measured positions from their means, times the mean
    spread of the records: ``w_r = mean_q S_q / S_r`` with ``S_r = sum_j |y_rj - mean
    y_rj|^2``.  The weighted cost is then a sum over records of ``(1 - fit_r / 100)^2``
    (the pooled fit percentage of each record, times the mean spread), where the
    unweighted cost weighs each record's ``(1 - fit_r / 100)^2`` by its spread ``S_r``:
    on the ECP records the steps (held away from rest for seconds) have 4-5 times the
    spread of a pulse of the impulses and 5-7 times that of a sweep.  One record gets
    weight 1 exactly (the unweighted cost).

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment

    Returns
    -------
    ndarray, shape (n_records,)
        Positive weights with mean spread ``sum_r w_r S_r / n = mean S``.

    Raises
    ------
    DataError
        For a record whose positions do not move (spread 0).
    """
    experiments = as_list(experiments)
    spread = np.array([float(np.sum((e.y_m - e.y_m.mean(axis=0)) ** 2)) for e in experiments])
    flat = [e.name for e, s in zip(experiments, spread, strict=True) if not s > 0.0]
    if flat:
        raise DataError(f"{flat[0]}: the positions do not move, so the record has no "
                        "spread to weigh it by; leave it out or pass weights=None")
    if len(experiments) == 1:
        return np.ones(1)
    return float(np.mean(spread)) / spread


def root_weights(weights, experiments: Sequence[Experiment]) -> np.ndarray | None:
    """Square roots of the records' weights, one per stacked residual.

    Parameters
    ----------
    weights : None, "spread" or sequence of float
        As in :func:`experiment_weights`; None for unweighted.
    experiments : sequence of Experiment

    Returns
    -------
    ndarray, shape (sum_e N_e * n_outputs,), or None
        In the layout of :func:`extension_residuals` (each record's samples times
        outputs in turn); None for ``weights`` None.
    """
    if weights is None:
        return None
    return np.repeat(np.sqrt(experiment_weights(weights, experiments)),
                     [e.n_samples * e.n_outputs for e in experiments])


def experiment_weights(weights, experiments: Sequence[Experiment]) -> np.ndarray:
    """The weight of each experiment in a least-squares cost.

    Parameters
    ----------
    weights : None, "spread" or sequence of float
        None: all 1; ``"spread"``: :func:`record_weights`; else one per experiment.
    experiments : sequence of Experiment

    Returns
    -------
    ndarray, shape (n_experiments,)

    Raises
    ------
    ConfigError
        For an unknown weighting or unusable numbers.
    """
    if weights is None:
        return np.ones(len(experiments))
    if isinstance(weights, str):
        if weights not in WEIGHTINGS:
            raise ConfigError(f"weights: unknown weighting {weights!r}; use one of "
                              f"{WEIGHTINGS} or one number per experiment")
        return record_weights(experiments)
    w = np.asarray(weights, dtype=float)
    if w.shape != (len(experiments),):
        raise ConfigError(f"weights: need one per experiment ({len(experiments)}), got "
                          f"shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise ConfigError(f"weights must be finite, non-negative and not all zero, got "
                          f"{w.tolist()}")
    return w


def as_list(experiments) -> list[Experiment]:
    """``experiments`` as a list (one Experiment: a list of one); DataError if empty."""
    if isinstance(experiments, Experiment):
        return [experiments]
    experiments = list(experiments)
    if not experiments:
        raise DataError("no experiments given")
    return experiments


def model_names(ext: Extension | None, rig: Rig) -> tuple[str, ...]:
    """Parameter names of ``ext`` on ``rig`` (None: the linear free-damping model's)."""
    return LinearModel(rig, "free").names if ext is None else ext.names(rig)


def simulate_model(ext: Extension | None, rig: Rig, theta: np.ndarray, e: Experiment
                   ) -> np.ndarray:
    """Cart positions of one record for a batch of parameter sets.

    Parameters
    ----------
    ext : Extension or None
        None for the linear free-damping model (run by the effects' kernel with no
        effect).
    rig : Rig
    theta : ndarray, shape (nb, n_params)
    e : Experiment
        The record (its input and sample interval).

    Returns
    -------
    ndarray, shape (nb, N, n_outputs), m
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    if ext is not None:
        return ext.simulate(rig, theta, e.v_volt, e.dt)
    model = LinearModel(rig, "free")
    if not np.all(model.valid(theta)):
        raise ModelError("linear model: impossible parameters (masses and dampers must be "
                         "positive, relative dampers >= 0)")
    x0 = np.zeros((theta.shape[0], 2 * rig.n_carts))
    return linear_lanes_run(rig, np.ascontiguousarray(theta), np.asarray(e.v_volt, float),
                            float(e.dt), x0)


def new_record_theta(theta: np.ndarray, names: Sequence[str], per_record: Sequence[str]
                     ) -> np.ndarray:
    """The parameter vector of a record not in the fit.

    Per-record parameters are averaged over the fitted records: geometrically for
    ``g_v`` (a positive scale), arithmetically otherwise.

    Parameters
    ----------
    theta : ndarray, shape (n_records, n_params)
    names : sequence of str
    per_record : sequence of str

    Returns
    -------
    ndarray, shape (n_params,)
    """
    theta = np.asarray(theta, dtype=float)
    out = theta[0].copy()
    for p in per_record:
        i = list(names).index(p)
        col = theta[:, i]
        out[i] = np.exp(np.mean(np.log(col))) if p == "g_v" else np.mean(col)
    return out


def default_per_record(names) -> tuple[str, ...]:
    """The per-record parameters by default: ``g_v``, and ``v_offset`` if in ``names``."""
    return ("g_v",) + (("v_offset",) if "v_offset" in names else ())


