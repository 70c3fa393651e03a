"""Peaks in the residual spectrum: an unmodelled mode.

A resonance the model lacks (a fourth degree of freedom, the motor, the frame) leaves a
narrow peak in the residual spectrum away from the modelled natural frequencies.  The
Welch estimate ``P(f)`` of a smooth spectrum ``S(f)`` has ``P / S`` distributed as
``chi2(nu) / nu`` with ``nu`` about twice the number of averaged segments; ``S`` is taken
as a running median of ``P`` over neighbouring bins (a peak narrower than the median
window does not move it).  A bin is a peak when ``P / S`` exceeds the ``1 - alpha / m``
quantile (Bonferroni over the ``m`` bins tested).  Peaks within ``mode_tolerance`` of a
modelled natural frequency (or two frequency bins) are reported but not counted: the
residual of a slightly wrong model always peaks there; so are peaks below ``min_ratio``
times the background.
"""

from __future__ import annotations

import numpy as np
from scipy import signal, stats
from scipy.ndimage import median_filter

from ...model.effects import suggested_by
from ._result import Diagnostic
from .residuals import LinearResiduals

__all__ = ["residual_spectrum", "model_frequencies_hz"]


def model_frequencies_hz(res: LinearResiduals) -> np.ndarray:
    """Undamped natural frequencies of the fitted model, Hz, ascending."""
    M, _, K, _ = res.matrices()
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    return np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi)


def residual_spectrum(
    res: LinearResiduals,
    *,
    nperseg: int = 512,
    median_bins: int = 15,
    f_min_hz: float = 0.5,
    f_max_hz: float | None = None,
    mode_tolerance: float = 0.15,
    min_ratio: float = 5.0,
    alpha: float = 0.01,
) -> Diagnostic:
    """Narrow peaks in the residual PSD away from the modelled modes.

    Parameters
    ----------
    res : LinearResiduals
    nperseg : int
        Welch segment length, samples (Hann window, 50 % overlap).
    median_bins : int
        Width of the running median that estimates the smooth spectrum, bins (odd).
    f_min_hz, f_max_hz : float
        Band searched, Hz (default up to 0.8 of Nyquist).
    mode_tolerance : float
        Relative distance to a modelled natural frequency within which a peak is
        attributed to that mode (at least two frequency bins).
    min_ratio : float
        Smallest peak-to-background ratio reported as detected (effect-size guard: the
        harmonics that friction and other nonlinearities spread are weaker).
    alpha : float
        Family-wise significance level.

    Returns
    -------
    Diagnostic
        ``statistic``: the largest ``P / S`` of a peak away from the modes (0 if none);
        ``p_value``: Bonferroni p of that ratio.  Detail: ``f_hz``, ``psd`` (n_out, nf)
        m^2/Hz, ``baseline`` (n_out, nf), ``limit`` (the ratio threshold), ``peaks`` (list
        of dict: output, f_hz, ratio, near_mode_hz or None), ``model_hz``.
    """
    dt = res.dt
    r = res.residual - res.residual.mean(axis=0)
    N = r.shape[0]
    nperseg = min(nperseg, N)
    f, P = signal.welch(r, fs=1 / dt, nperseg=nperseg, axis=0)
    P = P.T
    n_seg = max(1, (N - nperseg) // (nperseg // 2) + 1)
    nu = 2.0 * n_seg * 0.9  # Hann, 50 % overlap: slightly fewer than 2 K degrees of freedom
    f_max = 0.8 / (2 * dt) if f_max_hz is None else f_max_hz
    band = (f >= f_min_hz) & (f <= f_max)
    m = int(band.sum()) * P.shape[0]
    limit = stats.chi2.isf(alpha / max(m, 1), nu) / nu
    base = np.exp(median_filter(np.log(np.maximum(P, 1e-300)), size=(1, median_bins),
                                mode="nearest"))
    ratio = P / base
    model_hz = model_frequencies_hz(res)
    peaks = []
    best = (0.0, None)
    for j in range(P.shape[0]):
        cand = np.flatnonzero(band & (ratio[j] > limit))
        for k in cand:
            if (k > 0 and ratio[j, k - 1] > ratio[j, k]) or (
                k + 1 < f.size and ratio[j, k + 1] > ratio[j, k]
            ):
                continue  # not the local maximum
            dist = np.abs(f[k] - model_hz)
            tol = np.maximum(mode_tolerance * model_hz, 2 * (f[1] - f[0]))
            near = model_hz[np.argmin(dist / tol)] if np.any(dist < tol) else None
            peaks.append({"output": j, "f_hz": float(f[k]), "ratio": float(ratio[j, k]),
                          "near_mode_hz": None if near is None else float(near)})
            if near is None and ratio[j, k] > max(best[0], min_ratio):
                best = (float(ratio[j, k]), (j, float(f[k])))
    stat = best[0]
    p_fw = float(min(1.0, m * stats.chi2.sf(stat * nu, nu))) if stat > 0 else 1.0
    detected = best[1] is not None
    if detected:
        j, fk = best[1]
        summary = (f"unmodelled peak in the residual spectrum at {fk:.2f} Hz "
                   f"(output {j + 1}, {stat:.0f} x the background, p = {p_fw:.2g})")
    else:
        summary = (f"no residual-spectrum peak away from the modelled modes "
                   f"({len(peaks)} peak(s) at modelled modes)")
    return Diagnostic(
        name="residual_spectrum",
        statistic=float(stat),
        p_value=p_fw,
        threshold=None,
        detected=bool(detected),
        suggests=suggested_by("unmodelled_mode") if detected else (),
        location=f"output {best[1][0] + 1}" if detected else None,
        summary=summary,
        detail={"f_hz": f, "psd": P, "baseline": base, "limit": float(limit), "peaks": peaks,
                "model_hz": model_hz, "nu": nu, "alpha": alpha},
    )
