"""Plot of the steady-state analysis: plateau windows and levels (report Figure 2)."""

from __future__ import annotations

import numpy as np

from ..static import StaticResult

__all__ = ["plot_steady_state"]


def plot_steady_state(result: StaticResult, *, ax=None, show_input: bool = True):
    """Outputs of a step experiment with the picked plateaus shaded and their levels.

    Parameters
    ----------
    result : StaticResult
        From :func:`bayesmodal.static.steady_state`.
    ax : matplotlib Axes, optional
        Axes to draw on (a new figure if omitted).
    show_input : bool
        Draw the input voltage on a twin axis.

    Returns
    -------
    matplotlib.axes.Axes
        The displacement axes (mm against s).

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> from bayesmodal.static import steady_state
    >>> p = find_data("ecp210-3dof/data_steps.mat")
    >>> ax = plot_steady_state(steady_state(load_experiment(p))) if p else None
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(10, 4.5), layout="constrained")
    e = result.experiment
    p = result.plateaus
    t = e.t_s
    colors = [f"C{j}" for j in range(e.n_outputs)]
    for j in range(e.n_outputs):
        ax.plot(t, 1e3 * e.y_m[:, j], color=colors[j], lw=1.0, label=f"x{j + 1}")
    used = set(result.on_index.tolist())
    for i in range(p.n_plateaus):
        t0, t1 = t[p.start[i]], t[p.stop[i] - 1]
        if p.on[i]:
            face = "tab:green" if i in used else "tab:red"
        else:
            face = "0.6"
        ax.axvspan(t0, t1, color=face, alpha=0.15, lw=0)
        for j in range(e.n_outputs):
            ax.plot([t0, t1], [1e3 * p.level_m[i, j]] * 2, color="k", lw=1.2, ls="--")
    ax.plot([], [], color="k", ls="--", label="plateau level")
    ax.fill_between([], [], color="tab:green", alpha=0.15, label="on-plateau (used)")
    ax.fill_between([], [], color="0.6", alpha=0.15, label="rest plateau")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement [mm]")
    ax.set_title(
        f"{e.name}: steady-state picking, g_v = {result.g_v:.4f} +- {result.g_v_se:.2g} N/V "
        f"(reference: {result.reference})"
    )
    if show_input:
        ax2 = ax.twinx()
        ax2.step(t, e.v_volt, where="post", color="0.3", lw=0.8, alpha=0.7)
        ax2.set_ylabel("input v [V]")
        vmax = float(np.max(np.abs(e.v_volt))) or 1.0
        ax2.set_ylim(-0.1 * vmax, 4.0 * vmax)
    ax.legend(loc="upper right", fontsize="small", ncols=2)
    return ax
