"""Readings rounded to a sensor's step: the interval-censored likelihood.

An encoder reports whole counts of ``q`` metres, counted from where it was zeroed; a
converter reports whole steps.  The reading's error is then not a Gaussian residual: it
is the rounding of the position, bounded by half a step and shifted by where within a
step the count was zeroed.  With white noise of level ``sigma`` before the rounding and
the zero at ``c q`` (``-1/2 <= c <= 1/2``, a fraction of a step), the reading ``y_k``
says that the model's output ``x_k`` satisfies ``y_k - x_k in [c q - q/2, c q + q/2]``
up to that noise, so the residual ``r_k = y_k - x_k`` has the density

    p(r_k) = [Phi((r_k - c q + q/2) / sigma) - Phi((r_k - c q - q/2) / sigma)] / q,

independently from sample to sample (the rounding is a function of the position; the
sample-to-sample dependence of its error while the cart moves slowly is that of the
position, which the model already carries).  For ``sigma >> q`` it is the Gaussian
density of ``N(c q, sigma^2 + q^2 / 12)`` to first order; for ``sigma -> 0`` it is 1/q
inside the step and 0 outside.  An output that is not rounded (``q = 0``) takes the
Gaussian density ``N(0, sigma^2)``.

Parameters per output: ``sigma_j`` (m, or the sensor's SI unit) and ``shift_j``
(``c``, steps).  The steps ``q_j`` come from the record (:func:`.motion.quantum_of`,
:meth:`QuantisedNoise.for_record`), never from the model parameters.

Use: ``noise="quantised"`` for records of an encoder whose rounding is the main error
(the mixed encoder + accelerometer records of docs/accelerometers.md, section 6).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import log_ndtr

from ..._errors import DataError
from ..priors import PriorSet, Uniform
from .base import HALF_LOG_2PI, SIGMA_PRIOR, NoiseModel, check_residual
from .motion import quantum_of

__all__ = ["QuantisedNoise", "SHIFT_PRIOR", "SIGMA_PRIOR_ROUNDED", "log_step_probability"]

#: Prior of the zero's place within a step, in steps.
SHIFT_PRIOR = Uniform(-0.5, 0.5)
#: Prior of the noise before the rounding: uniform from zero, sampled in ``log sigma``
#: (where its density falls as ``sigma`` towards zero).  An encoder may have no noise
#: before its count, and a log-uniform prior needs a floor: at the other noise models'
#: 1e-7 m (0.5 % of a 2.2e-5 m count) the posterior sat on it, the counts' bounds were
#: blurred at the scale at which the posterior resolves the positions, and the 90 %
#: intervals of the mixed encoder + accelerometer records covered 97-100 %
#: (docs/accelerometers.md, section 6).
SIGMA_PRIOR_ROUNDED = Uniform(0.0, SIGMA_PRIOR.hi)


def log_step_probability(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``log(Phi(hi) - Phi(lo))`` for ``lo < hi``, accurate in both tails and when
    ``hi - lo`` is small.

    Parameters
    ----------
    lo, hi : ndarray
        Standardised lower and upper ends of the step, broadcast together.

    Returns
    -------
    ndarray
        The log probability of the step, shape of the broadcast inputs.

    Examples
    --------
    >>> from scipy.stats import norm
    >>> lo, hi = np.array([-1.0, 8.0, -40.0]), np.array([0.5, 9.0, -39.0])
    >>> ref = np.log(norm.cdf(hi[:1]) - norm.cdf(lo[:1]))
    >>> bool(np.isclose(log_step_probability(lo, hi)[0], ref[0], rtol=1e-14))
    True
    >>> bool(np.isclose(log_step_probability(lo, hi)[1],
    ...                 np.log(norm.sf(8.0) - norm.sf(9.0)), rtol=1e-12))
    True
    >>> bool(np.isfinite(log_step_probability(lo, hi)[2]))
    True
    """
    lo, hi = np.broadcast_arrays(np.asarray(lo, float), np.asarray(hi, float))
    # in the upper tail use Phi(hi) - Phi(lo) = Phi(-lo) - Phi(-hi)
    up = lo > 0
    a = np.where(up, -lo, hi)
    b = np.where(up, -hi, lo)
    la, lb = log_ndtr(a), log_ndtr(b)
    return la + np.log(-np.expm1(lb - la))


