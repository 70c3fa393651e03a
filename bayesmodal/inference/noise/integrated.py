"""Integrated AR(1) noise: a discrepancy that wanders, started at rest.

The AR(1) posterior of the friction model on the measured ECP 210 records puts a third of
its draws above ``phi = 0.99999`` (docs/uncertainty.md): the residual behaves like a
random walk (where a cart sticks, the model's position error persists), and the
stationary AR(1) then sits at the edge of its parameter space, where the sampler mixes
slowly and the stationary spread ``sigma / sqrt(1 - phi^2)`` is unbounded.  This model
says it directly: the residual's increments are a stationary AR(1),

    r_k = r_{k-1} + d_k,   d_k = phi d_{k-1} + e_k,   e_k ~ N(0, sigma^2),

with ``r_{-1} = 0`` (the record starts at rest, where the model and the rig agree), i.e.
ARIMA(1, 1, 0) per output.  The map from ``r`` to ``d = (r_0, r_1 - r_0, ...)`` is
triangular with a unit diagonal, so the density of ``r`` is the stationary AR(1) density
of ``d`` (no Jacobian term).  ``phi`` is now the persistence of the error's *velocity*
(a stationary residual has anti-correlated increments: a negative ``phi``).  The
predictive spread of a new record grows without bound (as the square root of its length
for ``phi = 0``): this model suits records of similar lengths, and the leave-one-record-out
check measures whether it predicts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import AR1Noise, check_residual

__all__ = ["IntegratedAR1Noise"]


def _increments(R: np.ndarray, axis: int) -> np.ndarray:
    """``d_0 = r_0``, ``d_k = r_k - r_{k-1}`` along ``axis`` (the record starts at rest)."""
    return np.diff(R, axis=axis, prepend=0.0)


@dataclass(frozen=True)
class IntegratedAR1Noise(AR1Noise):
    """ARIMA(1, 1, 0) residuals per output, started at rest; parameters
    ``sigma_1..n, phi_1..n`` of the increments' stationary AR(1).

    Examples
    --------
    >>> r = np.cumsum(np.ones((1, 5, 1)), axis=1)   # increments all 1
    >>> d = IntegratedAR1Noise().pointwise(r, np.array([[1.0, 0.0]]))
    >>> bool(np.allclose(d, AR1Noise().pointwise(np.ones((1, 5, 1)), np.array([[1.0, 0.0]]))))
    True
    """

    name: str = "iar1"

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        return super().loglik(_increments(np.asarray(R, dtype=float), 0), params)

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        return super().pointwise(_increments(np.asarray(r, dtype=float), 1), params)

    def start(self, r: np.ndarray) -> np.ndarray:
        return super().start(_increments(check_residual(r), 0))

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        """Residual records, shape (nb, n_samples, n_out), m: cumulative sums of stationary
        AR(1) increments (``r_{-1} = 0``)."""
        return np.cumsum(super().simulate(params, n_samples, rng), axis=1)
