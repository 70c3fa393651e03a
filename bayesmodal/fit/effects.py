"""Output-error least squares of an extended model, started from the linear fit.

The linear parameters are optimised as in ``bayesmodal.fit.fit_lsq`` (log scale for
``g_v``, the masses and the absolute dampers; linear with a zero bound for the relative
dampers), the extension parameters in the extension's own optimiser coordinates
(``Extension.to_opt``), each scaled by its typical size so that unit steps are comparable.

Stick-slip friction and backlash make the cost piecewise smooth with small jumps (a cart
sticks one sub-step earlier or later), so the start matters and the finite-difference steps
must be larger than the jumps: the extension parameters are started from the best point of
a batched grid (``Extension.start_grid``, evaluated with the linear fit) and
differentiated with relative steps of ``fd_step`` (default 1e-3, against about 1e-7 for a
smooth cost).

Several local optima.  Friction and viscous damping both take energy out of the free
decay, and on an impulse record they trade against each other: started from the linear
fit (whose dampers carry all the dissipation) the optimiser stops in whichever basin is
nearest, and on the ECP impulse record these basins differ by 25 % in cost and by 15
points in their prediction of the steps record (docs/discrepancy.md).  The grid can
therefore be crossed with starts whose dampers are scaled down (``damper_scales``, e.g.
``(1.0, 0.3, 0.1)``), the whole cross product is evaluated in one batch, and the local fit
run from the ``n_starts`` best candidates; the lowest final cost wins.  The defaults (one
start, the linear dampers) keep the fit as cheap as a single local search.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..metrics import fit_percent
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig, damper_mask
from ._lsq_common import check_outputs, coordinates, fd_jacobian, solve
from .linear import LSQResult, barrier_residuals, fit_lsq

__all__ = ["ExtensionFit", "fit_extension_lsq", "extension_fit_at", "extension_residuals",
           "extension_cost", "record_weights", "experiment_weights", "root_weights",
           "WEIGHTINGS"]


@dataclass(frozen=True)
class ExtensionFit:
    """Least-squares fit of an extended model.

    Attributes
    ----------
    extension : Extension
    rig : Rig
    theta : ndarray, shape (n_params,)
        Estimate in ``extension.names(rig)`` order (linear parameters first).
    fit_percent : ndarray, shape (n_experiments, n_outputs)
        Fit percentage per experiment and output.
    cost : float
        Half the sum of squared residuals (weighted by ``weights`` if given), m^2.
    sigma_m : ndarray, shape (n_outputs,)
        RMS residual per output, pooled over experiments, m.
    linear : LSQResult
        The linear fit the extension was started from.
    theta_start : ndarray, shape (n_params,)
        The starting point chosen from the grid.
    success : bool
    message : str
    n_evaluations : int
        Residual evaluations of the optimiser (each Jacobian is one batched call).
    """

    extension: Extension
    rig: Rig
    theta: np.ndarray
    fit_percent: np.ndarray
    cost: float
    sigma_m: np.ndarray
    linear: LSQResult
    theta_start: np.ndarray
    success: bool
    message: str
    n_evaluations: int

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, linear first."""
        return self.extension.names(self.rig)

    @property
    def params(self) -> dict[str, float]:
        """Estimate as a name-to-value mapping."""
        return self.extension.as_dict(self.rig, self.theta)

    @property
    def improvement_percent(self) -> np.ndarray:
        """Fit percentage gained over the linear fit, shape (n_experiments, n_outputs)."""
        return self.fit_percent - self.linear.fit_percent


