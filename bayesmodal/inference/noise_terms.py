"""Gaussian residual noise in closed form: white and AR(1) terms, totals and draws.

The residual of output ``j`` of a record is ``r_k = y_k - yhat_k(theta)``.  Two noise
models, independent per output:

``"white"``
    ``r_k ~ N(0, sigma^2)`` independently.

``"ar1"``
    ``r_k = phi r_{k-1} + e_k`` with innovations ``e_k ~ N(0, sigma^2)`` and a stationary
    start, written in the exact innovations (prediction-error) form

        log p(r) = log N(r_0; 0, sigma^2 / (1 - phi^2))
                   + sum_{k>=1} log N(r_k - phi r_{k-1}; 0, sigma^2),

    which is the exact Gaussian log density of a stationary AR(1) record (no conditioning
    on the first sample is dropped).

:func:`white_terms` and :func:`ar1_terms` are the pointwise terms (one per sample and
output), :func:`residual_loglik` and :func:`loglik_from_sums` their sum from sufficient
statistics, :func:`simulate_noise` draws records and :func:`noise_moments` estimates the
parameters from residuals.  The likelihood (:mod:`bayesmodal.inference.likelihood`) and
the noise model classes (:mod:`bayesmodal.inference.noise`) are built on them; the
functions stay importable from :mod:`bayesmodal.inference.likelihood`.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = [
    "white_terms",
    "ar1_terms",
    "residual_loglik",
    "loglik_from_sums",
    "simulate_noise",
    "noise_moments",
    "level_column",
]


_HALF_LOG_2PI = 0.5 * float(np.log(2 * np.pi))


def white_terms(r: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Pointwise log densities of independent Gaussian residuals.

    Parameters
    ----------
    r : ndarray, shape (nb, N, n_out), m
    sigma : ndarray, shape (nb, n_out), m

    Returns
    -------
    ndarray, shape (nb, N, n_out)
    """
    s = sigma[:, None, :]
    return -_HALF_LOG_2PI - np.log(s) - 0.5 * (r / s) ** 2


