"""Plots of a posterior run: traces, pairs, predictive bands, Bode bands, modal intervals.

Every function takes the InferenceData of :func:`bayesmodal.inference.to_inference_data`
(or the modal samples derived from it), draws on new axes unless ``ax``/``axes`` is given,
and returns the axes.  matplotlib is imported inside the functions.
"""

from __future__ import annotations

import json

import numpy as np

from .._errors import DataError
from ..ema import frf_from_experiment
from ..inference.idata import experiments_from_idata, model_from_idata, posterior_matrix
from ..inference.propagate import modal_intervals, propagate_modes
from ..modal import transfer_function

__all__ = [
    "plot_trace",
    "plot_corner",
    "plot_predictive",
    "plot_bode_bands",
    "plot_modal_intervals",
]

_UNITS = {"g_v": "N/V", "ca": "1/s", "cb": "s"}


def _label(name: str) -> str:
    base, sep, _ = name.partition("[")
    if sep and base in _UNITS:  # a record's own value of a parameter, g_v[data_steps]
        return f"{name} ({_UNITS[base]})"
    if name in _UNITS:
        return f"{name} ({_UNITS[name]})"
    if name[0] == "m" and name[1:].isdigit():
        return f"{name} (kg)"
    if name.startswith("sigma"):
        return f"{name} (mm)"
    if name.startswith("phi"):
        return name
    if name[0] == "c":
        return f"{name} (N s/m)"
    return name


def _names(idata, var_names):
    if var_names is not None:
        return list(var_names)
    return json.loads(idata.posterior.attrs["parameter_names"])


