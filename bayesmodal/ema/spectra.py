"""Spectra of single signals: one-sided amplitude spectrum and spectrogram."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from .._errors import DataError

__all__ = ["Spectrogram", "Spectrum", "spectrogram", "spectrum"]


@dataclass(frozen=True)
class Spectrum:
    """One-sided amplitude spectrum.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (n_freq,)
    amplitude : ndarray, shape (n_freq,) or (n_freq, n_signals)
        Amplitude of the sinusoid each bin stands for (signal units).
    """

    omega_rad_s: np.ndarray
    amplitude: np.ndarray


@dataclass(frozen=True)
class Spectrogram:
    """Short-time power spectral density.

    Attributes
    ----------
    t_s : ndarray, shape (n_times,)
        Centre of each segment, s.
    omega_rad_s : ndarray, shape (n_freq,)
    psd : ndarray, shape (n_freq, n_times)
        Power spectral density, (signal units)^2 s/rad.
    """

    t_s: np.ndarray
    omega_rad_s: np.ndarray
    psd: np.ndarray


def spectrum(x, dt: float, *, window: str | tuple = "boxcar") -> Spectrum:
    """One-sided amplitude spectrum of one or several signals.

    Parameters
    ----------
    x : ndarray, shape (N,) or (N, n_signals)
    dt : float
        Sample interval, s.
    window : str or tuple
        Window (amplitude-corrected by its mean).

    Returns
    -------
    Spectrum
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    win = signal.get_window(window, n)
    shape = (n,) + (1,) * (x.ndim - 1)
    X = np.fft.rfft(x * win.reshape(shape), axis=0)
    amp = 2 * np.abs(X) / (n * np.mean(win))
    amp[0] /= 2
    return Spectrum(2 * np.pi * np.fft.rfftfreq(n, dt), amp)


def spectrogram(
    x, dt: float, *, nperseg: int = 256, noverlap: int | None = None, window="hann"
) -> Spectrogram:
    """Spectrogram (``scipy.signal.spectrogram``) on an angular-frequency axis.

    Parameters
    ----------
    x : ndarray, shape (N,)
    dt : float
        Sample interval, s.
    nperseg, noverlap, window
        As in scipy.

    Returns
    -------
    Spectrogram
        PSD converted to per rad/s.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise DataError(f"spectrogram needs a 1-D signal, got shape {x.shape}")
    f, t, S = signal.spectrogram(x, 1 / dt, window=window, nperseg=nperseg, noverlap=noverlap)
    return Spectrogram(t, 2 * np.pi * f, S / (2 * np.pi))
