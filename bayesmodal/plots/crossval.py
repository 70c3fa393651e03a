"""Plots of a leave-one-record-out study: held-out bands and a forest of estimates."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_heldout_band", "plot_forest"]


def plot_heldout_band(fold, *, axes=None, max_points: int = 4000):
    """One held-out record with its 90 % predictive band, one panel per cart.

    Parameters
    ----------
    fold : FoldResult
        A fold with ``band`` (``t_s``, ``y``, ``q05``, ``q50``, ``q95``, m).
    axes : sequence of matplotlib Axes, optional
    max_points : int
        Samples drawn per curve (evenly thinned).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    b = fold.band
    n_out = b["y"].shape[1]
    if axes is None:
        fig, axes = plt.subplots(n_out, 1, figsize=(9, 1.9 * n_out + 0.6), sharex=True,
                                 squeeze=False)
        axes = axes[:, 0]
    fig = axes[0].figure
    step = max(1, b["t_s"].size // max_points)
    t = b["t_s"][::step]
    s = fold.scores
    for j, ax in enumerate(axes):
        ax.fill_between(t, 1e3 * b["q05"][::step, j], 1e3 * b["q95"][::step, j],
                        color="tab:blue", alpha=0.3, lw=0, label="90 % predictive band")
        ax.plot(t, 1e3 * b["q50"][::step, j], color="tab:blue", lw=0.8,
                label="predictive median")
        ax.plot(t, 1e3 * b["y"][::step, j], color="k", lw=0.6, label="measured")
        ax.set_ylabel(f"x{j + 1} (mm)")
        ax.set_title(f"cart {j + 1}: fit {s.fit_percent[j]:.1f} %, 90 % band covers "
                     f"{100 * s.coverage_90[j]:.0f} %, width {s.width_90[j]:.2f} sd",
                     fontsize=9, loc="left")
    axes[-1].set_xlabel("time (s)")
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    fig.suptitle(f"{fold.heldout}: predicted from {', '.join(fold.training)}", fontsize=10)
    fig.tight_layout()
    return fig


def plot_forest(result, *, axes=None):
    """Per-record estimates against the joint posterior: g_v and the natural frequencies.

    Each record's own least-squares value (dot), the held-out fold's prediction of it
    (bar: 90 % interval of the population draw for g_v, of the training posterior for
    omega), and the joint posterior's 90 % interval (band).

    Parameters
    ----------
    result : CrossvalResult
    axes : sequence of matplotlib Axes, optional
        One per quantity (g_v and each omega).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    folds = result.folds
    n_modes = len(folds[0].estimates["omega_rad_s"]["median"])
    quantities = [("g_v", None, "g_v (N/V)")] + [
        ("omega_rad_s", i, f"f{i + 1} (Hz)") for i in range(n_modes)]
    if axes is None:
        fig, axes = plt.subplots(1, len(quantities), figsize=(3.0 * len(quantities), 0.55 *
                                 len(folds) + 1.6), sharey=True, squeeze=False)
        axes = axes[0]
    fig = axes[0].figure
    y = np.arange(len(folds))
    for ax, (key, i, label) in zip(axes, quantities, strict=True):
        scale = 1.0 if key == "g_v" else 1.0 / (2 * np.pi)
        for k, f in enumerate(folds):
            est = f.estimates[key]
            j = 0 if i is None else i
            lo, med, hi = (scale * est[q][j] for q in ("lo", "median", "hi"))
            ax.plot([lo, hi], [k, k], color="tab:blue", lw=2,
                    label="held-out prediction (90 %)" if k == 0 else None)
            ax.plot(med, k, "|", color="tab:blue", ms=10)
            own = result.own.get(f.heldout, {}).get(key)
            if own is not None:
                v = scale * (own if i is None else own[i])
                ax.plot(v, k, "o", color="k", ms=4, label="record's own LSQ" if k == 0 else None)
        if result.joint is not None:
            est = result.joint.estimates[key]
            j = 0 if i is None else i
            ax.axvspan(scale * est["lo"][j], scale * est["hi"][j], color="tab:orange",
                       alpha=0.3, label="joint posterior (90 %)")
        ax.set_xlabel(label)
        ax.locator_params(axis="x", nbins=4)
    axes[0].set_yticks(y, [f.heldout for f in folds])
    axes[0].legend(loc="upper center", bbox_to_anchor=(0.5, -0.35), fontsize=8, ncol=1)
    fig.tight_layout()
    return fig
