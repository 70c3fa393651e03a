"""Synthetic test cases of lecture 11d: a three-mode system with two close modes.

The lecture identifies the eigenvalues::

    lambda_1,2 = -0.0389 +- 0.6172 j,   lambda_3,4 = -0.0754 +- 1.4140 j,
    lambda_5,6 = -0.0607 +- 1.6138 j    (1/s)

from two impulse responses ``h11`` and ``h12`` sampled at ``dt = 1 s`` on
``0 <= t < 100 s`` with 5 % Gaussian noise.  The lecture does not give the residues.
Here the mode shapes (column ``l = 1`` of the residue matrices, rows ``i = 1, 2``) are::

    u_k = a_k (1, r_k),   r = (0.8, 0.5, -1.0),   a_k = sqrt(nu_k |mu_k| / (nu_1 |mu_1|)),

i.e. a_k = (1, 2.1073, 2.0199), with ``c_k = 2 j nu_k``, so that
``A_k[i, 1] = u_k[i] u_k[1] / (2 j nu_k)`` and
``h[i, 1](t) = sum_k u_k[i] u_k[1] exp(mu_k t) sin(nu_k t) / nu_k``.  The scale ``a_k``
makes the three resonance peaks of ``|H11|`` equally high (peak ``~ |A_k| / |mu_k|``); the
opposite signs of modes 2 and 3 in ``h12`` merge their peaks into one in ``|H12|`` (no
antiresonance between them), as in the lecture's figure.  The noise of each IRF is
Gaussian with a standard deviation of 5 % of that IRF's RMS value over the record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._errors import DataError

__all__ = [
    "LECTURE_POLES",
    "LECTURE_SHAPES",
    "ModalSystem",
    "lecture_system",
    "lecture_irfs",
]

#: Eigenvalues of the lecture's LSCE example (one per conjugate pair), 1/s.
LECTURE_POLES = np.array([-0.0389 + 0.6172j, -0.0754 + 1.4140j, -0.0607 + 1.6138j])

#: Mode shapes chosen here for the lecture example, normalised on output 1: rows are modes,
#: columns outputs 1, 2.
LECTURE_SHAPES = np.array([[1.0, 0.8], [1.0, 0.5], [1.0, -1.0]])


@dataclass(frozen=True)
class ModalSystem:
    """A system given by its poles and one column of residues.

    Attributes
    ----------
    poles : ndarray of complex, shape (n_modes,)
        One pole per conjugate pair (``Im > 0``), 1/s.
    residues : ndarray of complex, shape (n_modes, n_outputs)
        Residues ``A_k[i, l]`` of the pole with ``Im > 0``; the conjugate pole has the
        conjugate residue.
    """

    poles: np.ndarray
    residues: np.ndarray

    def frf(self, omega_rad_s) -> np.ndarray:
        """``H(w) = sum_k A_k / (j w - lambda_k) + conj(A_k) / (j w - conj(lambda_k))``.

        Returns
        -------
        ndarray of complex, shape (n_freq, n_outputs)
        """
        jw = 1j * np.asarray(omega_rad_s, dtype=float)[:, None, None]
        lam = self.poles[None, :, None]
        A = self.residues[None]
        return np.sum(A / (jw - lam) + A.conj() / (jw - lam.conj()), axis=1)

    def irf(self, t_s) -> np.ndarray:
        """``h(t) = sum_k 2 Re(A_k exp(lambda_k t))``, shape (n_times, n_outputs)."""
        t = np.asarray(t_s, dtype=float)[:, None, None]
        return 2 * np.sum((self.residues[None] * np.exp(self.poles[None, :, None] * t)).real,
                          axis=1)


def lecture_system() -> ModalSystem:
    """The lecture's three-mode system with the mode shapes chosen in this module."""
    lam = LECTURE_POLES
    scale = np.sqrt(lam.imag * np.abs(lam.real) / (lam.imag[0] * abs(lam.real[0])))
    u = scale[:, None] * LECTURE_SHAPES
    A = u * u[:, :1] / (2j * lam.imag[:, None])
    return ModalSystem(lam, A)


def lecture_irfs(
    rng, *, noise: float = 0.05, dt: float = 1.0, duration: float = 100.0
) -> tuple[np.ndarray, np.ndarray, ModalSystem]:
    """Noisy impulse responses ``h11`` and ``h12`` of the lecture example.

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Random generator or seed.
    noise : float
        Noise standard deviation as a fraction of each IRF's RMS value.
    dt : float
        Sample interval, s.
    duration : float
        Record length, s (samples at ``0 <= t < duration``).

    Returns
    -------
    t : ndarray, shape (N,)
        Times, s.
    h : ndarray, shape (N, 2)
        Noisy ``h11`` and ``h12``.
    system : ModalSystem
        The exact system.

    Examples
    --------
    >>> t, h, sys = lecture_irfs(0)
    >>> h.shape
    (100, 2)
    """
    if not (np.isfinite(noise) and noise >= 0):
        raise DataError(f"noise must be a finite fraction >= 0, got {noise!r}")
    rng = np.random.default_rng(rng)
    system = lecture_system()
    t = np.arange(0.0, duration, dt)
    h = system.irf(t)
    rms = np.sqrt(np.mean(h**2, axis=0))
    return t, h + noise * rms * rng.standard_normal(h.shape), system
