r"""The process-noise model as a discrete-time system, and its steady-state Kalman filter.

:mod:`.kalman` gives the model (a white random force on each cart) and evaluates its
likelihood; here are the pieces of the filter that do not depend on the record: the
exact discretisation of a batch of parameter sets, ``Ad, Bd`` (ZOH input) and the state
noise covariance ``Qd`` over one sample by Van Loan's method, and the steady-state
predicted covariance ``P``, innovation covariance ``S`` and gain ``K`` of the filter.

DARE solver.  A batched structure-preserving doubling algorithm (SDA; Chu, Fan and Lin
2005) on the dual (control-form) equation ``X = A' X (I + G X)^-1 A + H`` with
``A = Ad'``, ``G = C' R^-1 C``, ``H = Qd``: ``A_{k+1} = A_k W^-1 A_k``,
``G_{k+1} = G_k + A_k W^-1 G_k A_k'``, ``H_{k+1} = H_k + A_k' H_k W^-1 A_k`` with
``W = I + G_k H_k``; ``H_k`` increases to ``P`` with an error that squares each step.
Lanes that do not converge fall back to ``scipy.linalg.solve_discrete_are``.  With
``q = 0`` the solution is ``P = 0``, the filter runs open loop and the likelihood is the
white-noise output-error likelihood.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from ..._errors import DataError

__all__ = [
    "ProcessNoiseSystem",
    "SteadyStateFilter",
    "discretize_process_noise",
    "steady_state_filter",
    "solve_filter_dare",
]

_SDA_MAX_IT = 80


@dataclass(frozen=True)
class ProcessNoiseSystem:
    """Discretised process-noise model of a batch of parameter sets.

    Attributes
    ----------
    Ad : ndarray, shape (nb, s, s)
    Bd : ndarray, shape (nb, s)
        m/V and m/(V s) blocks.
    Qd : ndarray, shape (nb, s, s)
        Covariance of the state noise over one sample, m^2 and (m/s)^2 blocks.
    dt : float
        Sample interval, s.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    Qd: np.ndarray
    dt: float


@dataclass(frozen=True)
class SteadyStateFilter:
    """Steady-state Kalman filter of a batch.

    Attributes
    ----------
    P : ndarray, shape (nb, s, s)
        Steady-state predicted state covariance.
    S : ndarray, shape (nb, n_out, n_out)
        Innovation covariance ``C P C' + R``, m^2.
    gain : ndarray, shape (nb, s, n_out)
        Filter gain ``K = P C' S^-1`` (update ``x + K eps``).
    """

    P: np.ndarray
    S: np.ndarray
    gain: np.ndarray


