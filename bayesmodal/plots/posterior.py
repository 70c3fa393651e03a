"""Plots of a posterior run: traces, pairs, predictive bands, Bode bands, modal intervals.

Every function takes the InferenceData of :func:`bayesmodal.inference.to_inference_data`
(or the modal samples derived from it), draws on new axes unless ``ax``/``axes`` is given,
and returns the axes.  matplotlib is imported inside the functions.
"""

from __future__ import annotations

import json

import numpy as np

__all__ = [
    "plot_trace",
    "plot_corner",
    "plot_predictive",
    "plot_bode_bands",
    "plot_modal_intervals",
]

_UNITS = {"g_v": "N/V", "ca": "1/s", "cb": "s"}


def _label(name: str) -> str:
    if name in _UNITS:
        return f"{name} ({_UNITS[name]})"
    if name[0] == "m" and name[1:].isdigit():
        return f"{name} (kg)"
    if name.startswith("sigma"):
        return f"{name} (m)"
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

    names = _names(idata, var_names)
    if axes is None:
        fig, axes = plt.subplots(len(names), 2, figsize=(9, 1.6 * len(names) + 0.6),
                                 squeeze=False, gridspec_kw={"width_ratios": [3, 1]})
    axes = np.asarray(axes).reshape(len(names), 2)
    a = idata.posterior.attrs
    for i, nm in enumerate(names):
        x = idata.posterior[nm].values  # (chain, draw)
        axes[i, 0].plot(x.T, lw=0.4, alpha=0.5)
        axes[i, 0].set_ylabel(_label(nm), fontsize=8)
        axes[i, 1].hist(x.ravel(), bins=40, color="0.4")
        axes[i, 1].set_yticks([])
    axes[-1, 0].set_xlabel(f"retained draw (every {a.get('thin', 1)} steps after "
                           f"{a.get('burn', 0)} burn-in)")
    axes[-1, 1].set_xlabel("value")
    axes[0, 0].set_title("walker traces")
    axes[0, 1].set_title("marginal")
    return axes


