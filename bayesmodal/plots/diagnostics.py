"""Plots of the residual diagnostics (``bayesmodal.discrepancy.checks``).

One function per diagnostic family, each ``plot_*(result, *, ax=None)`` returning the
axes, and ``plot_diagnostic`` choosing by ``result.name``.  ``plot_residuals`` draws the
residual time series themselves.
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ..data import ECP_M_PER_COUNT
from ..discrepancy.checks import Diagnostic, LinearResiduals

__all__ = [
    "plot_diagnostic",
    "plot_residuals",
    "plot_whiteness",
    "plot_input_correlation",
    "plot_friction_signature",
    "plot_decay_envelope",
    "plot_amplitude_dependence",
    "plot_stick",
    "plot_residual_spectrum",
    "plot_gain_error",
    "plot_consistency",
    "plot_input_bias",
    "plot_drive_gain",
]


def _axes(ax, figsize=(8, 4)):
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax


def _title(ax, result: Diagnostic) -> None:
    verdict = "detected" if result.detected else "not detected"
    ax.set_title(f"{result.name}: {verdict}", fontsize=10)


def plot_residuals(res: LinearResiduals, *, ax=None, counts: bool = True):
    """Residual time series of every output.

    Parameters
    ----------
    res : LinearResiduals
    ax : matplotlib Axes, optional
    counts : bool
        Plot in encoder counts (else in mm).

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (10, 4))
    scale, unit = (1 / ECP_M_PER_COUNT, "counts") if counts else (1e3, "mm")
    t = res.experiment.t_s
    for j in range(res.n_outputs):
        ax.plot(t, scale * res.residual[:, j], lw=0.8, label=f"x{j + 1}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"residual y - yhat [{unit}]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"residuals of the linear model: {res.experiment.name}", fontsize=10)
    return ax