def plot_trace(idata, *, var_names=None, axes=None):
    """Trace of every walker (thin lines) and the pooled marginal histogram.

    Parameters
    ----------
    idata : arviz.InferenceData
    var_names : sequence of str, optional
        Parameters to show (default all).
    axes : ndarray of Axes, shape (n_vars, 2), optional

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (n_vars, 2)
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    names = _names(idata, var_names)
    if axes is None:
        fig, axes = plt.subplots(len(names), 2, figsize=(9, 1.6 * len(names) + 0.8),
                                 squeeze=False, gridspec_kw={"width_ratios": [3, 1]},
                                 layout="constrained")
    axes = np.asarray(axes).reshape(len(names), 2)
    a = idata.posterior.attrs
    for i, nm in enumerate(names):
        x = _scale(nm) * idata.posterior[nm].values  # (chain, draw); noise in mm
        axes[i, 0].plot(x.T, lw=0.4, alpha=0.5)
        # a record's parameter (g_v[data_steps]) on two lines, so that it fits the row
        base, sep, record = nm.partition("[")
        if sep:
            axes[i, 0].set_ylabel(f"{_label(base)}\n[{record}", fontsize=7)
        else:
            axes[i, 0].set_ylabel(_label(nm), fontsize=8)
        axes[i, 1].hist(x.ravel(), bins=40, color="0.4")
        axes[i, 1].set_yticks([])
        # plain numbers (an offset text would sit on the tick labels of the panel above),
        # three of them, so that long values of the narrow histogram stay apart
        for ax_ in axes[i]:
            ax_.ticklabel_format(useOffset=False)
            ax_.tick_params(labelsize=7)
        axes[i, 0].yaxis.set_major_locator(MaxNLocator(3))
        axes[i, 1].xaxis.set_major_locator(MaxNLocator(3))
        if i < len(names) - 1:  # the draws are the same on every row
            axes[i, 0].sharex(axes[-1, 0])
            axes[i, 0].tick_params(labelbottom=False)
    axes[-1, 0].set_xlabel(f"retained draw (every {a.get('thin', 1)} steps after "
                           f"{a.get('burn', 0)} burn-in)")
    axes[-1, 1].set_xlabel("value")
    axes[0, 0].set_title("walker traces")
    axes[0, 1].set_title("marginal")
    return axes


def _scale(name: str) -> float:
    """Factor from the stored unit to the plotted one (noise levels in mm)."""
    return 1e3 if name.startswith("sigma") else 1.0


def posterior_limits(x: np.ndarray, *, q: float = 0.005, pad: float = 0.08
                     ) -> tuple[float, float]:
    """Axis limits that frame the bulk of a sample: the ``q`` and ``1 - q`` quantiles,
    widened by ``pad`` times their distance on each side.

    Examples
    --------
    >>> lo, hi = posterior_limits(np.linspace(0.0, 1.0, 1001), q=0.0, pad=0.1)
    >>> round(lo, 6), round(hi, 6)
    (-0.1, 1.1)
    """
    lo, hi = np.quantile(np.asarray(x, dtype=float), [q, 1.0 - q])
    span = hi - lo
    if not span > 0:
        span = max(abs(lo), 1e-12) * 1e-3
    return float(lo - pad * span), float(hi + pad * span)


def _mark_reference(a, value: float, lim: tuple[float, float], axis: str, *,
                    text: bool = False) -> None:
    """A reference value on one axis: a line when inside the limits, otherwise an arrow at
    the edge it lies beyond (with the value written next to it when ``text``)."""
    lo, hi = lim
    if lo <= value <= hi:
        (a.axvline if axis == "x" else a.axhline)(value, color="C3", lw=0.8)
        return
    above = value > hi
    if axis == "x":
        pos = (1.0 if above else 0.0, 0.9)
        marker = ">" if above else "<"
    else:
        pos = (0.1, 1.0 if above else 0.0)
        marker = "^" if above else "v"
    a.plot([pos[0]], [pos[1]], marker=marker, color="C3", ms=5, transform=a.transAxes,
           clip_on=False)
    if text:
        a.annotate(f"LSQ {value:.4g}", xy=pos, xycoords="axes fraction",
                   xytext=(-5 if above else 5, 0), textcoords="offset points",
                   ha="right" if above else "left", va="center", fontsize=6, color="C3",
                   bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 0.5})


def plot_corner(idata, *, var_names=None, axes=None, reference=None):
    """Corner plot: pairwise scatter of the draws below the diagonal, histograms on it.

    Axes are zoomed on the posterior (0.5 to 99.5 % quantiles, padded); a reference value
    outside them is marked by an arrow at the edge with its value, not by stretching the
    axes.  (ArviZ's ``plot_pair`` triggers a matplotlib 3.11 deprecation warning, so the
    grid is drawn directly.)

    Parameters
    ----------
    idata : arviz.InferenceData
    var_names : sequence of str, optional
        Default: the mechanical parameters.
    axes : ndarray of Axes, shape (n, n), optional
    reference : dict of str to float, optional
        Values to mark in red (e.g. the LSQ estimate), in the stored units (noise levels
        in m; plotted in mm).

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (n, n)
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    names = list(var_names) if var_names is not None else json.loads(
        idata.posterior.attrs["mechanical_names"])
    n = len(names)
    x = np.stack([_scale(nm) * idata.posterior[nm].values.ravel() for nm in names], axis=1)
    lims = [posterior_limits(x[:, i]) for i in range(n)]
    ref = {nm: _scale(nm) * float(v) for nm, v in (reference or {}).items()}
    if axes is None:
        fig, axes = plt.subplots(n, n, figsize=(1.45 * n + 1.2, 1.45 * n + 1.2),
                                 squeeze=False)
        fig.subplots_adjust(wspace=0.08, hspace=0.08, left=0.09, bottom=0.09, right=0.98,
                            top=0.97)
    axes = np.asarray(axes).reshape(n, n)
    for i in range(n):
        for j in range(n):
            a = axes[i, j]
            if j > i:
                a.set_visible(False)
                continue
            if i == j:
                a.hist(x[:, i], bins=30, range=lims[i], color="0.4")
                a.set_yticks([])
            else:
                a.plot(x[:, j], x[:, i], ".", ms=1, alpha=0.3, color="C0")
                a.set_ylim(lims[i])
            a.set_xlim(lims[j])
            if names[j] in ref:  # the value is written once, on the diagonal
                _mark_reference(a, ref[names[j]], lims[j], "x", text=i == j)
            if i != j and names[i] in ref:
                _mark_reference(a, ref[names[i]], lims[i], "y")
            a.xaxis.set_major_locator(MaxNLocator(3))
            if i != j:
                a.yaxis.set_major_locator(MaxNLocator(3))
            a.ticklabel_format(style="plain", useOffset=False)
            a.tick_params(labelsize=6)
            if i < n - 1:
                a.set_xticklabels([])
            else:
                a.set_xlabel(_label(names[j]), fontsize=7)
                # upright: a label turned 45 degrees to the left runs into the last one
                # of the panel to its left
                for t in a.get_xticklabels():
                    t.set_rotation(90)
                    t.set_ha("center")
            if j == 0 and i > 0:
                a.set_ylabel(_label(names[i]), fontsize=7)
            elif i != j:
                a.set_yticklabels([])
    if reference:
        axes[0, 0].figure.text(
            0.55, 0.9, "red line: least-squares (LSQ) value\nred arrow at an edge: LSQ value "
            "outside the axes,\nin that direction (value written on the diagonal)",
            fontsize=9, color="C3", va="top")
    return axes


