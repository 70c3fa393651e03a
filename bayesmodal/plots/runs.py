"""Plots of run cross-checks and of several runs side by side (Agg-safe, units on axes)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_residuals", "plot_residual_acf", "plot_run_intervals"]


#: Most record panels side by side.  At the report's width (1100 px for a 9-inch figure)
#: four columns leave each panel about 250 px, room for a record name of some 25
#: characters and its tick labels; more records wrap onto further rows of panels.
MAX_COLUMNS = 4


def _record_axes(axes, n_records: int, n_rows: int, row_height_in: float):
    """Axes of one panel per record and row, ``(n_records, n_rows)``, in blocks of at
    most :data:`MAX_COLUMNS` records side by side; the figure's height follows the grid."""
    import matplotlib.pyplot as plt

    if axes is not None:
        ax = np.asarray(axes).reshape(n_rows, n_records)
        return ax.T, ax
    n_cols = min(n_records, MAX_COLUMNS)
    n_blocks = -(-n_records // n_cols)
    fig = plt.figure(figsize=(9.0, 0.9 + row_height_in * n_rows * n_blocks),
                     layout="constrained")
    grid = fig.subplots(n_rows * n_blocks, n_cols, squeeze=False)
    per_record = np.empty((n_records, n_rows), dtype=object)
    for r in range(n_records):
        b, c = divmod(r, n_cols)
        per_record[r] = grid[b * n_rows:(b + 1) * n_rows, c]
    for a in grid.ravel()[n_records * n_rows:] if n_rows == 1 else ():
        a.set_visible(False)
    if n_rows > 1:
        for r in range(n_records, n_blocks * n_cols):
            b, c = divmod(r, n_cols)
            for a in grid[b * n_rows:(b + 1) * n_rows, c]:
                a.set_visible(False)
    return per_record, per_record.T


def _label_record_panels(per_record, x_label: str, y_label) -> None:
    """Record names as panel titles, x labels under each record's bottom panel only,
    y labels on the first column of panels only."""
    for r, col in enumerate(per_record):
        for j, a in enumerate(col):
            if j < len(col) - 1:
                a.sharex(col[-1])
                a.tick_params(labelbottom=False)
        col[-1].set_xlabel(x_label)
        first = r % MAX_COLUMNS == 0
        for j, a in enumerate(col):
            if first:
                a.set_ylabel(y_label(j))


def plot_residuals(checks, *, axes=None):
    """Residual time series, one row per output, one column per experiment.

    The panels are titled with the record's name; four records at most side by side, more
    wrap onto further rows.

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
    per_record, ax = _record_axes(axes, len(checks), n_out, 1.6)
    for chk, col in zip(checks, per_record, strict=True):
        for j, a in enumerate(col):
            a.plot(chk.t_s, 1e3 * chk.residual_m[:, j], lw=0.5, color="C0")
            a.axhline(0.0, color="k", lw=0.5)
        col[0].set_title(chk.experiment, fontsize=9)
    if axes is None:
        _label_record_panels(per_record, "time (s)", lambda j: f"x{j + 1} residual (mm)")
        ax[0, 0].figure.suptitle("Residuals: measured - model at the posterior median",
                                 fontsize=10)
    else:
        for col in per_record:
            col[-1].set_xlabel("time (s)")
            for j, a in enumerate(col):
                a.set_ylabel(f"x{j + 1} residual (mm)")
    return ax


def plot_residual_acf(checks, *, axes=None):
    """Residual autocorrelation with the 95 % band of white noise, one panel per experiment.

    The panels are titled with the record's name and share one legend, below them; four
    records at most side by side, more wrap onto further rows.

    Parameters
    ----------
    checks : sequence of ResidualCheck
    axes : array of Axes, shape (1, n_experiments), optional

    Returns
    -------
    ndarray of Axes, shape (1, n_experiments)
    """
    checks = list(checks)
    per_record, ax = _record_axes(axes, len(checks), 1, 2.4)
    for chk, (a,) in zip(checks, per_record, strict=True):
        for j in range(chk.acf.shape[1]):
            a.plot(chk.lag_s, chk.acf[:, j], lw=1.0, label=f"x{j + 1}")
        a.axhspan(-chk.band, chk.band, color="0.8", label="white-noise limit (95 %)")
        a.axhline(0.0, color="k", lw=0.5)
        a.set_title(chk.experiment, fontsize=9)
    first = per_record[0, 0]
    lo = min(a.get_ylim()[0] for a in ax.ravel())
    for a in ax.ravel():
        a.set_ylim(lo, 1.05)  # one scale: every ACF is 1 at lag 0
    for r, (a,) in enumerate(per_record):
        a.set_xlabel("lag (s)")
        if r % MAX_COLUMNS == 0 or axes is not None:
            a.set_ylabel("autocorrelation (-)")
    fig = first.figure
    if axes is None:
        fig.suptitle("Autocorrelation of the residuals at the posterior median", fontsize=10)
        fig.legend(*first.get_legend_handles_labels(), loc="outside lower center",
                   ncol=4, fontsize=8, frameon=False)
    else:
        first.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
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
