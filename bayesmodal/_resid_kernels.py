"""Compiled residual statistics of a batch of predictions (numba), without temporaries.

The Gaussian white and AR(1) log-likelihoods of a residual record ``r_k = y_k - yhat_k``
depend on the data only through ``S00 = sum_{k>=1} r_k^2``, ``S01 = sum_{k>=1} r_k
r_{k-1}``, ``r_0`` and ``r_{N-1}`` per output (see ``inference.likelihood.residual_loglik``).
Forming ``r`` as an array first costs a fresh (N, n_out, nb) allocation per call, which on
a half-ensemble batch of a 7400-sample record took most of the likelihood's time.  These
kernels read the prediction where the simulator left it (lanes innermost in memory) and
accumulate the sums lane by lane.  With ``affine`` the prediction is ``g (a + v0 b)`` per
lane (several records: a per-record gain and input offset applied to unit-gain
simulations, ``inference.records``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["ar1_sums", "ar1_sums_affine"]


@njit(cache=False, nogil=True, fastmath=False)
def _sums(y, yh, s00, s01, r0, rl):  # pragma: no cover - compiled
    nb, n, nj = yh.shape
    prev = np.empty((nj, nb))
    for j in range(nj):
        for b in range(nb):
            r = y[0, j] - yh[b, 0, j]
            r0[j, b] = r
            prev[j, b] = r
    for k in range(1, n):
        for j in range(nj):
            yk = y[k, j]
            for b in range(nb):
                r = yk - yh[b, k, j]
                s00[j, b] += r * r
                s01[j, b] += r * prev[j, b]
                prev[j, b] = r
    for j in range(nj):
        for b in range(nb):
            rl[j, b] = prev[j, b]


@njit(cache=False, nogil=True, fastmath=False)
def _sums_affine(y, a, bb, g, v0, s00, s01, r0, rl):  # pragma: no cover - compiled
    nb, n, nj = a.shape
    prev = np.empty((nj, nb))
    for j in range(nj):
        for b in range(nb):
            r = y[0, j] - g[b] * (a[b, 0, j] + v0[b] * bb[b, 0, j])
            r0[j, b] = r
            prev[j, b] = r
    for k in range(1, n):
        for j in range(nj):
            yk = y[k, j]
            for b in range(nb):
                r = yk - g[b] * (a[b, k, j] + v0[b] * bb[b, k, j])
                s00[j, b] += r * r
                s01[j, b] += r * prev[j, b]
                prev[j, b] = r
    for j in range(nj):
        for b in range(nb):
            rl[j, b] = prev[j, b]


def _out(nj, nb):
    return (np.zeros((nj, nb)), np.zeros((nj, nb)), np.empty((nj, nb)), np.empty((nj, nb)))


def ar1_sums(y: np.ndarray, yh: np.ndarray):
    """Residual sums of predictions ``yh`` (nb, N, n_out) against ``y`` (N, n_out), m.

    Returns
    -------
    s00, s01, r0, rl : ndarray, each shape (n_out, nb)
        ``sum_{k>=1} r_k^2``, ``sum_{k>=1} r_k r_{k-1}``, ``r_0`` and ``r_{N-1}``.
    """
    y = np.ascontiguousarray(y, dtype=float)
    out = _out(yh.shape[2], yh.shape[0])
    _sums(y, yh, *out)
    return out


def ar1_sums_affine(y, a, b, g, v0):
    """As :func:`ar1_sums` for the prediction ``g (a + v0 b)`` (per-lane ``g``, ``v0``)."""
    y = np.ascontiguousarray(y, dtype=float)
    out = _out(a.shape[2], a.shape[0])
    _sums_affine(y, a, b, np.ascontiguousarray(g, float), np.ascontiguousarray(v0, float),
                 *out)
    return out
