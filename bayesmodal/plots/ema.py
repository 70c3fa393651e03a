"""Plots of the experimental modal analysis: FRF with fit, Nyquist circle, stabilisation.

Each function takes a result of :mod:`bayesmodal.ema` and keyword-only options, draws on
``ax`` if given (a new figure otherwise) and returns the axes.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError
from ..ema.peaks import mode_indicator

__all__ = [
    "plot_frf",
    "plot_nyquist",
    "plot_stabilization",
    "plot_error_curve",
    "plot_coherence",
    "plot_spectrogram",
    "save_ema_figures",
]


def _new(ax, nrows=1, **kw):
    import matplotlib.pyplot as plt

    if ax is not None:
        return ax
    _, axes = plt.subplots(nrows, 1, layout="constrained", **kw)
    return axes


def plot_frf(frf, *, fitted=None, estimate=None, ax=None, band=None, fit_band=None,
             outputs=None, labels=None):
    """Magnitude and phase of a measured FRF, with a fitted model and the modes found.

    Parameters
    ----------
    frf : bayesmodal.ema.FRF
    fitted : ndarray of complex, shape (n_freq, n_outputs), optional
        Model FRF on ``frf.omega_rad_s`` (dashed), e.g. ``EMAResult.fitted``.
    estimate : ModalEstimate, optional
        Identified modes are marked by vertical lines at ``Im(lambda)``.
    ax : sequence of two Axes, optional
        Magnitude and phase axes.
    band : (lo, hi), optional
        Frequency range shown, rad/s.
    fit_band : (lo, hi), optional
        Range where the fitted model is drawn (the band it was fitted on), rad/s.
    outputs : sequence of int, optional
        Outputs to draw (all by default).
    labels : sequence of str, optional
        Output names (default ``x1, x2, ...``).

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2,)

    Examples
    --------
    >>> from bayesmodal.ema import FRF
    >>> w = np.linspace(1, 20, 200)
    >>> axes = plot_frf(FRF(w, 1 / (100 - w**2 + 0.4j * w)))
    >>> axes[1].get_xlabel()
    'frequency (rad/s)'
    """
    axes = _new(ax, 2, sharex=True, figsize=(7, 6))
    w = frf.omega_rad_s
    sel = np.ones(w.size, bool) if band is None else (w >= band[0]) & (w <= band[1])
    outs = range(frf.n_outputs) if outputs is None else outputs
    for j, i in enumerate(outs):
        name = labels[j] if labels is not None else f"x{i + 1}"
        color = f"C{j}"
        axes[0].semilogy(w[sel], np.abs(frf.H[sel, i]), color=color, label=f"{name} measured")
        axes[1].plot(w[sel], np.degrees(np.unwrap(np.angle(frf.H[sel, i]))), color=color)
        if fitted is not None:
            fsel = sel if fit_band is None else sel & (w >= fit_band[0]) & (w <= fit_band[1])
            f = np.asarray(fitted)[fsel, i]
            axes[0].semilogy(w[fsel], np.abs(f), "--", color=color, label=f"{name} fit")
            axes[1].plot(w[fsel], np.degrees(np.unwrap(np.angle(f))), "--", color=color)
    if estimate is not None:
        for k in range(estimate.n_modes):
            if estimate.identified[k] and np.isfinite(estimate.poles[k]):
                for a in axes:
                    a.axvline(estimate.poles[k].imag, color="0.5", lw=0.8, ls=":")
    axes[0].set_ylabel(f"|H| ({frf.units})")
    axes[1].set_ylabel("phase (deg)")
    axes[1].set_xlabel("frequency (rad/s)")
    axes[0].legend(fontsize="small", ncol=2)
    axes[0].set_title(f"FRF ({frf.estimator}, {frf.n_averages} average(s))")
    return np.asarray(axes)


def plot_nyquist(fit, *, ax=None, n_circle: int = 200):
    """Nyquist plot of a circle fit: FRF points, fitted circle, resonance and residual.

    Parameters
    ----------
    fit : bayesmodal.ema.CircleFit
    ax : matplotlib Axes, optional
    n_circle : int
        Points drawn on the circle.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> from bayesmodal.ema import circle_fit
    >>> w = np.linspace(9, 11, 41)
    >>> ax = plot_nyquist(circle_fit(w, 1 / (100 - w**2 + 0.4j * w)))
    >>> ax.get_xlabel()
    'Re H'
    """
    ax = _new(ax, figsize=(5.5, 5.5))
    z = fit.H
    ax.plot(z.real, z.imag, "o", ms=4, label="FRF points")
    phi = np.linspace(0, 2 * np.pi, n_circle)
    c = fit.centre + fit.radius * np.exp(1j * phi)
    ax.plot(c.real, c.imag, "-", lw=1, label="fitted circle")
    res = fit.model(np.array([fit.pole.imag]))[0]
    ax.plot(res.real, res.imag, "s", color="C3",
            label=f"resonance nu = {fit.pole.imag:.4g} rad/s, zeta = {fit.zeta:.3g}")
    ax.plot(fit.residual.real, fit.residual.imag, "x", color="C2", label="R + jI (other modes)")
    ax.plot(fit.centre.real, fit.centre.imag, "+", color="k")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("Re H")
    ax.set_ylabel("Im H")
    ax.set_title("circle fit")
    ax.legend(fontsize="small")
    return ax


def plot_stabilization(diagram, *, ax=None, frf=None, band=None):
    """Stabilisation diagram: pole frequencies against model order.

    Parameters
    ----------
    diagram : bayesmodal.ema.StabilizationDiagram
    ax : matplotlib Axes, optional
    frf : FRF, optional
        Its mode indicator is drawn on a second y-axis for orientation.
    band : (lo, hi), optional
        Frequency range shown, rad/s.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> from bayesmodal.ema import stabilization_diagram
    >>> t = np.arange(300) * 0.1
    >>> d = stabilization_diagram(np.exp(-0.1 * t) * np.sin(2 * t), 0.1, orders=[1, 2, 3])
    >>> plot_stabilization(d).get_ylabel()
    'number of modes n'
    """
    ax = _new(ax, figsize=(7, 5))
    style = {"new": ("o", "0.6", "new"), "freq": ("^", "C1", "frequency stable"),
             "stable": ("*", "C2", "stable (frequency and damping)")}
    seen = set()
    for n, poles, status, ident in zip(diagram.orders, diagram.poles, diagram.status,
                                       diagram.identified, strict=True):
        for lam, st, ok in zip(poles, status, ident, strict=True):
            w = abs(lam)
            if band is not None and not band[0] <= w <= band[1]:
                continue
            marker, color, label = style[st]
            if not ok:
                marker, color, label = "x", "0.75", "computational"
            key = label
            ax.plot(w, n, marker, color=color, ms=6, mfc="none" if marker == "o" else color,
                    label=None if key in seen else label)
            seen.add(key)
    ax.set_xlabel("natural frequency |lambda| (rad/s)")
    ax.set_ylabel("number of modes n")
    if frf is not None:
        ax2 = ax.twinx()
        w = frf.omega_rad_s
        sel = np.ones(w.size, bool) if band is None else (w >= band[0]) & (w <= band[1])
        ax2.semilogy(w[sel], mode_indicator(frf)[sel], color="0.3", lw=0.8)
        ax2.set_ylabel("mode indicator sum |H_i| / max |H_i|")
    # the legend, headed by the title, above the axes: inside it would hide the poles
    ax.legend(fontsize="small", loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4,
              frameon=False, title="stabilisation diagram")
    return ax


def plot_error_curve(curve, *, ax=None):
    """LSCE least-squares error against the number of modes (lecture 11d).

    Parameters
    ----------
    curve : bayesmodal.ema.ErrorCurve
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _new(ax, figsize=(6, 4))
    ax.semilogy(curve.orders, curve.error, "o-", label="|B alpha - R|^2 / |R|^2")
    ax.semilogy(curve.orders, curve.reconstruction_error, "s--",
                label="|h - h_fit| / |h| (P samples)")
    ax.set_xlabel("number of modes n")
    ax.set_ylabel("relative least-squares error (-)")
    ax.set_xticks(curve.orders)
    ax.set_title("LSCE error against model order")
    ax.legend(fontsize="small")
    return ax