def plot_corner(idata, *, var_names=None, axes=None, reference=None):
    """Corner plot: pairwise scatter of the draws below the diagonal, histograms on it.

    (ArviZ's ``plot_pair`` triggers a matplotlib 3.11 deprecation warning, so the grid is
    drawn directly.)

    Parameters
    ----------
    idata : arviz.InferenceData
    var_names : sequence of str, optional
        Default: the mechanical parameters.
    axes : ndarray of Axes, shape (n, n), optional
    reference : dict of str to float, optional
        Values to mark with red lines (e.g. the LSQ estimate).

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (n, n)
    """
    import matplotlib.pyplot as plt

    names = list(var_names) if var_names is not None else json.loads(
        idata.posterior.attrs["mechanical_names"])
    n = len(names)
    x = np.stack([idata.posterior[nm].values.ravel() for nm in names], axis=1)
    if axes is None:
        fig, axes = plt.subplots(n, n, figsize=(1.5 * n + 1, 1.5 * n + 1), squeeze=False)
        fig.subplots_adjust(wspace=0.05, hspace=0.05)
    axes = np.asarray(axes).reshape(n, n)
    for i in range(n):
        for j in range(n):
            a = axes[i, j]
            if j > i:
                a.set_visible(False)
                continue
            if i == j:
                a.hist(x[:, i], bins=30, color="0.4")
                a.set_yticks([])
            else:
                a.plot(x[:, j], x[:, i], ".", ms=1, alpha=0.3, color="C0")
            if reference is not None and names[j] in reference:
                a.axvline(reference[names[j]], color="C3", lw=0.8)
            if reference is not None and i != j and names[i] in reference:
                a.axhline(reference[names[i]], color="C3", lw=0.8)
            a.tick_params(labelsize=6)
            if i < n - 1:
                a.set_xticklabels([])
            else:
                a.set_xlabel(_label(names[j]), fontsize=7)
            if j == 0 and i > 0:
                a.set_ylabel(_label(names[i]), fontsize=7)
            elif i != j:
                a.set_yticklabels([])
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
        fig, axes = plt.subplots(2 * n_out, 1, figsize=(9, 2.2 * 2 * n_out), sharex=True,
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
    axes[0].legend(fontsize=7, loc="upper right", ncol=2)
    axes[0].set_title(f"posterior predictive, {exp} ({idata.posterior.attrs.get('damping')} "
                      f"damping, {idata.posterior.attrs.get('noise')} noise)")
    axes[-1].set_xlabel("time (s)")
    return axes


def plot_bode_bands(idata, *, omega_rad_s=None, prob: float = 0.9, input: str = "voltage",
                    n_draws: int = 200, ax=None):
    """Bode diagram with credible bands of magnitude and phase over posterior draws.

    Parameters
    ----------
    idata : arviz.InferenceData
    omega_rad_s : ndarray, shape (n_freq,), optional
        Frequency grid, rad/s (default 1 to 80 rad/s, log-spaced).
    prob : float
    input : {"voltage", "force"}
        Transfer function X/V (m/V) or X/F (m/N).
    n_draws : int
        Evenly spaced draws used for the bands.
    ax : sequence of two Axes, optional

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2,)
    """
    from ..inference.idata import model_from_idata, posterior_matrix
    from ..modal import transfer_function
    from .modal import plot_bode

    model = model_from_idata(idata)
    draws = posterior_matrix(idata, list(model.names)).reshape(-1, model.n_params)
    idx = np.unique(np.linspace(0, len(draws) - 1, min(n_draws, len(draws))).round()
                    .astype(int))
    w = np.geomspace(1.0, 80.0, 600) if omega_rad_s is None else np.asarray(omega_rad_s)
    H = transfer_function(model, draws[idx], w, input=input)  # (S, n_freq, n_out)
    mag = np.abs(H)
    ph = np.degrees(np.unwrap(np.angle(H), axis=1))
    qa = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    m_lo, m_med, m_hi = np.quantile(mag, qa, axis=0)
    p_lo, p_med, p_hi = np.quantile(ph, qa, axis=0)
    H_med = m_med * np.exp(1j * np.radians(p_med))
    unit = "m/V" if input == "voltage" else "m/N"
    return plot_bode(w, H_med, ax=ax, bands=(m_lo, m_hi), phase_bands=(p_lo, p_hi),
                     unit=unit)


def plot_modal_intervals(modal, *, reference=None, prob: float = 0.9, axes=None):
    """Posterior intervals of natural frequency and damping ratio per mode, LSQ marked.

    Parameters
    ----------
    modal : ModalSamples
        Posterior modal samples (``bayesmodal.inference.propagate_modes``).
    reference : ModalSamples, optional
        Modal quantities of the LSQ estimate (one system), drawn as red crosses.
    prob : float
    axes : ndarray of Axes, shape (2, n_modes), optional

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2, n_modes)
    """
    import matplotlib.pyplot as plt

    from ..inference.propagate import modal_intervals

    iv = modal_intervals(modal, prob)
    n = modal.n_modes
    if axes is None:
        fig, axes = plt.subplots(2, n, figsize=(2.6 * n + 1, 4.2), squeeze=False)
    axes = np.asarray(axes).reshape(2, n)
    for row, (key, lab) in enumerate((("omega_rad_s", "omega (rad/s)"), ("zeta", "zeta"))):
        q = iv[key]
        for i in range(n):
            a = axes[row, i]
            a.plot([0, 0], [q.lo[i], q.hi[i]], color="C0", lw=4, alpha=0.6,
                   label=f"{prob:.0%} equal-tailed")
            a.plot([0.15, 0.15], [q.hdi_lo[i], q.hdi_hi[i]], color="C2", lw=2,
                   label=f"{prob:.0%} HDI")
            a.plot(0, q.median[i], "o", color="C0", label="median")
            if reference is not None:
                ref = np.asarray(getattr(reference, key)).reshape(-1, n)[0, i]
                a.plot(0.3, ref, "x", color="C3", ms=8, mew=2, label="LSQ")
            a.set_xlim(-0.5, 0.8)
            a.margins(y=0.15)
            a.set_xticks([])
            a.ticklabel_format(axis="y", useOffset=False)
            a.set_title(f"mode {i + 1}", fontsize=9)
            if i == 0:
                a.set_ylabel(lab)
    axes[0, -1].legend(fontsize=7, loc="best")
    return axes
