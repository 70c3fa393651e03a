"""A noise level per record size: the discrepancy scales with the record.

On the measured ECP 210 records the linear model misses about the same share of every
record (fit 55-74 %), so a noise level shared by the records in metres is too small for
the big records (the sweeps) and too large for the small ones (the impulses):
leave-one-record-out bands then under-cover the impulses and are more than twice as wide
as the sweeps (docs/uncertainty.md, "A noise level per record size").  With
``RecordLayout(noise_scale="response")`` record ``r``'s noise is the shared noise model
times a number ``s_r``, the root mean square of the model's response to the record's
input, relative to the geometric mean over the fitted records:

    s_r = rms(y_r(theta_ref)) / exp(mean_k log rms(y_k(theta_ref)))

``theta_ref`` is one fixed parameter row (the walkers' least-squares start), so ``s_r``
is a constant of the likelihood, read from the input through the model, never from the
record's measured positions; a new record (a held-out one) gets its ``s`` the same way.
Fixing it matters: a scale that moved with the sampled parameters would add
``-N log s(theta)`` to the log-likelihood and pull the gains towards small responses.

With ``noise_scale = "power"`` the level is ``sigma s_r^a`` with the exponent ``a``
(``scale_power``) sampled in [0, 1]: one level in metres (``a = 0``) and a level
proportional to the record's size (``a = 1``) are its two ends, and the fitted records
choose between them.

For Gaussian noise models (white, AR(1), AR(p)) scaling the residual's standard deviation
by ``s`` is the same as dividing the residual by ``s`` and adding ``-N n_out log s``:
``Likelihood`` uses the first for white and AR(1) noise, the second for the others.
Process noise (a random force through the dynamics) has no such scale and refuses it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError
from ..data import Experiment

__all__ = ["NOISE_SCALES", "POWER_NAME", "RecordScales", "record_scales"]

#: ``[records] noise_scale`` values: one level in metres, the level times each record's
#: relative response size, or that size to a sampled power.
NOISE_SCALES = ("none", "response", "power")

#: Name, prior bounds and start of the sampled exponent of ``noise_scale = "power"``.
POWER_NAME = "scale_power"
POWER_BOUNDS = (0.0, 1.0)
POWER_START = 0.5


@dataclass(frozen=True)
class RecordScales:
    """Relative response sizes of the fitted records and how to size a new one.

    Attributes
    ----------
    at : ndarray, shape (n_mech,)
        The parameter row the responses are simulated with (single-record model order).
    rms_m : ndarray, shape (n_records,)
        Root mean square of each fitted record's simulated response, m.
    reference_m : float
        Their geometric mean, m (or the reference of the records a likelihood was fitted
        to, when it is rebuilt on others).
    """

    at: np.ndarray
    rms_m: np.ndarray
    reference_m: float

    @property
    def scales(self) -> np.ndarray:
        """``rms_m / reference_m``, shape (n_records,)."""
        return self.rms_m / self.reference_m

    @classmethod
    def reference(cls, at, reference_m: float) -> RecordScales:
        """The reference of a stored run (its row and size) without its records' sizes."""
        return cls(np.asarray(at, dtype=float), np.empty(0), float(reference_m))

    def scale_of(self, rms_m: float) -> float:
        """The scale of a record whose simulated response has this RMS, m."""
        return float(rms_m) / self.reference_m


def powered(scale: float, power: np.ndarray | None) -> np.ndarray | float:
    """``scale ** power`` per parameter row (shape (nb,)), or ``scale`` without a power."""
    return scale if power is None else np.power(scale, power)


def response_rms(predict: Callable[[np.ndarray, Experiment], np.ndarray], at: np.ndarray,
                 experiment: Experiment) -> float:
    """RMS over samples and outputs of ``predict(at[None], experiment)``, m."""
    y = np.asarray(predict(np.asarray(at, dtype=float)[None], experiment))[0]
    rms = float(np.sqrt(np.mean(y**2)))
    if not np.isfinite(rms) or rms <= 0:
        raise DataError(
            f"{experiment.name}: the model's response to this record's input is "
            f"{'zero' if rms == 0 else 'not finite'} at the reference parameters, so its "
            "noise cannot be scaled by it; use noise_scale = 'none' for this record set")
    return rms


def record_scales(predict: Callable[[np.ndarray, Experiment], np.ndarray], at,
                  experiments: Sequence[Experiment], n_mech: int,
                  reference_m: float | None = None) -> RecordScales:
    """The :class:`RecordScales` of records at one parameter row.

    Parameters
    ----------
    predict : callable
        ``predict(mech (1, n_mech), experiment) -> (1, N, n_out)``, m: the model's
        noise-free response (``Likelihood.predict_mech`` with zero offset).
    at : array_like, shape (n_mech,)
        Model parameters in single-record order (e.g. the least-squares estimate).
    experiments : sequence of Experiment
    n_mech : int
        Expected length of ``at``.
    reference_m : float, optional
        The reference size, m: default the geometric mean of these records' RMS.  Given
        when a fitted likelihood is rebuilt on other records (its noise level is relative
        to the records it was fitted to).
    """
    at = np.asarray(at, dtype=float).ravel()
    if at.shape != (n_mech,) or not np.all(np.isfinite(at)):
        raise ConfigError(
            f"scale_at must be {n_mech} finite model parameters (the single-record order), "
            f"got shape {at.shape}; pass e.g. the least-squares estimate's theta")
    rms = np.array([response_rms(predict, at, e) for e in experiments])
    ref = float(np.exp(np.mean(np.log(rms)))) if reference_m is None else float(reference_m)
    if not (np.isfinite(ref) and ref > 0):
        raise ConfigError(f"reference_m must be a positive size in m, got {reference_m!r}")
    return RecordScales(at, rms, ref)
