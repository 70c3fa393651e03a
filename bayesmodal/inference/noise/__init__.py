"""Noise and discrepancy models of the residual, as standalone array-level modules.

- :mod:`.base`: the :class:`NoiseModel` protocol, with white and AR(1) noise;
- :mod:`.arp`: AR(p) per output, exact stationary likelihood, order chosen by BIC;
- :mod:`.integrated`: integrated AR(1) (ARIMA(1, 1, 0)), a wandering discrepancy that
  starts at rest;
- :mod:`.kalman`: process noise (a random force on each cart) through the steady-state
  Kalman filter of the linear model;
- :mod:`.steady_filter`: that model discretised, and its steady-state filter (the DARE);
- :mod:`.quantised`: readings rounded to a sensor's step (interval-censored likelihood).

See docs/noise_models.md.
"""

from .arp import ARpNoise, OrderChoice, burg, choose_order, levinson_table, pacf_to_ar
from .base import AR1Noise, NoiseModel, WhiteNoise
from .integrated import IntegratedAR1Noise
from .kalman import (
    ProcessNoise,
    kalman_loglik,
    kalman_pointwise,
    simulate_process_noise,
)
from .quantised import QuantisedNoise
from .steady_filter import steady_state_filter

__all__ = ["NoiseModel", "WhiteNoise", "AR1Noise", "IntegratedAR1Noise", "ARpNoise",
           "OrderChoice", "burg", "choose_order", "levinson_table", "pacf_to_ar",
           "ProcessNoise", "QuantisedNoise", "kalman_loglik",
           "kalman_pointwise", "simulate_process_noise", "steady_state_filter"]
