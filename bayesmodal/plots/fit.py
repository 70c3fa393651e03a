"""Measured against simulated outputs with residuals (report Figures 6-7)."""

from __future__ import annotations

import numpy as np

from .._errors import DataError
from ..data import Experiment
from ..metrics import fit_percent
from ..model.simulate import simulate_linear

__all__ = ["plot_fit", "plot_lsq_fit"]


def plot_fit(
    experiment: Experiment,
    y_hat_m: np.ndarray,
    *,
    axes=None,
    label: str = "model",
    title: str | None = None,
):
    """One panel per output: measured, simulated and residual, with the fit percentage.

    Parameters
    ----------
    experiment : Experiment
        Measured record.
    y_hat_m : ndarray, shape (n_samples, n_outputs)
        Simulated outputs, m.
    axes : sequence of matplotlib Axes, length n_outputs, optional
        Axes to draw on (a new figure with one row per output if omitted).
    label : str
        Legend label of the simulation.
    title : str, optional
        Figure title (default: the experiment name).

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (n_outputs,)

    Examples
    --------
    >>> t = np.arange(100) * 0.01
    >>> e = Experiment(t, np.ones(100), np.c_[t, 2 * t])
    >>> axes = plot_fit(e, e.y_m * 0.9)
    >>> len(axes)
    2
    """
    import matplotlib.pyplot as plt

    y = experiment.y_m
    y_hat = np.asarray(y_hat_m, dtype=float)
    if y_hat.shape != y.shape:
        raise DataError(f"y_hat_m has shape {y_hat.shape}, the experiment {y.shape}")
    n = experiment.n_outputs
    if axes is None:
        fig, axes = plt.subplots(n, 1, figsize=(10, 2.4 * n), sharex=True,
                                 layout="constrained", squeeze=False)
        axes = axes[:, 0]
    else:
        axes = np.atleast_1d(np.asarray(axes, dtype=object))
        if axes.size != n:
            raise DataError(f"need {n} axes, got {axes.size}")
        fig = axes[0].figure
    fits = fit_percent(y, y_hat)
    t = experiment.t_s
    for j, ax in enumerate(axes):
        ax.plot(t, 1e3 * y[:, j], color="C0", lw=1.0, label="measured")
        ax.plot(t, 1e3 * y_hat[:, j], color="C1", lw=1.0, ls="--", label=label)
        ax.plot(t, 1e3 * (y[:, j] - y_hat[:, j]), color="C3", lw=0.8, label="residual")
        ax.set_ylabel(f"x{j + 1} [mm]")
        ax.set_title(f"x{j + 1}: fit {fits[j]:.2f} %", fontsize="medium", loc="left")
    axes[0].legend(loc="upper right", fontsize="small", ncols=3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title if title is not None else experiment.name)
    return axes


def plot_lsq_fit(result, experiment: Experiment, *, axes=None, title: str | None = None):
    """Simulate a least-squares estimate on an experiment and plot it with ``plot_fit``.

    Parameters
    ----------
    result : LSQResult
        From :func:`bayesmodal.fit.fit_lsq` (its ``model`` and ``theta`` are used).
    experiment : Experiment
    axes : sequence of matplotlib Axes, optional
    title : str, optional
        Default: experiment name and damping model.

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (n_outputs,)
    """

    y_hat = simulate_linear(result.model, result.theta, experiment.v_volt, experiment.dt)
    if title is None:
        title = f"{experiment.name}: {result.model.damping} damping"
    return plot_fit(experiment, y_hat, axes=axes, label=f"model ({result.model.damping})",
                    title=title)