def plot_whiteness(result: Diagnostic, *, ax=None):
    """Autocorrelation of the AR-whitened residuals with the 95 % band.

    Parameters
    ----------
    result : Diagnostic
        The ``whiteness`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        Autocorrelation (-) against lag (samples).
    """
    ax = _axes(ax)
    acf = np.asarray(result.detail["acf"])
    lags = np.arange(1, acf.shape[1] + 1)
    for j in range(acf.shape[0]):
        ax.plot(lags + 0.1 * j, acf[j], "o-", ms=3, lw=0.8,
                label=f"output {j + 1} (p = {result.detail['p_values'][j]:.2g})")
    band = result.detail["band"]
    ax.axhspan(-band, band, color="0.85", zorder=0, label="95 % band, white noise")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("lag [samples]")
    ax.set_ylabel("autocorrelation of innovations [-]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_input_correlation(result: Diagnostic, *, ax=None):
    """Cross-correlation of whitened residual and input against lag.

    Parameters
    ----------
    result : Diagnostic
        The ``input_correlation`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        Normalised cross-correlation (-) against lag (ms).
    """
    ax = _axes(ax)
    lags = 1e3 * np.asarray(result.detail["lags_s"])
    xc = np.asarray(result.detail["xcorr"])
    for j in range(xc.shape[0]):
        ax.plot(lags, xc[j], lw=1.0, label=f"output {j + 1}")
    band = result.detail["band"]
    ax.axhspan(-band, band, color="0.85", zorder=0, label="+-3/sqrt(N)")
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("lag of the residual after the input [ms]")
    ax.set_ylabel("cross-correlation [-]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_friction_signature(result: Diagnostic, *, ax=None):
    """Binned force residual against velocity for every cart (a step at zero = friction).

    Parameters
    ----------
    result : Diagnostic
        The ``friction_signature`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        Force residual (N) against velocity (mm/s).
    """
    ax = _axes(ax)
    vb = np.asarray(result.detail["v_bins"])
    fb = np.asarray(result.detail["f_bins"])
    fc = result.detail["fc_n"]
    for i in range(vb.shape[0]):
        line, = ax.plot(1e3 * vb[i], fb[i], "o-", ms=3, lw=0.8,
                        label=f"cart {i + 1}: Fc = {fc[i]:.3f} N")
        vmax = np.nanmax(np.abs(vb[i]))
        ax.plot([-1e3 * vmax, 0, 0, 1e3 * vmax], [fc[i], fc[i], -fc[i], -fc[i]],
                color=line.get_color(), lw=0.8, ls="--")
    ax.axhline(0, color="k", lw=0.5)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("velocity [mm/s]")
    ax.set_ylabel("force residual M r'' + C r' + K r [N]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_decay_envelope(result: Diagnostic, *, ax=None):
    """``sqrt(E)`` on each free-decay stretch with the exponential and linear laws.

    Parameters
    ----------
    result : Diagnostic
        The ``decay_envelope`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        sqrt of the mechanical energy (J^0.5) against time from the stretch start (s).
    """
    ax = _axes(ax)
    d = result.detail
    for k, (t, s) in enumerate(zip(d["t_s"], d["sqrt_energy"], strict=True)):
        line, = ax.plot(t, s, lw=1.2, label=f"stretch {k + 1}: share {d['share'][k]:.2f}")
        ax.plot(t, d["fit_exponential"][k], color=line.get_color(), ls=":", lw=0.8)
        ax.plot(t, d["fit_linear"][k], color=line.get_color(), ls="--", lw=0.8)
    ax.plot([], [], "k:", label="exponential (viscous)")
    ax.plot([], [], "k--", label="linear (Coulomb)")
    ax.set_xlabel("time in stretch [s]")
    ax.set_ylabel("sqrt(energy) [J^0.5]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_amplitude_dependence(result: Diagnostic, *, ax=None):
    """Relative frequency of each mode against amplitude, one point per window.

    Parameters
    ----------
    result : Diagnostic
        The ``amplitude_dependence`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        Frequency relative to the model (%) against cart amplitude (mm).
    """
    ax = _axes(ax)
    for m in result.detail["modes"]:
        A = np.asarray(m["amplitude_m"])
        if A.size == 0:
            continue
        rel = 100 * (np.asarray(m["omega"]) / m["omega_model"] - 1)
        ax.plot(1e3 * A, rel, "o", ms=4,
                label=f"mode {m['mode']} ({m['omega_model']:.1f} rad/s, t = {m['t']:.1f})")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("amplitude [mm]")
    ax.set_ylabel("frequency - model [%]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_stick(result: Diagnostic, res: LinearResiduals | None = None, *, ax=None):
    """Stuck episodes on the measured positions (or as bars without ``res``).

    Parameters
    ----------
    result : Diagnostic
        From ``stick_detection``.
    res : LinearResiduals, optional
        The residuals the diagnostic used; draws the measured and predicted positions.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
        Position (counts) against time (s), stuck episodes shaded.
    """
    ax = _axes(ax, (10, 4))
    mask = np.asarray(result.detail["stuck_mask"])
    n = mask.shape[1]
    if res is not None:
        t = res.experiment.t_s
        for i in range(n):
            line, = ax.plot(t, res.y[:, i] / ECP_M_PER_COUNT, lw=0.9, label=f"x{i + 1}")
            ax.plot(t, res.y_pred[:, i] / ECP_M_PER_COUNT, lw=0.6, ls="--",
                    color=line.get_color())
        dt = res.dt
    else:
        t = np.arange(mask.shape[0])
        dt = 1.0
    for i in range(n):
        for s0, s1, _, _ in result.detail["episodes"][i]:
            ax.axvspan(s0 * dt, s1 * dt, ymin=i / n, ymax=(i + 1) / n, color=f"C{i}",
                       alpha=0.2, lw=0)
    ax.set_xlabel("time [s]" if res is not None else "sample")
    ax.set_ylabel("position [counts]")
    if res is not None:
        ax.legend(fontsize=8, loc="upper right")
    _title(ax, result)
    return ax


def plot_residual_spectrum(result: Diagnostic, *, ax=None):
    """Residual PSD with the smooth background, the peak limit and the model's modes.

    Parameters
    ----------
    result : Diagnostic
        The ``residual_spectrum`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        PSD (m^2/Hz, log) against frequency (Hz).
    """
    ax = _axes(ax)
    d = result.detail
    f = d["f_hz"]
    for j in range(d["psd"].shape[0]):
        line, = ax.semilogy(f, d["psd"][j], lw=0.9, label=f"output {j + 1}")
        ax.semilogy(f, d["baseline"][j] * d["limit"], color=line.get_color(), ls=":", lw=0.8)
    for fm in d["model_hz"]:
        ax.axvline(fm, color="0.5", lw=0.8, ls="--")
    for pk in d["peaks"]:
        if pk["near_mode_hz"] is None:
            ax.plot(pk["f_hz"], d["psd"][pk["output"]][np.argmin(np.abs(f - pk["f_hz"]))],
                    "rv", ms=8)
    ax.plot([], [], "k:", label="peak limit")
    ax.plot([], [], color="0.5", ls="--", label="model modes")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("residual PSD [m^2/Hz]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_gain_error(result: Diagnostic, *, ax=None):
    """Relative gain error per output with 2-sigma bars.

    Parameters
    ----------
    result : Diagnostic
        The ``gain_error`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
        Gain error (%) per output.
    """
    ax = _axes(ax, (5, 4))
    g = 100 * np.asarray(result.detail["gain"])
    se = 100 * np.asarray(result.detail["stderr"])
    x = np.arange(1, g.size + 1)
    ax.errorbar(x, g, yerr=2 * se, fmt="o", capsize=4)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(x, [f"x{i}" for i in x])
    ax.set_xlabel("output")
    ax.set_ylabel("gain error [%]")
    _title(ax, result)
    return ax


def plot_consistency(result: Diagnostic, *, ax=None):
    """Fit percentage of each experiment (columns) predicted from each fit (rows).

    Parameters
    ----------
    result : Diagnostic
        The ``consistency`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (5.5, 4.5))
    F = np.asarray(result.detail["fit_matrix"])
    labels = result.detail["experiments"]
    im = ax.imshow(F, cmap="viridis", vmin=min(0, F.min()), vmax=100)
    for i in range(F.shape[0]):
        for j in range(F.shape[1]):
            ax.text(j, i, f"{F[i, j]:.1f}", ha="center", va="center", color="w", fontsize=9)
    ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right")
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("predicted experiment")
    ax.set_ylabel("parameters fitted on")
    ax.figure.colorbar(im, ax=ax, label="fit [%]")
    _title(ax, result)
    return ax


def plot_input_bias(result: Diagnostic, *, ax=None):
    """Residual mean per output (micrometres) against the fitted offset's response.

    Parameters
    ----------
    result : Diagnostic
        The ``input_bias`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (5, 4))
    mean = np.asarray(result.detail["mean_m"])
    unit = np.asarray(result.detail["unit_response"])
    v0 = float(result.detail["offset_v"])
    x = np.arange(1, mean.size + 1)
    ax.bar(x - 0.2, 1e6 * mean, width=0.4, label="residual mean")
    ax.bar(x + 0.2, 1e6 * v0 * unit[-1], width=0.4, label="offset response (end)")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(x, [f"x{i}" for i in x])
    ax.set_xlabel("output")
    ax.set_ylabel("residual [um]")
    ax.legend(fontsize=8)
    _title(ax, result)
    return ax


def plot_drive_gain(result: Diagnostic, *, ax=None):
    """Gain error asked by each input event against its amplitude, with 2-sigma bars.

    Parameters
    ----------
    result : Diagnostic
        The ``drive_gain`` check (``bayesmodal.discrepancy.checks``), whose ``detail``
        holds what is drawn.
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (5, 4))
    a = np.asarray(result.detail["amplitude_v"])
    g = 100 * np.asarray(result.detail["gain"])
    se = 100 * np.asarray(result.detail["stderr"])
    if a.size:
        ax.errorbar(a, g, yerr=2 * se, fmt="o", capsize=4)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("input amplitude [V]")
    ax.set_ylabel("gain error [%]")
    _title(ax, result)
    return ax


_PLOTS = {
    "whiteness": plot_whiteness,
    "input_correlation": plot_input_correlation,
    "friction_signature": plot_friction_signature,
    "decay_envelope": plot_decay_envelope,
    "amplitude_dependence": plot_amplitude_dependence,
    "stick": plot_stick,
    "residual_spectrum": plot_residual_spectrum,
    "gain_error": plot_gain_error,
    "consistency": plot_consistency,
    "input_bias": plot_input_bias,
    "drive_gain": plot_drive_gain,
}


def plot_diagnostic(result: Diagnostic, *, ax=None):
    """Plot any diagnostic with the function for its ``name``.

    Parameters
    ----------
    result : Diagnostic
        A check's result; its ``name`` picks the plot (``whiteness``, ``stick``, ...).
    ax : matplotlib Axes, optional
        Axes to draw on; new axes when None.

    Examples
    --------
    >>> # ax = plot_diagnostic(friction_signature(res))
    """
    try:
        fn = _PLOTS[result.name]
    except KeyError:
        raise ConfigError(
            f"no plot for diagnostic {result.name!r}; known: {sorted(_PLOTS)}"
        ) from None
    return fn(result, ax=ax)
