"""Impulse responses from FRFs by inverse FFT, on the FFT's frequency grid."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._errors import DataError

if TYPE_CHECKING:  # the argument's type only: frf re-exports this module's names
    from .frf import FRF

__all__ = ["IRF", "frequency_grid", "impulse_response"]


@dataclass(frozen=True)
class IRF:
    """Sampled impulse response functions (or free decays) of several outputs.

    Attributes
    ----------
    t_s : ndarray, shape (N,)
        Times, s (uniform, ``t_s[k] = t0 + k dt``).
    h : ndarray, shape (N, n_outputs)
        Response per unit impulse (m/(V s) for an FRF in m/V).
    dt : float
        Sample interval, s.
    """

    t_s: np.ndarray
    h: np.ndarray
    dt: float


def frequency_grid(n_samples: int, dt: float) -> np.ndarray:
    """The one-sided FFT grid ``2 pi k / (n_samples dt)``, k from 0 to ``n_samples // 2``, rad/s."""
    return 2 * np.pi * np.fft.rfftfreq(int(n_samples), dt)


def impulse_response(frf: FRF, *, n_samples: int | None = None) -> IRF:
    """Impulse response by inverse FFT of an FRF on a full one-sided FFT grid.

    Parameters
    ----------
    frf : FRF
        Values at ``k d_omega`` for ``k = k0 .. n_samples // 2`` (``k0`` is 0 or 1; a
        missing DC value is extrapolated as the first value's real part).
    n_samples : int, optional
        Length of the time record ``N``; by default ``2 (n_freq - 1)`` (even N).  The
        sample interval is ``dt = 2 pi / (N d_omega)``.

    Returns
    -------
    IRF
        ``h[k] ~ h(k dt)`` in FRF units per second, periodic with period ``N dt`` (a pole
        ``lambda`` stays the same pole after this time aliasing; only its residue is
        scaled by ``1 / (1 - exp(lambda N dt))``).

    Raises
    ------
    DataError
        If the frequencies are not uniform multiples of one step.
    """
    w = frf.omega_rad_s
    dw = w[1] - w[0]
    k = w / dw
    if not np.allclose(k, np.round(k), atol=1e-6) or not np.allclose(np.diff(k), 1, atol=1e-6):
        raise DataError("impulse_response needs an FRF on a uniform grid k * d_omega")
    k0 = int(round(k[0]))
    if k0 not in (0, 1):
        raise DataError(f"the FRF grid must start at 0 or d_omega; it starts at {w[0]:g} rad/s")
    H = frf.H
    if k0 == 1:
        H = np.vstack([H[:1].real, H])
    n_freq = H.shape[0]
    N = 2 * (n_freq - 1) if n_samples is None else int(n_samples)
    if N // 2 + 1 != n_freq:
        raise DataError(f"n_samples = {N} does not match {n_freq} one-sided frequencies")
    dt = 2 * np.pi / (N * dw)
    h = np.fft.irfft(H, N, axis=0) / dt
    return IRF(np.arange(N) * dt, h, dt)
