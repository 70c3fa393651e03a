"""Cross-experiment consistency: do parameters fitted on one experiment predict the others?

A correct model has one parameter set for all experiments.  If the rig is nonlinear
(friction, saturation, amplitude-dependent stiffness), experiments at different amplitudes
or with different inputs pull a linear model to different parameters, and each fitted
model predicts the other experiments worse than their own fits do.

For ``n`` experiments the model is fitted to each one and used to predict every one; the
statistic is the largest drop of the (output-averaged) fit percentage of an experiment
between its own fit and the prediction from another experiment's parameters.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..._errors import DataError
from ...data import Experiment
from ...fit.lsq import fit_lsq
from ...metrics import fit_percent
from ...model.effects import suggested_by
from ...model.simulate import simulate_linear
from ...model.system import LinearModel, Rig
from ._result import Diagnostic

__all__ = ["cross_experiment_consistency"]


def cross_experiment_consistency(
    experiments: Sequence[Experiment],
    *,
    model: LinearModel | None = None,
    fit: Callable[[list[Experiment]], np.ndarray] | None = None,
    simulate: Callable[[np.ndarray, Experiment], np.ndarray] | None = None,
    names: Sequence[str] | None = None,
    threshold_percent: float = 5.0,
) -> Diagnostic:
    """Fit on each experiment, predict all, and compare with the own fits.

    Parameters
    ----------
    experiments : sequence of Experiment
        At least two.
    model : LinearModel, optional
        Model used by the default ``fit`` and ``simulate`` (free damping by default).
    fit : callable, optional
        ``fit(list_of_experiments) -> theta``; default ``fit_lsq(..., model).theta``.  Pass
        e.g. ``lambda es: fit_lsq(es, rig, extension=ext).theta`` for an extended model.
    simulate : callable, optional
        ``simulate(theta, experiment) -> y_pred`` (N, n_out); default ``simulate_linear``.
    names : sequence of str, optional
        Parameter names for the detail (default ``model.names``).
    threshold_percent : float
        Largest acceptable drop of fit percentage, percentage points.

    Returns
    -------
    Diagnostic
        ``statistic``: the largest drop (points); ``threshold``.  Detail: ``fit_matrix``
        (n, n) fit percent of experiment j (column) predicted with the parameters of
        experiment i (row), averaged over outputs; ``theta`` (n, n_params);
        ``relative_spread`` (n_params,) ``(max - min) / |mean|``; ``experiments`` names;
        ``names``.  Suggests amplitude-dependent effects.
    """
    experiments = list(experiments)
    if len(experiments) < 2:
        raise DataError(f"need at least two experiments to compare, got {len(experiments)}")
    if model is None:
        model = LinearModel(Rig(), "free")
    if fit is None:
        def fit(es):
            return fit_lsq(es, model).theta
    if simulate is None:
        def simulate(theta, e):
            return simulate_linear(model, theta, e.v_volt, e.dt)
    thetas = np.array([np.asarray(fit([e]), float) for e in experiments])
    n = len(experiments)
    F = np.empty((n, n))
    for i in range(n):
        for j, e in enumerate(experiments):
            F[i, j] = float(np.mean(fit_percent(e.y_m, simulate(thetas[i], e))))
    drop = np.diag(F)[None, :] - F
    np.fill_diagonal(drop, -np.inf)
    i, j = np.unravel_index(int(np.argmax(drop)), drop.shape)
    stat = float(drop[i, j])
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.ptp(thetas, axis=0) / np.abs(thetas.mean(axis=0))
    detected = stat > threshold_percent
    labels = [e.name for e in experiments]
    summary = (
        f"parameters from {labels[i]} predict {labels[j]} {stat:.1f} points worse than its "
        f"own fit ({F[j, j]:.1f} -> {F[i, j]:.1f} %; threshold {threshold_percent})"
    )
    return Diagnostic(
        name="consistency",
        statistic=stat,
        p_value=None,
        threshold=float(threshold_percent),
        detected=bool(detected),
        suggests=suggested_by("consistency") if detected else (),
        location=f"{labels[i]} -> {labels[j]}" if detected else None,
        summary=summary,
        detail={"fit_matrix": F, "theta": thetas, "relative_spread": spread,
                "experiments": labels,
                "names": tuple(names) if names is not None else model.names},
    )