def plot_predictive(idata, *, experiment: str | None = None, prob: float = 0.9, axes=None,
                    t_range: tuple[float, float] | None = None):
    """Posterior-predictive bands over the measured outputs, with residuals.

    For each output: the measurement, the median noise-free prediction, the credible band
    of the noise-free prediction (parameter uncertainty) and the wider band of replicated
    measurements (parameters and noise); below it the residual of the median prediction
    with the predictive band of the noise.

    Parameters
    ----------
    idata : arviz.InferenceData
        With ``posterior_predictive`` (``y``, ``y_hat``) and ``observed_data``.
    experiment : str, optional
        Which experiment (default the first).
    prob : float
        Band probability.
    axes : ndarray of Axes, shape (2 * n_out,), optional
    t_range : (float, float), optional
        Time window to show, s.

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2 * n_out,)
    """
    import matplotlib.pyplot as plt

    obs = idata.observed_data
    names = obs["experiment"].values.astype(str)
    exp = names[0] if experiment is None else experiment
    sel = names == exp
    if not np.any(sel):
        raise ValueError(f"no experiment {exp!r}; have {sorted(set(names))}")
    t = obs["t_s"].values[sel]
    y = obs["y"].values[sel]
    pp = idata.posterior_predictive
    yrep = pp["y"].values[:, :, sel].reshape(-1, sel.sum(), y.shape[1])
    yhat = pp["y_hat"].values[:, :, sel].reshape(-1, sel.sum(), y.shape[1])
    qa = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    h_lo, h_med, h_hi = np.quantile(yhat, qa, axis=0)
    r_lo, _, r_hi = np.quantile(yrep, qa, axis=0)
    n_lo, _, n_hi = np.quantile(yrep - yhat, qa, axis=0)
    w = slice(None) if t_range is None else (t >= t_range[0]) & (t <= t_range[1])
    n_out = y.shape[1]
    if axes is None:
        fig, axes = plt.subplots(2 * n_out, 1, figsize=(9, 2.2 * 2 * n_out + 0.6),
                                 sharex=True, layout="constrained",
                                 gridspec_kw={"height_ratios": [2, 1] * n_out})
    axes = np.asarray(axes).ravel()
    mm = 1e3
    for j in range(n_out):
        a, b = axes[2 * j], axes[2 * j + 1]
        a.fill_between(t[w], r_lo[w, j] * mm, r_hi[w, j] * mm, color="C0", alpha=0.2,
                       lw=0, label=f"{prob:.0%} predictive (parameters + noise)")
        a.fill_between(t[w], h_lo[w, j] * mm, h_hi[w, j] * mm, color="C1", alpha=0.5,
                       lw=0, label=f"{prob:.0%} model output (parameters)")
        a.plot(t[w], y[w, j] * mm, "k", lw=0.6, label="measured")
        a.plot(t[w], h_med[w, j] * mm, "C1", lw=0.6, label="median model output")
        a.set_ylabel(f"x{j + 1} (mm)")
        res = (y[:, j] - h_med[:, j]) * mm
        b.fill_between(t[w], n_lo[w, j] * mm, n_hi[w, j] * mm, color="C0", alpha=0.2, lw=0)
        b.plot(t[w], res[w], "k", lw=0.5)
        b.axhline(0, color="0.5", lw=0.5)
        b.set_ylabel("residual (mm)")
    # one legend below the panels, where it hides no part of the record
    fig = axes[0].figure
    fig.suptitle(f"posterior predictive, {exp} ({idata.posterior.attrs.get('damping')} "
                 f"damping, {idata.posterior.attrs.get('noise')} noise)", fontsize=10)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=4,
               fontsize=7, frameon=False)
    axes[-1].set_xlabel("time (s)")
    return axes