def plot_coherence(frf, *, ax=None, band=None):
    """Ordinary coherence of an FRF estimate.

    Parameters
    ----------
    frf : FRF
        With ``coherence`` (at least two averages).
    ax : matplotlib Axes, optional
    band : (lo, hi), optional

    Returns
    -------
    matplotlib.axes.Axes
    """

    if frf.coherence is None:
        raise DataError("this FRF has no coherence (a single average)")
    ax = _new(ax, figsize=(7, 3.5))
    w = frf.omega_rad_s
    sel = np.ones(w.size, bool) if band is None else (w >= band[0]) & (w <= band[1])
    for i in range(frf.n_outputs):
        ax.plot(w[sel], frf.coherence[sel, i], label=f"x{i + 1}")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("frequency (rad/s)")
    ax.set_ylabel("coherence gamma^2 (-)")
    ax.legend(fontsize="small")
    return ax


def plot_spectrogram(sg, *, ax=None, omega_max=None, db: bool = True):
    """Spectrogram of a signal (e.g. a sine sweep), frequency against time.

    Parameters
    ----------
    sg : bayesmodal.ema.Spectrogram
    ax : matplotlib Axes, optional
    omega_max : float, optional
        Upper frequency shown, rad/s.
    db : bool
        Colour scale in dB.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _new(ax, figsize=(7, 4))
    sel = np.ones(sg.omega_rad_s.size, bool) if omega_max is None else sg.omega_rad_s <= omega_max
    P = sg.psd[sel]
    C = 10 * np.log10(P + 1e-30) if db else P
    m = ax.pcolormesh(sg.t_s, sg.omega_rad_s[sel], C, shading="auto")
    ax.figure.colorbar(m, ax=ax, label="PSD (dB)" if db else "PSD")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("frequency (rad/s)")
    ax.set_title("spectrogram")
    return ax


def save_ema_figures(result, directory) -> list:
    """Write the figures of an ``EMAResult`` as PNG files.

    Files: ``frf.png`` (FRF with the fitted model and the modes), ``coherence.png`` (when
    the FRF has coherence), ``nyquist_mode<k>.png`` (circle fits, output with the largest
    circle), ``stabilization.png`` (LSCE with a stabilisation diagram).

    Parameters
    ----------
    result : bayesmodal.ema.EMAResult
    directory : path-like
        Created if missing.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    from pathlib import Path

    import matplotlib.pyplot as plt

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    written = []

    def save(ax, name):
        fig = np.ravel(ax)[0].figure
        path = out / name
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    lo, hi = result.band
    band = (0.0, 1.2 * hi)
    save(plot_frf(result.frf, fitted=result.fitted, estimate=result.estimate, band=band,
                  fit_band=(lo, hi)), "frf.png")
    if result.frf.coherence is not None:
        save(plot_coherence(result.frf, band=band), "coherence.png")
    fits = getattr(result.details, "fits", None)
    if fits is not None:
        for k, row in enumerate(fits):
            ok = [f for f in row if f is not None]
            if ok:
                best = max(ok, key=lambda f: f.radius)
                save(plot_nyquist(best), f"nyquist_mode{k + 1}.png")
    if result.stabilization is not None:
        save(plot_stabilization(result.stabilization, frf=result.frf, band=band),
             "stabilization.png")
    return written
