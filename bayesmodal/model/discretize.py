"""Exact zero-order-hold discretisation, and the time steps of a record.

With the input held constant over each sample interval, ``x' = A x + B v`` is integrated
exactly by

    [Ad  Bd]  =  expm( [[A, B], [0, 0]] * dt )     (top block row, Van Loan)
    x[k+1] = Ad x[k] + Bd v[k]

which is what ``scipy.signal.lsim(..., interp=False)`` computes (``discretize_zoh``).  A
record whose stamps jitter has steps ``t[k+1] - t[k]`` that differ; ``step_groups`` finds
the few distinct ones (each discretised once by the simulator, ``bayesmodal.model.simulate``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .._errors import DataError

__all__ = ["Discretized", "discretize_zoh", "step_groups"]


@dataclass(frozen=True)
class Discretized:
    """Zero-order-hold discretisation of a batch of continuous systems.

    Attributes
    ----------
    Ad : ndarray, shape (nb, s, s)
    Bd : ndarray, shape (nb, s)
    dt : float
        Sample interval, s.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    dt: float


def _check_dt(dt: float) -> float:
    if not (np.isscalar(dt) and np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    return float(dt)


def step_groups(steps: np.ndarray, t_max: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The distinct values of a record's steps and, for each step, which one it is.

    Steps are differences of stamps, each exact only to the stamps' own rounding, so two
    steps are the same when they differ by less than ``4 eps max(|t|)`` (a difference of
    two floats near ``t`` is off by up to ``eps |t|``; stamps rounded to ms that should give
    exactly 1 ms give 0.001 +- 1e-18..1e-15 s).

    Parameters
    ----------
    steps : ndarray, shape (N - 1,)
        Steps ``t[k+1] - t[k]``, s (> 0).
    t_max : float
        Largest ``|t|`` of the stamps, s (the resolution's scale; default the sum of
        the steps).

    Returns
    -------
    values : ndarray, shape (J,)
        Each group's first step, s, in order of first appearance.
    index : ndarray of int64, shape (N,)
        ``values[index[k]]`` is the step from sample ``k`` to ``k + 1``; the last entry
        (no step follows) is 0.

    Examples
    --------
    >>> v, i = step_groups(np.diff(np.array([0.0, 0.001, 0.002, 0.004, 0.005])))
    >>> v.tolist(), i.tolist()
    ([0.001, 0.002], [0, 0, 1, 0, 0])
    """
    h = np.asarray(steps, dtype=float)
    scale = max(float(t_max), float(np.sum(h)))
    tol = 4 * np.finfo(float).eps * scale
    order = np.argsort(h, kind="stable")
    hs = h[order]
    label_sorted = np.concatenate([[0], np.cumsum(np.diff(hs) > tol)])
    label = np.empty(h.size, np.int64)
    label[order] = label_sorted
    # renumber the groups by first appearance, so that step 0's group is block 0
    _, first = np.unique(label, return_index=True)
    rank = np.empty(first.size, np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    index = rank[label]
    # each group's first step stands for it (all agree to the stamps' resolution; a
    # constant array of steps gives back its value exactly)
    values = h[np.sort(first)]
    return values, np.concatenate([index, [0]])


def _check_steps(dt, n_samples: int):
    """``(dt, None, None)`` for a scalar step, else ``(h_0, values, index)`` of
    :func:`step_groups` for per-sample steps (one group: a uniform step again)."""
    if np.isscalar(dt):
        return _check_dt(dt), None, None
    h = np.asarray(dt, dtype=float)
    if h.shape != (n_samples - 1,):
        raise DataError(f"steps must be a scalar dt or have shape ({n_samples - 1},) (one "
                        f"per interval between the {n_samples} samples), got {h.shape}")
    if not np.all(np.isfinite(h) & (h > 0)):
        k = int(np.argmax(~(np.isfinite(h) & (h > 0))))
        raise DataError(f"steps must be finite and > 0 s; step {k} is {h[k]!r}")
    values, index = step_groups(h)
    if values.size == 1:
        return float(values[0]), None, None
    return float(values[0]), values, index



def _batched(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (s, s) or (nb, s, s) and ``B`` (s,) or (nb, s) as float arrays with a leading
    batch dimension (nb = 1 for an unbatched system)."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A = A[None]
    if B.ndim == 1:
        B = B[None]
    return A, B


def discretize_zoh(A: np.ndarray, B: np.ndarray, dt: float) -> Discretized:
    """Exact ZOH discretisation of ``x' = A x + B u`` for a stack of systems.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s) or (s, s)
    B : ndarray, shape (nb, s) or (s,)
    dt : float
        Sample interval, s (> 0).

    Returns
    -------
    Discretized
        With leading batch dimension (nb = 1 for unbatched input).

    Examples
    --------
    >>> d = discretize_zoh(np.array([[-1.0]]), np.array([1.0]), 0.1)
    >>> float(d.Ad[0, 0, 0])  # exp(-0.1)
    0.9048374180359595
    """
    dt = _check_dt(dt)
    A, B = _batched(A, B)
    nb, s, _ = A.shape
    F = np.zeros((nb, s + 1, s + 1))
    F[:, :s, :s] = A * dt
    F[:, :s, s] = B * dt
    E = expm(F)
    return Discretized(Ad=E[:, :s, :s], Bd=E[:, :s, s], dt=dt)
