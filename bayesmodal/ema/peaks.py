"""Peak picking: first estimates of the resonances from the FRF magnitude.

The mode indicator is the sum of magnitudes over the outputs,
``MIF(w) = sum_i |H_i(w)| / max |H_i|`` (each output scaled to unit maximum so that one
sensor does not dominate).  Its local maxima with a prominence on a log scale (a lightly
damped mode rises by about ``1 / (2 zeta)`` above its surroundings, whatever its level)
are resonance candidates; frequencies where the input had no energy (``FRF.reliable_mask``)
and peaks below 0.1 % of the largest are ignored.  Noise where ``|H|`` is tiny is prominent on a log
scale too, so when a number of peaks is asked for, the candidates are ranked by their
prominence on a linear scale.  Each peak is refined by a parabola through the three
points around the maximum (on the log scale), and its damping is estimated from the
half-power bandwidth (``MIF`` down by ``sqrt(2)``), ``zeta ~ (w_b - w_a) / (2 w_r)``.
These values seed the circle fit and the multi-mode fit; they are not final estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .._errors import DataError
from .frf import FRF, RELIABLE_INPUT_POWER

__all__ = ["Peaks", "pick_peaks", "mode_indicator"]


@dataclass(frozen=True)
class Peaks:
    """Resonance candidates, strongest first in ``prominence`` but sorted by frequency.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (n_peaks,)
        Peak frequency, rad/s.
    zeta : ndarray, shape (n_peaks,)
        Half-power-bandwidth damping ratio (NaN when a half-power point is missing).
    prominence : ndarray, shape (n_peaks,)
        Prominence of the peak in the log mode indicator (natural log units).
    band : ndarray, shape (n_peaks, 2)
        Suggested fitting band around each peak, rad/s: a few half-power widths, clipped
        halfway to the neighbouring peaks.
    """

    omega_rad_s: np.ndarray
    zeta: np.ndarray
    prominence: np.ndarray
    band: np.ndarray


def mode_indicator(frf: FRF, *, reliable: np.ndarray | None = None) -> np.ndarray:
    """Normalised mode indicator, shape (n_freq,): ``sum_i |H_i| / max |H_i|``.

    The maximum is taken over the reliable frequencies only (``frf.reliable_mask()`` by
    default): the estimate near a zero of the input spectrum would otherwise set the
    scale and flatten every resonance.
    """
    mag = np.abs(frf.H)
    ok = frf.reliable_mask() if reliable is None else np.asarray(reliable, bool)
    scale = np.max(mag[ok], axis=0) if np.any(ok) else np.max(mag, axis=0)
    scale[scale == 0] = 1.0
    return np.sum(mag / scale, axis=1)


def pick_peaks(
    frf: FRF,
    n_peaks: int | None = None,
    *,
    band: tuple[float, float] | None = None,
    min_prominence: float = 0.2,
    half_widths: float = 3.0,
    min_input_power: float = RELIABLE_INPUT_POWER,
    min_level: float = 1e-3,
) -> Peaks:
    """Find the resonance peaks of an FRF.

    Parameters
    ----------
    frf : FRF
    n_peaks : int, optional
        Keep the ``n_peaks`` peaks with the largest linear prominence (all by default).
    band : (lo, hi), optional
        Search band, rad/s.
    min_prominence : float
        Minimum prominence in the log mode indicator (0.2: a rise of about 22 %).
    half_widths : float
        Half-width of each suggested fitting band, in half-power bandwidths.
    min_input_power : float
        Frequencies where ``frf.input_power`` is below this fraction of its local envelope
        are ignored (``FRF.reliable_mask``: the estimate is noise where the input has no
        energy, e.g. at the zeros of a rectangular pulse's spectrum).
    min_level : float
        Peaks lower than this fraction of the largest value of the mode indicator are
        ignored.

    Returns
    -------
    Peaks

    Examples
    --------
    >>> w = np.linspace(1, 20, 2000)
    >>> H = 1 / (100 - w**2 + 2j * 0.02 * 10 * w)
    >>> p = pick_peaks(FRF(w, H))
    >>> round(float(p.omega_rad_s[0]), 1), round(float(p.zeta[0]), 3)
    (10.0, 0.02)
    """
    sub = frf if band is None else frf.band(*band)
    w = sub.omega_rad_s
    ok = sub.reliable_mask(min_input_power)
    if not np.any(ok):
        return Peaks(np.empty(0), np.empty(0), np.empty(0), np.empty((0, 2)))
    lin = mode_indicator(sub, reliable=ok)
    mif = np.log(lin + 1e-300)
    # no peak where the input has no energy: flatten the indicator there
    mif = np.where(ok, mif, mif[ok].min())
    # a resonance must also stand out in level: noise where |H| is tiny makes peaks
    # that are prominent on a log scale only
    floor = np.log(min_level * lin[ok].max())
    idx, props = signal.find_peaks(mif, prominence=min_prominence, height=floor)
    if idx.size == 0:
        return Peaks(np.empty(0), np.empty(0), np.empty(0), np.empty((0, 2)))
    prom = props["prominences"]
    if n_peaks is not None:
        if n_peaks < 1:
            raise DataError(f"n_peaks must be >= 1, got {n_peaks}")
        # the strongest peaks: ranked by their rise on a linear scale
        lin_prom = signal.peak_prominences(np.exp(mif), idx)[0]
        keep = np.sort(np.argsort(lin_prom)[::-1][:n_peaks])
        idx, prom = idx[keep], prom[keep]
    omega = np.empty(idx.size)
    zeta = np.full(idx.size, np.nan)
    for j, i in enumerate(idx):
        # parabolic refinement of the maximum of log MIF
        if 0 < i < w.size - 1:
            y0, y1, y2 = mif[i - 1 : i + 2]
            den = y0 - 2 * y1 + y2
            d = 0.5 * (y0 - y2) / den if den < 0 else 0.0
            d = float(np.clip(d, -1, 1))
            omega[j] = w[i] + d * (w[i + 1] - w[i - 1]) / 2
            peak = y1 - 0.25 * (y0 - y2) * d
        else:
            omega[j] = w[i]
            peak = mif[i]
        # half-power points: MIF (a magnitude) drops by a factor sqrt(2)
        level = peak - 0.5 * np.log(2.0)
        lo = i
        while lo > 0 and mif[lo] > level:
            lo -= 1
        hi = i
        while hi < w.size - 1 and mif[hi] > level:
            hi += 1
        if mif[lo] <= level and mif[hi] <= level:
            wa = np.interp(level, [mif[lo], mif[lo + 1]], [w[lo], w[lo + 1]])
            wb = np.interp(level, [mif[hi], mif[hi - 1]], [w[hi], w[hi - 1]])
            zeta[j] = (wb - wa) / (2 * omega[j])
    bands = np.empty((idx.size, 2))
    width = np.where(np.isfinite(zeta), 2 * zeta * omega, 0.05 * omega)
    for j in range(idx.size):
        lo = omega[j] - half_widths * width[j]
        hi = omega[j] + half_widths * width[j]
        if j > 0:
            lo = max(lo, 0.5 * (omega[j - 1] + omega[j]))
        if j < idx.size - 1:
            hi = min(hi, 0.5 * (omega[j] + omega[j + 1]))
        bands[j] = (max(lo, w[0]), min(hi, w[-1]))
    return Peaks(omega, zeta, prom, bands)
