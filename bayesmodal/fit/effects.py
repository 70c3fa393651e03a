"""Output-error least squares of an extended model, started from the linear fit:
``fit_extension_lsq(records, ext, rig, ...)`` is the same as ``fit_lsq(records, rig,
extension=ext, ...)`` (:func:`bayesmodal.fit.fit_lsq`), kept under its name.

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

import numpy as np

from ..data import Experiment
from ..metrics import fit_percent
from ..model.effects._base import Extension
from ..model.system import Rig
from .lsq import fit_lsq
from .residuals import (
    WEIGHTINGS,
    admissible_residuals,
    as_list,
    experiment_weights,
    extension_cost,
    extension_residuals,
    record_weights,
    root_weights,
)
from .result import ExtensionFit, LSQResult

__all__ = ["ExtensionFit", "fit_extension_lsq", "extension_fit_at", "extension_residuals",
           "extension_cost", "record_weights", "experiment_weights", "root_weights",
           "WEIGHTINGS", "admissible_residuals"]


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
    """Least-squares fit of an extended model: ``fit_lsq(experiments, rig, extension=ext,
    theta0=theta0, linear=linear, fd_step=..., max_nfev=..., n_starts=...,
    damper_scales=..., weights=...)``.

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
        The :class:`~bayesmodal.fit.result.LSQResult` of the fit (``extension`` set).

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
    return fit_lsq(experiments, Rig() if rig is None else rig, extension=ext, theta0=theta0,
                   linear=linear, fd_step=fd_step, max_nfev=max_nfev, n_starts=n_starts,
                   damper_scales=tuple(damper_scales), weights=weights)


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
    experiments = as_list(experiments)
    theta = ext.check(rig, np.asarray(theta, float))
    w = experiment_weights(weights, experiments)
    fits, sq = [], []
    for e in experiments:
        yh = ext.simulate(rig, theta, e.v_volt, e.dt)
        fits.append(fit_percent(e.y_m, yh))
        sq.append(((e.y_m - yh) ** 2).sum(axis=0))
    n_total = sum(e.n_samples for e in experiments)
    return LSQResult(
        model=ext.linear_model(rig), theta=theta, fit_percent=np.array(fits),
        cost=0.5 * float(np.sum(w[:, None] * np.array(sq))),
        sigma_m=np.sqrt(np.sum(sq, axis=0) / n_total), cov=None, success=True,
        message="evaluated at a given point, not fitted", n_evaluations=0, extension=ext,
        linear=linear, theta_start=theta.copy(), weights=None if weights is None else w,
        record_names=tuple(e.name for e in experiments))