def _expm(F: np.ndarray) -> np.ndarray:
    """Matrix exponential of a stack (nb, m, m): scaling and squaring, Taylor degree 24.

    ``scipy.linalg.expm`` computes the same (Pade instead of Taylor), but on a stack of
    small matrices its compiled loop calls the threaded BLAS once per matrix, which on a
    loaded machine stalls (mean 56 ms against a best of 0.3 ms for 32 matrices of size 12
    with two OpenBLAS threads); ``np.matmul`` on the stack does not.  After scaling,
    ``|F / 2^j|_1 <= 2`` (``j`` per matrix) and the Taylor remainder is below
    ``2^25 / 25! < 3e-18``; the few squarings keep the result as accurate as scipy's
    (tested through ``Ad, Bd`` against ``scipy.signal.cont2discrete`` and ``Qd`` against
    quadrature).
    """
    # squarings per matrix, so that one wild walker does not cost the others accuracy
    norm = np.abs(F).sum(axis=-2).max(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        j = np.where(norm > 2.0, np.ceil(np.log2(norm / 2.0)), 0.0)
    j = np.where(np.isfinite(j), j, 0).astype(int)
    X = F / (2.0 ** j)[:, None, None]
    eye = np.eye(F.shape[-1])
    E = eye + X / 24.0
    for k in range(23, 0, -1):
        E = eye + (X @ E) / k
    for i in range(int(j.max(initial=0))):
        sq = j > i
        E[sq] = E[sq] @ E[sq]
    return E


def discretize_process_noise(model, theta_mech: np.ndarray, q: np.ndarray,
                             dt: float) -> ProcessNoiseSystem:
    """Exact discretisation (ZOH input, white force on each cart) of a batch.

    Parameters
    ----------
    model : LinearModel
    theta_mech : ndarray, shape (nb, n_params)
        Admissible mechanical parameters.
    q : ndarray, shape (nb, n_carts)
        Force spectral densities, N^2 s.
    dt : float
        Sample interval, s.

    Returns
    -------
    ProcessNoiseSystem
    """
    theta_mech = np.atleast_2d(np.asarray(theta_mech, dtype=float))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if not (np.isscalar(dt) and np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    dt = float(dt)
    A, B = model.state_space(theta_mech)
    n = model.n_carts
    s = 2 * n
    nb = A.shape[0]
    masses = np.diagonal(model.matrices(theta_mech)[0], axis1=-2, axis2=-1)
    # ZOH: expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, 1]]
    Z = np.zeros((nb, s + 1, s + 1))
    Z[:, :s, :s] = A * dt
    Z[:, :s, s] = B * dt
    EZ = _expm(Z)
    # Van Loan: expm([[-A, G Q G'], [0, A']] dt) = [[., E12], [0, E22]], Qd = E22' E12
    F = np.zeros((nb, 2 * s, 2 * s))
    F[:, :s, :s] = -A * dt
    F[:, s:, s:] = np.swapaxes(A, 1, 2) * dt
    idx = np.arange(n, s)
    F[:, idx, s + idx] = q / masses**2 * dt  # G Q G' = diag(0, q / m^2)
    E = _expm(F)
    Qd = np.swapaxes(E[:, s:, s:], 1, 2) @ E[:, :s, s:]
    Qd = 0.5 * (Qd + np.swapaxes(Qd, 1, 2))
    return ProcessNoiseSystem(Ad=EZ[:, :s, :s], Bd=EZ[:, :s, s], Qd=Qd, dt=dt)


def solve_filter_dare(Ad: np.ndarray, Qd: np.ndarray, r_diag: np.ndarray) -> np.ndarray:
    """Stabilising solution P of the filter DARE for each lane (batched doubling).

    Parameters
    ----------
    Ad : ndarray, shape (nb, s, s)
    Qd : ndarray, shape (nb, s, s)
    r_diag : ndarray, shape (nb, n_out)
        Measurement noise variances, m^2; the outputs are the first ``n_out`` states.

    Returns
    -------
    P : ndarray, shape (nb, s, s)
    """
    nb, s, _ = Ad.shape
    n_out = r_diag.shape[1]
    A = np.swapaxes(Ad, 1, 2).copy()
    G = np.zeros((nb, s, s))
    G[:, np.arange(n_out), np.arange(n_out)] = 1.0 / r_diag
    H = Qd.copy()
    eye = np.eye(s)
    done = np.zeros(nb, bool)
    for _ in range(_SDA_MAX_IT):
        WAG = np.linalg.solve(eye + G @ H, np.concatenate([A, G], axis=2))
        WA, WG = WAG[:, :, :s], WAG[:, :, s:]
        H_new = H + np.swapaxes(A, 1, 2) @ H @ WA
        G = G + A @ WG @ np.swapaxes(A, 1, 2)
        A = A @ WA
        H_new = 0.5 * (H_new + np.swapaxes(H_new, 1, 2))
        change = np.linalg.norm(H_new - H, axis=(1, 2))
        H = H_new
        done = change <= 16 * np.finfo(float).eps * np.linalg.norm(H, axis=(1, 2))
        if np.all(done):
            break
    bad = ~done | ~np.all(np.isfinite(H), axis=(1, 2))
    if np.any(bad):
        C = np.zeros((n_out, s))
        C[:, :n_out] = np.eye(n_out)
        for b in np.flatnonzero(bad):
            # scaled by the measurement variance: the solver loses digits on m^2 scales
            sc = float(np.max(r_diag[b]))
            try:
                H[b] = sc * solve_discrete_are(Ad[b].T, C.T, Qd[b] / sc,
                                               np.diag(r_diag[b] / sc))
            except (np.linalg.LinAlgError, ValueError):
                H[b] = np.nan  # no stabilising solution: the likelihood is -inf
    return H


def steady_state_filter(system: ProcessNoiseSystem, sigma: np.ndarray) -> SteadyStateFilter:
    """Steady-state covariance, innovation covariance and gain for each lane.

    Parameters
    ----------
    system : ProcessNoiseSystem
    sigma : ndarray, shape (nb, n_out)
        Measurement noise standard deviations, m (> 0).
    """
    sigma = np.atleast_2d(np.asarray(sigma, dtype=float))
    n_out = sigma.shape[1]
    P = solve_filter_dare(system.Ad, system.Qd, sigma**2)
    S = P[:, :n_out, :n_out] + sigma[:, :, None] ** 2 * np.eye(n_out)
    # K = P C' S^-1 (S symmetric): solve S K' = C P
    gain = np.swapaxes(np.linalg.solve(S, P[:, :n_out, :]), 1, 2)
    return SteadyStateFilter(P=P, S=S, gain=gain)