def _hz_ticks(ax, f_lo: float, f_hi: float) -> None:
    """Readable ticks on a log frequency axis in Hz (1-2-5 steps, plain numbers)."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    steps = np.array([1.0, 2.0, 5.0])
    dec = np.arange(np.floor(np.log10(f_lo)), np.ceil(np.log10(f_hi)) + 1)
    ticks = np.sort((steps[None, :] * 10.0 ** dec[:, None]).ravel())
    ticks = ticks[(ticks >= f_lo * 0.999) & (ticks <= f_hi * 1.001)]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def measured_frfs(idata, *, min_input_power: float = 1e-3):
    """H1 estimates (``bayesmodal.ema.frf_from_experiment``) of the records a run was
    fitted to, restricted to frequencies the input excites.

    Parameters
    ----------
    idata : arviz.InferenceData
    min_input_power : float
        Frequencies where the input auto-spectrum is below this fraction of its maximum
        (near the zeros of a pulse's spectrum) are dropped: the estimate is noise there.

    Returns
    -------
    list of (str, FRF)
        Record name and its FRF, m/V; records the estimator cannot handle are left out.
    """

    out = []
    for e in experiments_from_idata(idata):
        try:
            frf = frf_from_experiment(e)
        except (DataError, ValueError):
            continue
        if frf.input_power is not None:
            keep = frf.input_power >= min_input_power
            if np.count_nonzero(keep) < 2:
                continue
            from dataclasses import replace

            frf = replace(frf, omega_rad_s=frf.omega_rad_s[keep], H=frf.H[keep],
                          coherence=None if frf.coherence is None else frf.coherence[keep],
                          input_power=frf.input_power[keep])
        out.append((e.name, frf))
    return out


def plot_bode_bands(idata, *, omega_rad_s=None, prob: float = 0.9, input: str = "voltage",
                    n_draws: int = 200, measured=None, f_max_hz: float | None = None,
                    axes=None):
    """Bode diagram in Hz with the posterior credible bands and the measured FRF.

    Three panels: magnitude (dB), phase (deg), and the width of the credible band of the
    magnitude (dB), which shows the band even where it is thinner than a line.  The
    natural frequencies of the posterior median are marked.

    Parameters
    ----------
    idata : arviz.InferenceData
    omega_rad_s : ndarray, shape (n_freq,), optional
        Frequency grid, rad/s (default log-spaced from 0.2 Hz to ``f_max_hz``).
    prob : float
    input : {"voltage", "force"}
        Transfer function X/V (m/V) or X/F (m/N).
    n_draws : int
        Evenly spaced draws used for the bands.
    measured : sequence of (str, FRF), optional
        Measured FRFs to overlay (default :func:`measured_frfs` of the fitted records when
        ``input`` is ``"voltage"``; pass ``[]`` for none).
    f_max_hz : float, optional
        Upper end of the default grid, Hz (default 0.8 of the Nyquist frequency of the
        fitted records, the band the residual diagnostics search, or 80 Hz).
    axes : sequence of three Axes, optional

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (3,)
    """
    import matplotlib.pyplot as plt


    model = model_from_idata(idata)
    draws = posterior_matrix(idata, list(model.names)).reshape(-1, model.n_params)
    idx = np.unique(np.linspace(0, len(draws) - 1, min(n_draws, len(draws))).round()
                    .astype(int))
    if f_max_hz is None:
        t = idata.observed_data["t_s"].values
        dt = float(np.median(np.diff(t[:1000]))) if t.size > 1 else 0.0
        f_max_hz = 0.8 * 0.5 / dt if dt > 0 else 80.0
    w = (2 * np.pi * np.geomspace(0.2, f_max_hz, 800) if omega_rad_s is None
         else np.asarray(omega_rad_s, dtype=float))
    f = w / (2 * np.pi)
    H = transfer_function(model, draws[idx], w, input=input)  # (S, n_freq, n_out)
    db = 20 * np.log10(np.maximum(np.abs(H), np.finfo(float).tiny))
    ph = np.degrees(np.unwrap(np.angle(H), axis=1))
    qa = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    m_lo, m_med, m_hi = np.quantile(db, qa, axis=0)
    p_lo, p_med, p_hi = np.quantile(ph, qa, axis=0)
    unit = "m/V" if input == "voltage" else "m/N"
    if measured is None:
        measured = measured_frfs(idata) if input == "voltage" else []
    if axes is None:
        fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True, layout="constrained",
                                 gridspec_kw={"height_ratios": [3, 2, 1.2]})
    axes = np.asarray(axes).ravel()
    n_out = db.shape[2]
    for j in range(n_out):
        c = f"C{j}"
        axes[0].fill_between(f, m_lo[:, j], m_hi[:, j], color=c, alpha=0.35, lw=0)
        axes[0].plot(f, m_med[:, j], color=c, lw=0.9, label=f"x{j + 1} model (median)")
        axes[1].fill_between(f, p_lo[:, j], p_hi[:, j], color=c, alpha=0.35, lw=0)
        axes[1].plot(f, p_med[:, j], color=c, lw=0.9)
        axes[2].plot(f, m_hi[:, j] - m_lo[:, j], color=c, lw=1.0)
    for k, (name, frf) in enumerate(measured):
        fm = frf.omega_rad_s / (2 * np.pi)
        sel = (fm >= f[0]) & (fm <= f[-1])
        for j in range(min(n_out, frf.n_outputs)):
            hj = frf.H[sel, j]
            axes[0].plot(fm[sel], 20 * np.log10(np.maximum(np.abs(hj), 1e-300)), ".",
                         ms=1.6, color=f"C{j}", alpha=0.6,
                         label=f"x{j + 1} measured H1 ({name})" if k == 0 or j == 0 else None)
            # the measured phase wraps; shift it by whole turns to the model's phase
            phm = np.degrees(np.angle(hj))
            ref = np.interp(fm[sel], f, p_med[:, j])
            phm = phm + 360.0 * np.round((ref - phm) / 360.0)
            axes[1].plot(fm[sel], phm, ".", ms=1.6, color=f"C{j}", alpha=0.6)
    fn = propagate_modes(model, np.median(draws, axis=0)[None], methods=("eig",))
    for i, om in enumerate(np.asarray(fn.omega_rad_s).ravel()):
        for a in axes:
            a.axvline(om / (2 * np.pi), color="0.4", lw=0.6, ls=":")
        axes[0].annotate(f"mode {i + 1}\n{om / (2 * np.pi):.2f} Hz",
                         (om / (2 * np.pi), 1.0), xycoords=("data", "axes fraction"),
                         xytext=(3, -3), textcoords="offset points", va="top", fontsize=8,
                         color="0.2", bbox={"facecolor": "white", "edgecolor": "none",
                                            "alpha": 0.85, "pad": 1.0})
    # the magnitude axis spans what was measured, not the model's roll-off far below the
    # noise floor of the encoders
    meas_db = [20 * np.log10(np.maximum(np.abs(frf.H), 1e-300)).ravel() for _, frf in measured]
    low = np.min(m_med)
    if meas_db:
        low = max(low, np.percentile(np.concatenate(meas_db), 0.5) - 10.0)
    axes[0].set_ylim(low, max(np.max(m_hi), *(np.max(x) for x in meas_db)) + 5.0)
    for a in axes:
        a.set_xscale("log")
        a.grid(True, which="both", alpha=0.3)
        a.set_xlim(f[0], f[-1])
    _hz_ticks(axes[-1], f[0], f[-1])
    axes[0].set_ylabel(f"|H| (dB re 1 {unit})")
    axes[1].set_ylabel("phase (deg)")
    axes[2].set_ylabel(f"{prob:.0%} band\nwidth (dB)")
    axes[2].set_xlabel("frequency (Hz)")
    axes[0].legend(loc="lower left", fontsize=7, ncol=2, markerscale=4)
    axes[0].set_title(f"motor voltage to cart position: model median with {prob:.0%} "
                      "credible band (shaded), measured H1 (dots)", fontsize=9)
    return axes


def plot_modal_intervals(modal, *, reference=None, lsce=None, prob: float = 0.9,
                         axes=None):
    """Posterior intervals of natural frequency (Hz) and damping ratio per mode, with the
    least-squares and LSCE values.

    Parameters
    ----------
    modal : ModalSamples
        Posterior modal samples (``bayesmodal.inference.propagate_modes``).
    reference : ModalSamples, optional
        Modal quantities of the LSQ estimate (one system), drawn as red crosses.
    lsce : sequence of (str, ndarray, ndarray), optional
        Per record: name, natural frequencies (rad/s, shape (n_modes,), NaN where no mode
        was matched) and damping ratios of the LSCE estimate, drawn as diamonds.
    prob : float
    axes : ndarray of Axes, shape (2, n_modes), optional

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2, n_modes)
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator


    iv = modal_intervals(modal, prob)
    n = modal.n_modes
    lsce = list(lsce or [])
    if axes is None:
        fig, axes = plt.subplots(2, n, figsize=(2.9 * n + 1, 5.2), squeeze=False,
                                 layout="constrained")
    axes = np.asarray(axes).reshape(2, n)
    hz = 1.0 / (2.0 * np.pi)
    for row, (key, lab, k) in enumerate((("omega_rad_s", "natural frequency (Hz)", hz),
                                         ("zeta", "damping ratio zeta (-)", 1.0))):
        q = iv[key]
        for i in range(n):
            a = axes[row, i]
            a.plot([0, 0], [k * q.lo[i], k * q.hi[i]], color="C0", lw=5, alpha=0.6,
                   solid_capstyle="butt", label=f"{prob:.0%} equal-tailed interval")
            a.plot([0.2, 0.2], [k * q.hdi_lo[i], k * q.hdi_hi[i]], color="C2", lw=2,
                   label=f"{prob:.0%} HDI")
            a.plot(0, k * q.median[i], "o", color="C0", ms=5, label="posterior median")
            if reference is not None:
                ref = np.asarray(getattr(reference, key)).reshape(-1, n)[0, i]
                a.plot(0.45, k * ref, "x", color="C3", ms=8, mew=2, label="least squares")
            for r, (name, om, ze) in enumerate(lsce):
                v = np.asarray(om if row == 0 else ze, dtype=float)
                if i < v.size and np.isfinite(v[i]):
                    a.plot(0.7 + 0.12 * r, k * v[i], "D", color=f"C{4 + r}", ms=6,
                           label=f"LSCE ({name})")
            a.set_xlim(-0.4, 1.0 + 0.12 * max(len(lsce) - 1, 0))
            a.margins(y=0.15)
            a.set_xticks([])
            a.yaxis.set_major_locator(MaxNLocator(4))
            a.ticklabel_format(axis="y", style="plain", useOffset=False)
            a.tick_params(axis="y", labelsize=8)
            a.grid(axis="y", alpha=0.3)
            a.set_title(f"mode {i + 1}", fontsize=9)
            if i == 0:
                a.set_ylabel(lab)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    for a in axes.ravel():  # a mode without an LSCE match has fewer entries
        h, lb = a.get_legend_handles_labels()
        if len(lb) > len(labels):
            handles, labels = h, lb
    axes[0, 0].figure.legend(handles, labels, loc="outside lower center",
                             ncol=min(len(labels), 5), fontsize=8, frameon=False)
    return axes
