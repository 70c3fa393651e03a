"""Plots of a diagnosis: every diagnostic of the linear model, and the fit before/after."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..discrepancy.checks import linear_residuals
from ..discrepancy.diagnosis.null import run_diagnostics
from ..model.simulate import simulate_linear
from .diagnostics import plot_diagnostic, plot_residuals

__all__ = ["plot_before_after", "write_plots"]


def plot_before_after(diagnosis, experiment, *, ax=None):
    """Measured positions, the linear prediction and the extended model's, per cart."""
    import matplotlib.pyplot as plt


    lin = diagnosis.detail["linear"]
    n = experiment.n_outputs
    if ax is None:
        _, ax = plt.subplots(n, 1, sharex=True, figsize=(9, 2.2 * n))
    ax = np.atleast_1d(ax)
    t = experiment.t_s
    y_lin = simulate_linear(lin.model, lin.theta, experiment.v_volt, experiment.dt)
    y_ext, label = None, diagnosis.cause
    if diagnosis.cause != "none" and "extension_fit" in diagnosis.detail:
        # the final model: forward selection's fit, else the first step's (the first
        # cause may have been refined, e.g. to directional levels, so its name does not
        # name the fitted model)
        fwd = diagnosis.detail.get("forward")
        ef = fwd.fit if fwd is not None else diagnosis.detail["extension_fit"]
        label = ef.extension.name
        y_ext = ef.extension.simulate(ef.rig, ef.theta, experiment.v_volt, experiment.dt)
    for j in range(n):
        ax[j].plot(t, experiment.y_m[:, j] * 1e3, "k", lw=1, label="measured")
        ax[j].plot(t, y_lin[:, j] * 1e3, "C0", lw=0.8, label="linear")
        if y_ext is not None:
            ax[j].plot(t, y_ext[:, j] * 1e3, "C3", lw=0.8, label=label)
        ax[j].set_ylabel(f"x{j + 1} (mm)")
    ax[-1].set_xlabel("time (s)")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].set_title(f"{experiment.name}: before and after ({label})")
    return ax


def write_plots(diagnosis, experiments, folder: Path) -> list[Path]:
    """Write the diagnostics' plots and the before/after fits as PNG files in ``folder``.

    A diagnostic with nothing to draw (e.g. no free-decay stretch) gives an empty panel;
    matplotlib's warning about its empty legend is silenced.
    """
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="No artists with labels")
        return _write_plots(diagnosis, experiments, folder)


def _write_plots(diagnosis, experiments, folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lin = diagnosis.detail["linear"]
    written = []

    def save(fig, name: str) -> None:
        p = folder / f"{name}.png"
        fig.savefig(p, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(p)

    for i in diagnosis.train:
        e = experiments[i]
        res = linear_residuals(e, lin.model, lin.theta)
        fig, ax = plt.subplots(figsize=(9, 4))
        plot_residuals(res, ax=ax)
        save(fig, f"{e.name}_residuals")
        for name, d in run_diagnostics(e, lin.model, lin.theta, quantum_m=res.quantum_m).items():
            fig, ax = plt.subplots(figsize=(8, 4))
            plot_diagnostic(d, ax=ax)
            save(fig, f"{e.name}_{name}")
    for e in experiments:
        save(plot_before_after(diagnosis, e)[0].figure, f"{e.name}_before_after")
    return written
