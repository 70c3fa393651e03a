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

__all__ = ["ar1_sums", "ar1_sums_affine", "ar1_sums_lanes"]


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


@njit(cache=False, nogil=True, fastmath=False)
def _sums_lanes(y, Y, s00, s01, r0, rl):  # pragma: no cover - compiled
    # Y: the simulator's buffer (chunks, >= n, nj, width), lanes innermost (contiguous)
    n, nj = y.shape
    nc, _, _, W = Y.shape
    a00 = np.zeros((nj, W))
    a01 = np.zeros((nj, W))
    p = np.empty((nj, W))
    for c in range(nc):
        o = c * W
        for j in range(nj):
            for w in range(W):
                p[j, w] = y[0, j] - Y[c, 0, j, w]
                r0[j, o + w] = p[j, w]
                a00[j, w] = 0.0
                a01[j, w] = 0.0
        for k in range(1, n):
            for j in range(nj):
                yk = y[k, j]
                for w in range(W):
                    r = yk - Y[c, k, j, w]
                    a00[j, w] += r * r
                    a01[j, w] += r * p[j, w]
                    p[j, w] = r
        for j in range(nj):
            for w in range(W):
                s00[j, o + w] = a00[j, w]
                s01[j, o + w] = a01[j, w]
                rl[j, o + w] = p[j, w]


@njit(cache=False, nogil=True, fastmath=False)
def _sums_lanes_affine(y, A, B, g, v0, s00, s01, r0, rl):  # pragma: no cover - compiled
    # A, B: simulator buffers (chunks, >= n, nj, width); g, v0: (chunks * width,)
    n, nj = y.shape
    nc, _, _, W = A.shape
    a00 = np.zeros((nj, W))
    a01 = np.zeros((nj, W))
    p = np.empty((nj, W))
    gc = np.empty(W)
    vc = np.empty(W)
    for c in range(nc):
        o = c * W
        for w in range(W):
            gc[w] = g[o + w]
            vc[w] = v0[o + w]
        for j in range(nj):
            for w in range(W):
                p[j, w] = y[0, j] - gc[w] * (A[c, 0, j, w] + vc[w] * B[c, 0, j, w])
                r0[j, o + w] = p[j, w]
                a00[j, w] = 0.0
                a01[j, w] = 0.0
        for k in range(1, n):
            for j in range(nj):
                yk = y[k, j]
                for w in range(W):
                    r = yk - gc[w] * (A[c, k, j, w] + vc[w] * B[c, k, j, w])
                    a00[j, w] += r * r
                    a01[j, w] += r * p[j, w]
                    p[j, w] = r
        for j in range(nj):
            for w in range(W):
                s00[j, o + w] = a00[j, w]
                s01[j, o + w] = a01[j, w]
                rl[j, o + w] = p[j, w]


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


def ar1_sums_lanes(y: np.ndarray, Y: np.ndarray, nb: int, B: np.ndarray | None = None,
                   g: np.ndarray | None = None, v0: np.ndarray | None = None):
    """As :func:`ar1_sums` (or :func:`ar1_sums_affine` with ``B``, ``g``, ``v0``), reading
    the simulator's own buffers (``LinearSimulator.run_prepared(..., lanes_last=True)``).

    Parameters
    ----------
    y : ndarray, shape (N, n_out)
        Measured outputs.
    Y, B : ndarray, shape (n_chunks, >= N, n_out, width)
        Predictions (or unit-gain responses ``a`` and ``b``), lanes innermost; samples past
        ``N`` are ignored (a longer record's step response serves a shorter one).
    nb : int
        Number of real lanes (the rest of the last chunk is padding).
    g, v0 : ndarray, shape (nb,), optional
        Per-lane gain and input offset: the prediction is ``g (Y + v0 B)``.

    Returns
    -------
    s00, s01, r0, rl : ndarray, each shape (n_out, nb)
        Bit for bit those of :func:`ar1_sums` / :func:`ar1_sums_affine` (same operations in
        the same order per lane).
    """
    y = np.ascontiguousarray(y, dtype=float)
    nc, n_buf, nj, w = Y.shape
    if n_buf < y.shape[0] or nj != y.shape[1] or nc * w < nb:
        raise ValueError(f"buffer of shape {Y.shape} does not hold {nb} lanes of a "
                         f"{y.shape} record")
    out = _out(nj, nc * w)
    if B is None:
        _sums_lanes(y, Y, *out)
    else:
        pad = nc * w - nb
        gp = np.concatenate([np.asarray(g, float), np.zeros(pad)])
        vp = np.concatenate([np.asarray(v0, float), np.zeros(pad)])
        _sums_lanes_affine(y, Y, B, gp, vp, *out)
    return tuple(np.ascontiguousarray(a[:, :nb]) for a in out)
