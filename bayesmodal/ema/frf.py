"""Frequency response functions from input/output records, and the signal tools around them.

Estimators (lecture 11, "system identification" stage).  With auto and cross spectra
``S_uu``, ``S_yu = E[Y U*]``, ``S_yy`` averaged over records or Welch segments::

    H1 = S_yu / S_uu          (unbiased for noise on the output),
    H2 = S_yy / S_uy          (unbiased for noise on the input),
    gamma^2 = |S_yu|^2 / (S_uu S_yy) = H1 / H2     (ordinary coherence, 0..1).

Zero-order hold.  The rig's command voltage is held constant between samples, so the
sampled output spectrum is ``Y_d = H(j w) V_d (1 - e^{-j w dt}) / (j w dt)`` (aliases of a
low-pass mechanical FRF neglected).  The factor is a half-sample delay times
``sinc(w dt / 2)``; with ``zoh=True`` it is divided out, so that the estimate is the
continuous FRF ``H(j w)`` of ``M x'' + C x' + K x = b v`` in m/V, directly comparable
with ``C (j w I - A)^-1 B`` of the state-space model.

Pulse data.  The impulse records hold a train of short pulses, each followed by a free
decay that dies out before the next pulse.  Each pulse-to-pulse segment is then a complete
transient, and a rectangular window (zero-padded FFT) introduces no leakage; the segments
serve as the averages of H1/H2.

The signal tools around the FRF live beside it and are importable from here too: the
record's excitation and its segments (:mod:`.excitation`), impulse responses by inverse
FFT (:mod:`.irf`) and the spectra of single signals (:mod:`.spectra`).  Hammer tests have
their own estimator (:mod:`.impact`), and :mod:`.record_frf` chooses the estimator for
an ``Experiment`` from what its input holds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import signal
from scipy.ndimage import maximum_filter1d

from .._errors import DataError
from .excitation import (
    free_decay_segments,
    is_pulse_train,
    is_step_input,
    pulse_segments,
    step_increments,
)
from .irf import IRF, frequency_grid, impulse_response
from .spectra import Spectrogram, Spectrum, spectrogram, spectrum

__all__ = [
    "FRF",
    "IRF",
    "Spectrum",
    "Spectrogram",
    "ESTIMATORS",
    "welch_frf",
    "pulse_frf",
    "pulse_segments",
    "free_decay_segments",
    "is_pulse_train",
    "is_step_input",
    "step_increments",
    "impulse_response",
    "frequency_grid",
    "zoh_factor",
    "spectrum",
    "spectrogram",
    "band_coherence",
    "peak_prominence",
]

#: FRF estimators: H1 (output noise), H2 (input noise), Hv (both: the geometric mean of
#: the two magnitudes, with their common phase).
ESTIMATORS = ("H1", "H2", "Hv")

#: Input power, relative to its local envelope, below which an FRF value is not trusted.
RELIABLE_INPUT_POWER = 1e-2

#: Largest relative standard error of ``|H1|`` at a trusted frequency (averaged FRFs).
RELIABLE_RELATIVE_ERROR = 0.5

#: Input power, relative to its maximum, below which an FRF value is not trusted.
RELIABLE_INPUT_POWER_GLOBAL = 1e-6


@dataclass(frozen=True)
class FRF:
    """A measured or computed frequency response function, one input to several outputs.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (n_freq,)
        Angular frequencies, increasing, rad/s.
    H : ndarray of complex, shape (n_freq, n_outputs)
        Response per unit input (m/V for the rig positions per motor volt).
    coherence : ndarray, shape (n_freq, n_outputs), or None
        Ordinary coherence (None when there was a single average or no data).
    estimator : str
        ``"H1"``, ``"H2"`` or ``"model"``.
    units : str
        Units of H, e.g. ``"m/V"``.
    n_averages : int
        Number of records or Welch segments averaged.
    dt : float or None
        Sample interval of the data, s (None for an analytical FRF).
    derivative_order : int
        0 for displacement (receptance), 1 for velocity (mobility), 2 for acceleration
        responses; sets the residual terms of the multi-mode fit.
    input_power : ndarray, shape (n_freq,), or None
        Input auto-spectrum divided by its maximum; where it is small (near the zeros of
        a pulse's spectrum) the estimate is noise and peak picking ignores it.
    zoh_divided : bool
        True when the zero-order hold's factor (:func:`zoh_factor`) was divided out of
        ``H`` (the estimators' ``zoh=True``); the multi-mode fit's sampled-data basis
        divides its columns by it too.
    """

    omega_rad_s: np.ndarray
    H: np.ndarray
    coherence: np.ndarray | None = None
    estimator: str = "H1"
    units: str = "m/V"
    n_averages: int = 1
    dt: float | None = None
    derivative_order: int = 0
    input_power: np.ndarray | None = None
    zoh_divided: bool = False

    def __post_init__(self) -> None:
        w = np.asarray(self.omega_rad_s, dtype=float)
        H = np.asarray(self.H, dtype=complex)
        if H.ndim == 1:
            H = H[:, None]
        if w.ndim != 1 or H.ndim != 2 or H.shape[0] != w.size:
            raise DataError(
                f"FRF needs omega of shape (n_freq,) and H of shape (n_freq, n_outputs); got "
                f"{w.shape} and {H.shape}"
            )
        if w.size < 2 or np.any(np.diff(w) <= 0):
            raise DataError("FRF frequencies must be strictly increasing (at least two)")
        if not np.all(np.isfinite(H)):
            raise DataError("FRF values contain NaN or inf")
        if self.derivative_order not in (0, 1, 2):
            raise DataError(f"derivative_order must be 0, 1 or 2, got {self.derivative_order}")
        object.__setattr__(self, "omega_rad_s", w)
        object.__setattr__(self, "H", H)
        if self.coherence is not None:
            c = np.asarray(self.coherence, dtype=float).reshape(H.shape)
            object.__setattr__(self, "coherence", c)
        if self.input_power is not None:
            p = np.asarray(self.input_power, dtype=float).reshape(w.shape)
            object.__setattr__(self, "input_power", p)

    @property
    def n_outputs(self) -> int:
        return int(self.H.shape[1])

    def band(self, lo: float, hi: float) -> FRF:
        """The FRF restricted to ``lo <= omega <= hi`` (rad/s)."""
        sel = (self.omega_rad_s >= lo) & (self.omega_rad_s <= hi)
        if np.count_nonzero(sel) < 2:
            raise DataError(
                f"band [{lo:g}, {hi:g}] rad/s holds {np.count_nonzero(sel)} frequency point(s); "
                f"the FRF covers [{self.omega_rad_s[0]:g}, {self.omega_rad_s[-1]:g}] rad/s"
            )
        coh = None if self.coherence is None else self.coherence[sel]
        pw = None if self.input_power is None else self.input_power[sel]
        return replace(self, omega_rad_s=self.omega_rad_s[sel], H=self.H[sel], coherence=coh,
                       input_power=pw)

    def reliable_mask(self, min_relative: float = RELIABLE_INPUT_POWER, *,
                      max_relative_error: float = RELIABLE_RELATIVE_ERROR) -> np.ndarray:
        """Frequencies where the input had enough energy for the estimate to mean anything.

        ``H1 = S_yu / S_uu`` divides by the input power: near a zero of the input
        spectrum (the notches of a rectangular pulse at multiples of ``2 pi / width``)
        the estimate is output noise divided by almost nothing, and it dwarfs every
        resonance.  A frequency is kept when

        - its input power is at least ``min_relative`` times the largest input power
          within 2 % of the grid around it (the local envelope, so that the
          ``1 / omega^2`` fall of a pulse or step spectrum is not taken for a notch) and
          at least ``RELIABLE_INPUT_POWER_GLOBAL`` (-60 dB) of the largest overall;
        - with ``n`` averages and a coherence ``gamma^2``, the relative standard error of
          ``|H1|``, ``sqrt((1 - gamma^2) / (2 n gamma^2))`` (Bendat and Piersol), is at
          most ``max_relative_error``: ``gamma^2 >= 1 / (1 + 2 n e^2)``.  Where the
          segments of a pulse train share the same notch, their outputs there are noise
          and do not agree, so the coherence drops too.

        Parameters
        ----------
        min_relative : float
            Power ratio to the local envelope.
        max_relative_error : float
            Largest relative standard error of ``|H1|`` (0.5).

        Returns
        -------
        ndarray of bool, shape (n_freq,)
            All True when ``input_power`` is unknown.
        """
        ok = np.ones(self.omega_rad_s.size, bool)
        if self.input_power is not None:
            p = self.input_power
            half = max(2, p.size // 50)
            env = maximum_filter1d(p, size=2 * half + 1, mode="nearest")
            ok &= (p >= min_relative * env) & (p >= RELIABLE_INPUT_POWER_GLOBAL * p.max())
        if self.coherence is not None and self.n_averages > 1:
            gamma2_min = 1.0 / (1.0 + 2 * self.n_averages * max_relative_error**2)
            ok &= np.max(self.coherence, axis=1) >= gamma2_min
        return ok

    def reliable(self, min_relative: float = RELIABLE_INPUT_POWER) -> FRF:
        """The FRF at the frequencies of ``reliable_mask`` (the grid may then have gaps)."""
        keep = self.reliable_mask(min_relative)
        if np.all(keep):
            return self
        if np.count_nonzero(keep) < 2:
            raise DataError("the input has no energy at almost every frequency of the FRF")
        coh = None if self.coherence is None else self.coherence[keep]
        pw = None if self.input_power is None else self.input_power[keep]
        return replace(self, omega_rad_s=self.omega_rad_s[keep], H=self.H[keep],
                       coherence=coh, input_power=pw)

    def select(self, outputs) -> FRF:
        """The FRF of a subset of outputs (index or sequence of indices)."""
        idx = np.atleast_1d(outputs)
        coh = None if self.coherence is None else self.coherence[:, idx]
        return replace(self, H=self.H[:, idx], coherence=coh)


# --------------------------------------------------------------------------- helpers
def _check_io(u, y, dt) -> tuple[np.ndarray, np.ndarray, float]:
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if u.ndim != 1 or y.ndim != 2 or y.shape[0] != u.size:
        raise DataError(
            f"u must have shape (N,) and y shape (N, n_outputs); got {u.shape} and {y.shape}"
        )
    if u.size < 8:
        raise DataError(f"only {u.size} samples; need at least 8 for a spectrum")
    if not (np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise DataError("input or output contains NaN or inf")
    if not np.any(u != 0):
        raise DataError("the input is all zeros; no FRF can be estimated")
    return u, y, float(dt)


def zoh_factor(omega_rad_s: np.ndarray, dt: float) -> np.ndarray:
    """Zero-order-hold factor ``(1 - exp(-j w dt)) / (j w dt)`` (1 at w = 0).

    Parameters
    ----------
    omega_rad_s : ndarray, shape (n,)
    dt : float
        Sample interval, s.

    Returns
    -------
    ndarray of complex, shape (n,)
        ``exp(-j w dt / 2) sinc(w dt / 2)``.
    """
    w = np.asarray(omega_rad_s, dtype=float)
    return np.exp(-0.5j * w * dt) * np.sinc(w * dt / (2 * np.pi))


def _estimate(Syu, Suu, Syy, estimator):
    if estimator == "H1":
        H = Syu / Suu[:, None]
    elif estimator == "H2":
        # H2 = S_yy / S_uy with S_uy = conj(S_yu)
        with np.errstate(divide="ignore", invalid="ignore"):
            H = Syy / np.conj(Syu)
    elif estimator == "Hv":
        # one input: H1 and H2 share the phase of S_yu, and |Hv| = sqrt(|H1| |H2|) =
        # sqrt(S_yy / S_uu) (the total-least-squares estimate for equal noise shares)
        with np.errstate(divide="ignore", invalid="ignore"):
            H = np.sqrt(Syy / Suu[:, None]) * Syu / np.abs(Syu)
    else:
        raise DataError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.abs(Syu) ** 2 / (Suu[:, None] * Syy)
    return H, np.clip(np.nan_to_num(coh), 0.0, 1.0)


# --------------------------------------------------------------------------- Welch
def welch_frf(
    u,
    y,
    dt: float,
    *,
    estimator: str = "H1",
    window: str | tuple = "hann",
    nperseg: int | None = None,
    noverlap: int | None = None,
    detrend: str | bool = "constant",
    zoh: bool = True,
    units: str = "m/V",
) -> FRF:
    """FRF by Welch-averaged spectra (``scipy.signal.csd`` / ``welch``).

    Parameters
    ----------
    u : ndarray, shape (N,)
        Input, e.g. motor voltage, V.
    y : ndarray, shape (N,) or (N, n_outputs)
        Outputs, e.g. cart positions, m.
    dt : float
        Sample interval, s.
    estimator : {"H1", "H2", "Hv"}
    window : str or tuple
        Any window ``scipy.signal.get_window`` accepts (``"hann"``, ``"boxcar"``,
        ``("tukey", 0.25)``, ...).
    nperseg : int, optional
        Segment length; by default the largest power of two not above ``N / 2``.
    noverlap : int, optional
        Overlap, samples (default half a segment).
    detrend : str or False
        Passed to scipy (``"constant"`` removes each segment's mean).
    zoh : bool
        Divide out the zero-order hold of a sampled, held input (see module notes).
    units : str
        Units of the FRF, for labels.

    Returns
    -------
    FRF
        On the one-sided grid ``0 .. pi/dt`` rad/s (DC excluded).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(4096)
    >>> frf = welch_frf(u, 2.0 * u, 0.01, zoh=False)
    >>> bool(np.allclose(frf.H, 2.0))
    True
    """
    u, y, dt = _check_io(u, y, dt)
    n = u.size
    if nperseg is None:
        nperseg = 1 << int(np.floor(np.log2(max(n // 2, 8))))
    if not 8 <= nperseg <= n:
        raise DataError(f"nperseg must be between 8 and the record length {n}, got {nperseg}")
    fs = 1.0 / dt
    kw = dict(fs=fs, window=window, nperseg=nperseg, noverlap=noverlap, detrend=detrend)
    f, Suu = signal.welch(u, **kw)
    _, Syu = signal.csd(u[:, None], y, axis=0, **kw)  # scipy: conj(U) Y, i.e. E[Y U*]
    _, Syy = signal.welch(y, axis=0, **kw)
    step = nperseg - (nperseg // 2 if noverlap is None else noverlap)
    n_avg = 1 + (n - nperseg) // step
    keep = (f > 0) & (Suu > 0)
    w = 2 * np.pi * f[keep]
    H, coh = _estimate(Syu[keep], Suu[keep], Syy[keep].real, estimator)
    if zoh:
        H = H / zoh_factor(w, dt)[:, None]
    H = np.nan_to_num(H)
    power = Suu[keep] / np.max(Suu[keep])
    return FRF(w, H, coh if n_avg > 1 else None, estimator, units, n_avg, dt, 0, power,
               zoh_divided=bool(zoh))


# --------------------------------------------------------------------------- pulses
def summed_spectra(segments, n_fft: int):
    """Auto and cross spectra summed over input-output segments (zero-padded FFTs).

    Parameters
    ----------
    segments : iterable of (ndarray (L,), ndarray (L, n_out))
        Input and output samples of each segment (windowed as wanted).
    n_fft : int
        FFT length, at least the longest segment.

    Returns
    -------
    Suu : ndarray, shape (n_fft // 2 + 1,)
    Syu, Syy : ndarray, shape (n_fft // 2 + 1, n_out)
    """
    Suu = Syu = Syy = 0.0
    for useg, yseg in segments:
        U = np.fft.rfft(useg, n_fft)
        Y = np.fft.rfft(yseg, n_fft, axis=0)
        Suu = Suu + np.abs(U) ** 2
        Syu = Syu + Y * U.conj()[:, None]
        Syy = Syy + np.abs(Y) ** 2
    return Suu, Syu, Syy


def pulse_frf(
    u,
    y,
    dt: float,
    *,
    segments: np.ndarray | None = None,
    n_fft: int | None = None,
    pad: int = 4,
    estimator: str = "H1",
    zoh: bool = True,
    baseline: bool = True,
    units: str = "m/V",
) -> FRF:
    """FRF from transient records (pulse train), each segment one average.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Input, V.
    y : ndarray, shape (N,) or (N, n_outputs)
        Outputs, m.
    dt : float
        Sample interval, s.
    segments : ndarray of int, shape (n_segments, 2 or 3), optional
        Rows ``(start, ..., stop)``; by default ``pulse_segments(u)``.  A whole record is
        ``[[0, N]]``.
    n_fft : int, optional
        FFT length; by default ``pad`` times the longest segment (zero padding
        interpolates the spectrum of a complete transient without adding information).
    pad : int
        Zero-padding factor used when ``n_fft`` is not given.
    estimator : {"H1", "H2", "Hv"}
    zoh : bool
        Divide out the zero-order hold (see module notes).
    baseline : bool
        Subtract each segment's first output sample (the rest position before the pulse,
        which dry friction leaves slightly off zero).
    units : str

    Returns
    -------
    FRF
        On the grid ``2 pi k / (n_fft dt)``, ``k = 1 .. n_fft // 2``; coherence over the
        segments when there are at least two.

    Examples
    --------
    >>> u = np.zeros(400); u[0] = 1.0
    >>> y = 0.5 ** np.arange(400)      # first-order system y[k] = 0.5^k
    >>> frf = pulse_frf(u, y, 1.0, segments=np.array([[0, 400]]), zoh=False, baseline=False)
    >>> bool(np.allclose(frf.H[:, 0], 1 / (1 - 0.5 * np.exp(-1j * frf.omega_rad_s))))
    True
    """
    u, y, dt = _check_io(u, y, dt)
    seg = pulse_segments(u) if segments is None else np.asarray(segments, dtype=int)
    if seg.ndim != 2 or seg.shape[1] < 2 or seg.shape[0] < 1:
        raise DataError(f"segments must have shape (n, 2) or (n, 3), got {seg.shape}")
    starts, stops = seg[:, 0], seg[:, -1]
    if np.any(starts < 0) or np.any(stops > u.size) or np.any(stops - starts < 8):
        raise DataError(f"segments must lie in 0..{u.size} and span >= 8 samples: {seg.tolist()}")
    longest = int(np.max(stops - starts))
    if n_fft is None:
        n_fft = int(pad) * longest
    if n_fft < longest:
        raise DataError(f"n_fft = {n_fft} is shorter than the longest segment ({longest})")
    Suu, Syu, Syy = summed_spectra(
        ((u[a:b], y[a:b] - (y[a] if baseline else 0.0)) for a, b in zip(starts, stops,
                                                                          strict=True)),
        n_fft)
    w = 2 * np.pi * np.fft.rfftfreq(n_fft, dt)
    # every frequency of the grid is kept (impulse_response needs the whole grid); where
    # the input has no energy at all H is set to 0 and input_power is 0, so that
    # FRF.reliable leaves it out
    keep = w > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        H, coh = _estimate(Syu[keep], Suu[keep], Syy[keep], estimator)
    H[~(Suu[keep] > 1e-300)] = 0.0
    w = w[keep]
    if zoh:
        H = H / zoh_factor(w, dt)[:, None]
    n_avg = int(seg.shape[0])
    power = Suu[keep] / np.max(Suu[keep])
    return FRF(w, np.nan_to_num(H), coh if n_avg > 1 else None, estimator, units, n_avg, dt, 0,
               power, zoh_divided=bool(zoh))


# --------------------------------------------------------------------------- checks
def band_coherence(frf: FRF, band: tuple[float, float]) -> np.ndarray:
    """Mean coherence in a band, shape (n_outputs,) (NaN without coherence)."""
    sub = frf.band(*band)
    if sub.coherence is None:
        return np.full(frf.n_outputs, np.nan)
    return sub.coherence.mean(axis=0)


def peak_prominence(frf: FRF, band: tuple[float, float]) -> np.ndarray:
    """How much a resonance stands out of the FRF magnitude in a band.

    The ratio of ``max |H|`` inside the band to the larger of ``|H|`` at the two band
    edges.  A lightly damped mode inside the band rises above both edges (by up to about
    ``1 / (2 zeta)`` for a wide band); a band without a resonance, where ``|H|`` only
    falls, rises or levels off, gives about 1.

    Parameters
    ----------
    frf : FRF
    band : (lo, hi)
        rad/s; a few half-power bandwidths either side of the expected mode.

    Returns
    -------
    ndarray, shape (n_outputs,)

    Examples
    --------
    >>> w = np.linspace(5, 15, 201)
    >>> frf = FRF(w, 1 / (100 - w**2 + 0.4j * w))
    >>> bool(peak_prominence(frf, (8, 12))[0] > 5), bool(peak_prominence(frf, (12, 15))[0] < 1.01)
    (True, True)
    """
    sub = frf.band(*band)
    mag = np.abs(sub.H)
    edge = np.maximum(mag[0], mag[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(edge > 0, mag.max(axis=0) / edge, np.inf)
