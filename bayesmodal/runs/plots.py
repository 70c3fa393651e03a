"""Plots of run cross-checks and of several runs side by side (Agg-safe, units on axes)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_residuals", "plot_residual_acf", "plot_run_intervals"]


def _axes(axes, n_rows: int, n_cols: int, size=(9.0, 2.2)):
    import matplotlib.pyplot as plt

    if axes is not None:
        return np.asarray(axes).reshape(n_rows, n_cols)
    fig, ax = plt.subplots(n_rows, n_cols, figsize=(size[0], size[1] * n_rows), squeeze=False,
                           sharex="col")
    fig.set_layout_engine("constrained")
    return ax


def plot_residuals(checks, *, axes=None):
    """Residual time series, one row per output, one column per experiment.

    Parameters
    ----------
    checks : sequence of ResidualCheck
    axes : array of Axes, shape (n_out, n_experiments), optional

    Returns
    -------
    ndarray of Axes, shape (n_out, n_experiments)
    """
    checks = list(checks)
    n_out = checks[0].residual_m.shape[1]
    ax = _axes(axes, n_out, len(checks))
    for c, chk in enumerate(checks):
        for j in range(n_out):
            a = ax[j, c]
            a.plot(chk.t_s, 1e3 * chk.residual_m[:, j], lw=0.5, color="C0")
            a.axhline(0.0, color="k", lw=0.5)
            a.set_ylabel(f"x{j + 1} residual (mm)")
            if j == 0:
                a.set_title(f"{chk.experiment}: measured - model at posterior median")
        ax[-1, c].set_xlabel("time (s)")
    return ax


def plot_residual_acf(checks, *, axes=None):
    """Residual autocorrelation with the 95 % band of white noise, one panel per experiment.

    Parameters
    ----------
    checks : sequence of ResidualCheck
    axes : array of Axes, shape (1, n_experiments), optional

    Returns
    -------
    ndarray of Axes, shape (1, n_experiments)
    """
    checks = list(checks)
    ax = _axes(axes, 1, len(checks), size=(9.0, 3.0))
    for c, chk in enumerate(checks):
        a = ax[0, c]
        for j in range(chk.acf.shape[1]):
            a.plot(chk.lag_s, chk.acf[:, j], lw=1.0, label=f"x{j + 1}")
        a.axhspan(-chk.band, chk.band, color="0.8",
                  label=f"white-noise limit (95 %, +-{chk.band:.3f})")
        a.axhline(0.0, color="k", lw=0.5)
        a.set_xlabel("lag (s)")
        a.set_ylabel("autocorrelation (-)")
        a.set_title(f"{chk.experiment}: residual ACF")
        a.legend(fontsize=8, loc="upper right")
    return ax


def plot_run_intervals(comparison, *, axes=None):
    """Posterior medians and 90 % intervals of omega and zeta, one panel per mode, runs as
    rows, so that the intervals of the runs can be compared at the scale of each mode.

    Parameters
    ----------
    comparison : RunComparison
        From :func:`bayesmodal.runs.compare_runs`.
    axes : array of Axes, shape (2, n_modes), optional
        Natural frequencies in the first row, damping ratios in the second.

    Returns
    -------
    ndarray of Axes, shape (2, n_modes)
    """
    import matplotlib.pyplot as plt

    rows = comparison.rows
    n_modes = rows[0].n_modes
    if axes is None:
        fig, axes = plt.subplots(2, n_modes, figsize=(3.4 * n_modes, 1.2 + 0.45 * len(rows) * 2),
                                 squeeze=False, sharey=True)
        fig.set_layout_engine("constrained")
    axes = np.asarray(axes).reshape(2, n_modes)
    y = np.arange(len(rows))[::-1]
    for k, (key, label) in enumerate((("omega_rad_s", "omega_{} (rad/s)"),
                                      ("zeta", "zeta_{} (-)"))):
        for i in range(n_modes):
            a = axes[k, i]
            for r, row in enumerate(rows):
                iv = row.summary[key]
                med, lo, hi = (float(iv[x][i]) for x in ("median", "lo", "hi"))
                a.errorbar([med], [y[r]], xerr=[[med - lo], [hi - med]], fmt="o", ms=4,
                           capsize=3, color=f"C{r}")
            a.set_xlabel(label.format(i + 1))
            a.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4), useOffset=False)
            a.grid(axis="x", alpha=0.3)
        axes[k, 0].set_yticks(y, [row.label for row in rows])
        axes[k, 0].set_ylabel("run")
    axes[0, 0].figure.suptitle("posterior medians with 90 % intervals")
    return axes