@dataclass(frozen=True)
class QuantisedNoise(NoiseModel):
    """Readings rounded to steps ``q_j`` after white noise ``sigma_j``; parameters
    ``sigma_1..n, shift_1..n`` (see the module docstring).

    Attributes
    ----------
    quantum_m : ndarray, shape (n_out,), or None
        Each output's step ``q_j`` in its SI unit (0: not rounded); set by
        :meth:`for_record`.  Without it the model cannot evaluate a record.

    Examples
    --------
    Far from the rounding (``sigma >> q``) the density is the Gaussian one of the
    rounded reading:

    >>> from bayesmodal.inference.noise.base import WhiteNoise
    >>> r = np.random.default_rng(0).normal(size=(1, 200, 1))
    >>> m = QuantisedNoise(quantum_m=np.array([1e-4]))
    >>> a = m.pointwise(r, np.array([[1.0, 0.0]])).sum()
    >>> b = WhiteNoise().pointwise(r, np.array([[1.0]])).sum()
    >>> bool(abs(a - b) < 1e-6)
    True
    """

    name: str = "quantised"
    quantum_m: np.ndarray | None = field(default=None, repr=False, compare=False)

    def for_record(self, experiment) -> QuantisedNoise:
        """This model with the steps of ``experiment``'s outputs (``quantum_of``)."""
        return replace(self, quantum_m=quantum_of(experiment.y_m))

    def names(self, n_outputs: int) -> tuple[str, ...]:
        return tuple(f"{p}_{j + 1}" for p in ("sigma", "shift") for j in range(n_outputs))

    def priors(self, n_outputs: int) -> PriorSet:
        n = n_outputs
        return PriorSet(self.names(n), (SIGMA_PRIOR_ROUNDED,) * n + (SHIFT_PRIOR,) * n,
                        ("log",) * n + ("identity",) * n)

    def valid(self, params: np.ndarray) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 2
        sigma, shift = params[:, :n], params[:, n:]
        return (np.all(np.isfinite(params), axis=-1) & np.all(sigma > 0, axis=-1)
                & np.all(np.abs(shift) <= 0.5, axis=-1))

    def _steps(self, n_outputs: int) -> np.ndarray:
        if self.quantum_m is None:
            raise DataError("quantised noise needs the record's steps: build it with "
                            "QuantisedNoise().for_record(experiment) (the likelihoods do)")
        q = np.asarray(self.quantum_m, dtype=float)
        if q.shape != (n_outputs,):
            raise DataError(f"quantised noise has steps for {q.size} outputs, the record "
                            f"has {n_outputs}; build it with for_record on that record")
        return q

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        nb, N, n = r.shape
        params = self._params(params, n)
        ok = self.valid(params)
        safe = np.where(ok[:, None], params, np.r_[np.ones(n), np.zeros(n)])
        sigma, shift = safe[:, None, :n], safe[:, None, n:]
        q = self._steps(n)[None, None, :]
        rounded = q > 0
        qs = np.where(rounded, q, 1.0)
        centre = r - shift * q
        out = np.where(
            rounded,
            log_step_probability((centre - qs / 2) / sigma, (centre + qs / 2) / sigma)
            - np.log(qs),
            -HALF_LOG_2PI - np.log(sigma) - 0.5 * (r / sigma) ** 2)
        out[~ok] = -np.inf
        return out

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        return self._loglik_by_terms(R, params)

    def start(self, r: np.ndarray) -> np.ndarray:
        """``shift`` from the residuals' mean (in steps, within the prior), ``sigma`` from
        their variance less the rounding's ``q^2 / 12`` (at least a tenth of a step)."""
        r = check_residual(r)
        q = self._steps(r.shape[1])
        var = np.var(r, axis=0)
        shift = np.where(q > 0, np.clip(np.mean(r, axis=0) / np.where(q > 0, q, 1.0),
                                        -0.45, 0.45), 0.0)
        sigma = np.where(q > 0, np.sqrt(np.maximum(var - q**2 / 12, (q / 10) ** 2)),
                         np.sqrt(np.mean(r**2, axis=0)))
        return np.r_[np.maximum(sigma, SIGMA_PRIOR.lo * 10), shift]

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        """Residual records: the white noise plus a rounding error drawn uniform over the
        shifted step, independent from sample to sample (the rounding of a position that
        moves by many steps between samples; a slow one repeats its error)."""
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 2
        q = self._steps(n)
        g = np.random.default_rng(rng)
        shape = (params.shape[0], int(n_samples), n)
        e = g.standard_normal(shape) * params[:, None, :n]
        u = (g.uniform(-0.5, 0.5, shape) + params[:, None, n:]) * q
        return e + u