def extension_residuals(
    extension: Extension, rig: Rig, theta: np.ndarray, experiments: Sequence[Experiment]
) -> np.ndarray:
    """Stacked residuals ``y - yhat`` for a batch of parameter sets.

    Parameters
    ----------
    theta : ndarray, shape (nb, n_params)

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
    forward selection, pair benchmark seed 20002).  Arguments, shapes and units as
    :func:`extension_residuals`.
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
    experiments = _as_list(experiments)
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
    experiments = _as_list(experiments)
    spread = np.array([float(np.sum((e.y_m - e.y_m.mean(axis=0)) ** 2)) for e in experiments])
    flat = [e.name for e, s in zip(experiments, spread, strict=True) if not s > 0.0]
    if flat:
        raise DataError(f"{flat[0]}: the positions do not move, so the record has no "
                        "spread to weigh it by; leave it out or pass weights=None")
    if len(experiments) == 1:
        return np.ones(1)
    return float(np.mean(spread)) / spread


def root_weights(weights, experiments: Sequence[Experiment]) -> np.ndarray | None:
    """Square roots of the records' weights, one per stacked residual (the layout of
    :func:`extension_residuals`: each record's samples times outputs in turn); None for
    ``weights`` None (unweighted)."""
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


def _as_list(experiments) -> list[Experiment]:
    if isinstance(experiments, Experiment):
        return [experiments]
    experiments = list(experiments)
    if not experiments:
        raise DataError("no experiments given")
    return experiments


def fit_extension_lsq(
    experiments: Experiment | Sequence[Experiment],
    ext: Extension,
    rig: Rig | None = None,
    theta0: np.ndarray | None = None,
    *,
    linear: LSQResult | None = None,
    fd_step: float = 1e-3,
    max_nfev: int = 200,
    n_starts: int = 1,
    damper_scales: Sequence[float] = (1.0,),
    weights: Sequence[float] | str | None = None,
) -> ExtensionFit:
    """Least-squares fit of an extended model.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    ext : Extension
        E.g. ``EXTENSIONS["coulomb_friction"]``.
    rig : Rig, optional
        Default ``Rig()`` (the ECP 210 springs).
    theta0 : ndarray, shape (n_params,), optional
        Full starting vector.  By default the linear parameters come from ``linear`` (or a
        fresh ``fit_lsq`` with free damping) and the extension parameters from the best
        point of ``ext.start_grid(rig)``.
    linear : LSQResult, optional
        A linear free-damping fit to the same experiments (saves refitting it).
    fd_step : float
        Forward-difference step in scaled optimiser coordinates (dimensionless; the
        extension parameters are scaled by their typical size ``ParamSpec.scale``).
    max_nfev : int
        Maximum number of residual evaluations (per start).
    n_starts : int
        Local fits run from the best ``n_starts`` grid candidates (ignored with
        ``theta0``); the lowest final cost is returned.
    damper_scales : sequence of float
        Factors applied to the linear fit's dampers in the start candidates (each grid
        point is tried with each factor); ``(1.0,)`` keeps the linear dampers, ``(1.0,
        0.3, 0.1)`` lets friction take over part of the viscous damping from the start.
    weights : sequence of float or "spread", optional
        Weight of each experiment's squared residuals in the cost (default all 1), e.g.
        ``(1.0, 0.1)`` to trace how far a second record can pull the fit before the first
        one's fit degrades, or ``"spread"`` (:func:`record_weights`: every record weighs
        as much as the others).  Non-negative, finite, not all zero; the grid ranking
        and the returned ``cost`` use them too.

    Returns
    -------
    ExtensionFit

    Raises
    ------
    DataError
        For no experiments, an all-zero input or a wrong number of outputs.
    ConfigError
        For ``weights`` of the wrong length, negative, non-finite or all zero.
    ModelError
        For an impossible ``theta0`` or a ``linear`` fit that is not free damping.

    Examples
    --------
    >>> from bayesmodal.model.effects import EXTENSIONS
    >>> from bayesmodal.data import find_data, load_experiment
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> res = fit_extension_lsq(load_experiment(p), EXTENSIONS["motor_lag"]) if p else None
    """
    experiments = _as_list(experiments)
    rig = Rig() if rig is None else rig
    model = ext.linear_model(rig)
    check_outputs(experiments, rig)
    w_exp = experiment_weights(weights, experiments)
    # the weights once (a named weighting reads every record), as numbers from here on
    root_w = root_weights(None if weights is None else w_exp, experiments)
    if linear is None:
        linear = fit_lsq(experiments, model)
    elif linear.model.damping != "free" or linear.model.n_carts != rig.n_carts:
        raise ModelError("the linear start must be a free-damping fit of the same rig")

    def residuals(theta):
        r = admissible_residuals(ext, rig, theta, experiments)
        return r if root_w is None else r * root_w

    if theta0 is None:
        starts = _grid_starts(ext, rig, linear, damper_scales, n_starts, residuals)
    else:
        starts = [ext.check(rig, np.asarray(theta0, dtype=float))]

    # optimiser coordinates: log for positive linear parameters, scaled linear otherwise
    coords = coordinates(ext, rig, linear.theta)
    lower, upper = coords.lower, coords.upper
    steps = coords.fd_steps(fd_step)

    def to_theta(w):
        # a long trial step can overflow a log parameter to inf (or a mass to 0): such
        # points are not a model and get admissible_residuals' barrier, as in fit_lsq
        return coords.to_theta(w, quiet=True)

    def fun(w):
        return residuals(to_theta(w[None]))[0]

    def jac(w):  # forward differences, each step away from an upper bound
        return fd_jacobian(lambda ws: residuals(to_theta(ws)), w, range(w.size), steps, upper)

    best = None
    n_eval = 0
    for start in starts:
        w0 = coords.to_opt(start)
        # keep the start strictly inside finite bounds and replace infinite values (e.g.
        # "no saturation") by the largest finite grid value
        w0 = np.where(np.isfinite(w0), w0, np.where(np.isfinite(upper), upper, 1e3))
        w0 = np.clip(w0, lower, upper)
        sol = solve(fun, w0, jac, lower, upper, max_nfev, x_scale=1.0)
        n_eval += int(sol.nfev)
        cost_end, cost_start = np.sum(fun(sol.x) ** 2), np.sum(fun(w0) ** 2)
        theta = ext.check(rig, to_theta(sol.x))
        if not cost_end <= cost_start:  # never worse than the start
            theta, cost_end = start, cost_start
        if best is None or cost_end < best[0]:
            best = (cost_end, theta, start, sol)
    _, theta, theta_start, sol = best
    return _summary(experiments, ext, rig, theta, w_exp, linear, theta_start,
                    bool(sol.success), str(sol.message), n_eval)


def _grid_starts(ext, rig, linear, damper_scales, n_starts, residuals) -> list[np.ndarray]:
    """The ``n_starts`` best start vectors of ``fit_extension_lsq``: the linear fit with its
    dampers scaled by each of ``damper_scales``, crossed with ``ext.start_grid(rig)``,
    ranked by the cost of ``residuals`` (one batched evaluation)."""
    dampers = damper_mask(LinearModel(rig, "free"))
    grid = ext.start_grid(rig)
    lin_starts = []
    for f in damper_scales:
        th = np.array(linear.theta, dtype=float)
        th[dampers] *= float(f)
        lin_starts.append(th)
    lin_starts = np.array(lin_starts)
    cands = np.concatenate([np.repeat(lin_starts, len(grid), axis=0),
                            np.tile(grid, (len(lin_starts), 1))], axis=1)
    cands = cands[ext.valid(rig, cands)]
    r = residuals(cands)
    order = np.argsort(np.sum(r**2, axis=1))
    return [cands[i] for i in order[: max(1, int(n_starts))]]


def _summary(experiments, ext, rig, theta, w_exp, linear, theta_start, success, message,
             n_eval) -> ExtensionFit:
    fits, sq = [], []
    for e in experiments:
        yh = ext.simulate(rig, theta, e.v_volt, e.dt)
        fits.append(fit_percent(e.y_m, yh))
        sq.append(((e.y_m - yh) ** 2).sum(axis=0))
    n_total = sum(e.n_samples for e in experiments)
    return ExtensionFit(
        extension=ext,
        rig=rig,
        theta=theta,
        fit_percent=np.array(fits),
        cost=0.5 * float(np.sum(w_exp[:, None] * np.array(sq))),
        sigma_m=np.sqrt(np.sum(sq, axis=0) / n_total),
        linear=linear,
        theta_start=theta_start,
        success=success,
        message=message,
        n_evaluations=n_eval,
    )


def extension_fit_at(experiments: Experiment | Sequence[Experiment], ext: Extension,
                     rig: Rig, theta: np.ndarray, *, linear: LSQResult,
                     weights: Sequence[float] | str | None = None) -> ExtensionFit:
    """The :class:`ExtensionFit` summary of ``ext`` at ``theta``, without fitting.

    For a point found otherwise (a nested model's value at a larger model's optimum),
    summarised like a fit: fit percentages, cost and RMS residual at ``theta``;
    ``n_evaluations`` 0 and ``theta_start`` the point itself; ``weights`` as in
    :func:`fit_extension_lsq` (the cost's).

    Raises
    ------
    ModelError
        If ``theta`` is not an admissible parameter vector of ``ext``.
    """
    experiments = _as_list(experiments)
    theta = ext.check(rig, np.asarray(theta, float))
    return _summary(experiments, ext, rig, theta, experiment_weights(weights, experiments),
                    linear, theta.copy(), True, "evaluated at a given point, not fitted", 0)