def ar1_terms(r: np.ndarray, sigma: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Pointwise log densities of a stationary AR(1) residual in innovations form.

    Parameters
    ----------
    r : ndarray, shape (nb, N, n_out), m
    sigma : ndarray, shape (nb, n_out)
        Innovation standard deviation, m.
    phi : ndarray, shape (nb, n_out)
        Lag-1 coefficient, ``|phi| < 1``.

    Returns
    -------
    ndarray, shape (nb, N, n_out)
        Element 0 is ``log N(r_0; 0, sigma^2/(1-phi^2))``, element k >= 1 is
        ``log N(r_k - phi r_{k-1}; 0, sigma^2)``.

    Examples
    --------
    With ``phi = 0`` the terms are the white-noise terms:

    >>> r = np.random.default_rng(0).normal(size=(1, 5, 2))
    >>> s = np.ones((1, 2))
    >>> bool(np.allclose(ar1_terms(r, s, 0 * s), white_terms(r, s)))
    True
    """
    s = sigma[:, None, :]
    p = phi[:, None, :]
    out = np.empty_like(r)
    e = r[:, 1:, :] - p * r[:, :-1, :]
    out[:, 1:, :] = -_HALF_LOG_2PI - np.log(s) - 0.5 * (e / s) ** 2
    one_m_p2 = 1.0 - phi**2
    out[:, 0, :] = (
        -_HALF_LOG_2PI - np.log(sigma) + 0.5 * np.log(one_m_p2)
        - 0.5 * r[:, 0, :] ** 2 * one_m_p2 / sigma**2
    )
    return out


def residual_loglik(R: np.ndarray, sigma: np.ndarray, phi: np.ndarray | None) -> np.ndarray:
    """Total log density of residual records under white or AR(1) noise, batched.

    Computed from sufficient statistics: with ``S00 = sum_{k>=1} r_k^2``,
    ``S01 = sum_{k>=1} r_k r_{k-1}`` and ``S11 = sum_{k<=N-2} r_k^2``, the innovation sum
    of squares is ``S00 - 2 phi S01 + phi^2 S11``.  The cancellation costs about three of
    sixteen digits (the innovations are some 20 times smaller than the residuals), far
    below what matters for the log-likelihood, and the three sums run over the
    simulator's batch-innermost memory layout, which makes this several times faster
    than summing :func:`ar1_terms`.

    Parameters
    ----------
    R : ndarray, shape (N, n_out, nb)
        Residuals ``y - yhat``, m (batch innermost).
    sigma : ndarray, shape (nb, n_out)
        (Innovation) standard deviations, m.
    phi : ndarray, shape (nb, n_out), or None for white noise

    Returns
    -------
    ndarray, shape (nb,)
        Equal to the sum over samples and outputs of :func:`white_terms` or
        :func:`ar1_terms`.
    """
    # the sums of ``_resid_kernels.ar1_sums``, here from an array of residuals
    s00 = np.einsum("kjb,kjb->jb", R[1:], R[1:])
    s01 = np.einsum("kjb,kjb->jb", R[1:], R[:-1])
    return loglik_from_sums(s00, s01, R[0], R[-1], R.shape[0], sigma, phi)


def loglik_from_sums(s00, s01, r0, rl, n: int, sigma: np.ndarray,
                     phi: np.ndarray | None) -> np.ndarray:
    """:func:`residual_loglik` from the residual sums of ``_resid_kernels.ar1_sums``.

    Parameters
    ----------
    s00, s01, r0, rl : ndarray, shape (n_out, nb)
    n : int
        Record length.
    sigma, phi : ndarray, shape (nb, n_out) (phi None for white noise)

    Returns
    -------
    ndarray, shape (nb,)
    """
    s = sigma.T
    if phi is None:
        t = -n * (_HALF_LOG_2PI + np.log(s)) - 0.5 * (s00 + r0**2) / s**2
    else:
        p = phi.T
        s11 = s00 - rl**2 + r0**2
        ss = s00 - 2 * p * s01 + p**2 * s11
        one_m_p2 = 1.0 - p**2
        t = (-n * (_HALF_LOG_2PI + np.log(s)) + 0.5 * np.log(one_m_p2)
             - 0.5 * r0**2 * one_m_p2 / s**2 - 0.5 * ss / s**2)
    return t.sum(axis=0)


def simulate_noise(
    sigma: np.ndarray, phi: np.ndarray | None, n_samples: int, rng=None, start=None
) -> np.ndarray:
    """Draw residual records from the noise model (stationary start, or a given one).

    Parameters
    ----------
    sigma : ndarray, shape (nb, n_out)
        (Innovation) standard deviations, m.
    phi : ndarray, shape (nb, n_out), or None for white noise
    n_samples : int
    rng : numpy.random.Generator or int, optional
    start : array_like, shape (nb, n_out) or (n_out,), optional
        AR(1) only: the residual at sample 0, known (a record that starts at rest, where
        the model and the rig agree, has 0).  The draws are then the AR(1) process
        conditioned on it: mean ``phi^k r_0``, variance ``sigma^2 (1 - phi^(2k)) / (1 -
        phi^2)``, finite for ``phi`` at 1 (a random walk, ``k sigma^2``), where the
        stationary start's spread ``sigma / sqrt(1 - phi^2)`` is unbounded.

    Returns
    -------
    ndarray, shape (nb, n_samples, n_out), m
    """
    rng = np.random.default_rng(rng)
    sigma = np.asarray(sigma, dtype=float)
    e = rng.standard_normal((sigma.shape[0], n_samples, sigma.shape[1])) * sigma[:, None, :]
    if phi is None:
        if start is not None:
            raise DataError("a known start is for AR(1) noise (white noise has no memory)")
        return e
    phi = np.asarray(phi, dtype=float)
    out = np.empty_like(e)
    if start is None:
        out[:, 0] = e[:, 0] / np.sqrt(1.0 - phi**2)
    else:
        out[:, 0] = np.broadcast_to(np.asarray(start, dtype=float), out[:, 0].shape)
    for k in range(1, n_samples):
        out[:, k] = phi * out[:, k - 1] + e[:, k]
    return out


def noise_moments(r: np.ndarray, noise: str) -> np.ndarray:
    """Moment estimates of white or AR(1) noise parameters from residuals.

    Parameters
    ----------
    r : ndarray, shape (N, n_out), m
        Residuals.
    noise : {"white", "ar1"}

    Returns
    -------
    ndarray, shape (n_out,) or (2 n_out,)
        ``sigma`` (RMS residual for white noise; RMS innovation for AR(1)) followed, for
        AR(1), by the lag-1 autocorrelation ``phi`` (clipped inside (-1, 1)).
    """
    if noise == "white":
        return np.sqrt(np.mean(r**2, axis=0))
    phi = np.sum(r[1:] * r[:-1], axis=0) / np.sum(r[:-1] ** 2, axis=0)
    phi = np.clip(phi, -0.9999, 0.9999)
    sigma = np.sqrt(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0))
    return np.r_[sigma, phi]


def level_column(scale) -> np.ndarray:
    """A noise-level factor as a column to multiply ``sigma`` (nb, n_out) with.

    Parameters
    ----------
    scale : float or array_like, shape (nb,)
        One factor, or one per parameter row.

    Returns
    -------
    ndarray, shape (1, 1) or (nb, 1)
    """
    return np.reshape(np.asarray(scale, dtype=float), (-1, 1))
