"""Exact zero-order-hold simulation of the linear rig model, batched over parameter sets.

With the input held constant over each sample interval, the continuous system
``x' = A x + B v`` is integrated exactly by

    [Ad  Bd]  =  expm( [[A, B], [0, 0]] * dt )     (top block row)
    x[k+1] = Ad x[k] + Bd v[k]

(Van Loan's block exponential).  This is the discretisation ``scipy.signal.lsim`` uses
with ``interp=False``; here the exponential is taken for a whole stack of parameter sets at
once and the recursion runs in a compiled kernel with the batch index innermost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ._errors import DataError, ModelError
from ._kernels import run_recursion

__all__ = ["discretize_zoh", "simulate_linear", "simulate_state_space", "Discretized"]


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
    if not (np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim == 2:
        A = A[None]
    if B.ndim == 1:
        B = B[None]
    nb, s, _ = A.shape
    F = np.zeros((nb, s + 1, s + 1))
    F[:, :s, :s] = A * dt
    F[:, :s, s] = B * dt
    E = expm(F)
    return Discretized(Ad=E[:, :s, :s], Bd=E[:, :s, s], dt=float(dt))


def simulate_state_space(
    A: np.ndarray,
    B: np.ndarray,
    u: np.ndarray,
    dt: float,
    n_out: int,
    x0: np.ndarray | None = None,
) -> np.ndarray:
    """Simulate a stack of continuous systems under a ZOH input; outputs are the first states.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s)
    B : ndarray, shape (nb, s)
    u : ndarray, shape (N,)
        Input samples, held constant over each interval.
    dt : float
        Sample interval, s.
    n_out : int
        Number of leading states returned as outputs.
    x0 : ndarray, shape (s,) or (nb, s), optional
        Initial state; zero by default.

    Returns
    -------
    y : ndarray, shape (nb, N, n_out)
        Possibly a non-contiguous view; ``y[:, k]`` is the state at ``t = k dt``.
    """
    d = discretize_zoh(A, B, dt)
    nb, s, _ = d.Ad.shape
    u = np.ascontiguousarray(u, dtype=float)
    if u.ndim != 1:
        raise DataError(f"input u must be 1-D, got shape {u.shape}")
    if x0 is None:
        x0b = np.zeros((nb, s))
    else:
        x0 = np.asarray(x0, dtype=float)
        if x0.shape not in ((s,), (nb, s)):
            raise DataError(f"x0 must have shape ({s},) or ({nb}, {s}), got {x0.shape}")
        x0b = np.broadcast_to(x0, (nb, s))
    return run_recursion(d.Ad, d.Bd, u, x0b, int(n_out))


def simulate_linear(model, theta: np.ndarray, u: np.ndarray, dt: float, x0=None) -> np.ndarray:
    """Cart positions of the linear rig model for one or many parameter sets.

    Parameters
    ----------
    model : LinearModel
    theta : ndarray, shape (n_params,) or (nb, n_params)
        Parameter vectors in ``model.names`` order.
    u : ndarray, shape (N,)
        Motor voltage, V, held over each sample interval.
    dt : float
        Sample interval, s.
    x0 : ndarray, shape (2n,) or (nb, 2n), optional
        Initial state (positions m, velocities m/s); zero by default.

    Returns
    -------
    y : ndarray, shape (N, n) or (nb, N, n)
        Cart positions, m.

    Raises
    ------
    ModelError
        If any parameter set is impossible (see ``LinearModel.valid``).

    Examples
    --------
    >>> from bayesmodal.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> theta = np.array([6.2, 1.5, 1.5, 1.1, 1.5, 1e-4])
    >>> simulate_linear(model, theta, np.ones(100), 0.005).shape
    (100, 3)
    """
    theta = np.asarray(theta, dtype=float)
    single = theta.ndim == 1
    theta = model.check(np.atleast_2d(theta))
    if theta.ndim != 2:
        raise ModelError(f"theta must have shape (n_params,) or (nb, n_params), got {theta.shape}")
    A, B = model.state_space(theta)
    y = simulate_state_space(A, B, u, dt, model.n_carts, x0)
    return y[0] if single else y
