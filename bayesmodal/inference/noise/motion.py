"""AR(1) noise whose level follows each cart's measured speed.

On the measured ECP 210 records the AR(1) innovations are not of one size: the 90 %
predictive band of the linear and the extended models holds every sample while the carts
rest and 81-83 % while they move (docs/inference.md).  Encoder quantisation, the rack's
tooth-to-tooth error and the friction the model simplifies all act while a cart moves.
This model lets the innovation level follow the motion of the cart the output measures:

    r_k = phi r_{k-1} + s_k e_k,   e_k ~ N(0, 1),
    s_k^2 = f^2 + sigma^2 (rest + (1 - rest) w_k)^2,   0 <= w_k <= 1,

per output, with ``r_0 ~ N(0, s_0^2 / (1 - phi^2))``.  ``sigma`` is the level at the
record's fastest motion, ``rest`` the level at rest as a fraction of it (``rest = 1``
and no floor is the plain AR(1) model), and ``w_k`` the output's speed, ``|dy/dt|``
averaged over ``window_s`` seconds and scaled to 1 at its largest value in the record.

``f`` is the floor set by the sensor's resolution: an encoder that reads whole counts of
``q`` metres adds a rounding error of variance ``q^2 / 12`` to every sample, which puts
``(1 + phi^2) q^2 / 12`` into each innovation ``r_k - phi r_{k-1}``.  Without it a
resting cart, whose reading does not change at all, drives the level at rest to zero and
the likelihood without bound.  ``q`` is read from the record (:func:`quantum_of`: the
step of which every change of an output is a whole multiple; 0 for unquantised data).

The covariate ``w`` and the step ``q`` come from the record's measured positions, once
(:meth:`MotionAR1Noise.for_record`), never from the model parameters: the likelihood stays
a function of the residuals alone, as the noise-model protocol asks, and a held-out record
brings its own.  The speed of a measurement includes its noise; averaged over
``window_s`` (0.1 s, about a tenth of the slowest period of the ECP rig) an encoder's count
steps at rest add less than a count per window.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import convolve1d

from ..._errors import DataError
from ..priors import LogUniform, PriorSet
from .base import COEF_PRIOR, HALF_LOG_2PI, SIGMA_PRIOR, AR1Noise, NoiseModel, check_residual

__all__ = ["MotionAR1Noise", "REST_PRIOR", "quantum_of", "speed_weight"]

#: Prior of the rest fraction ``rest_j`` (level at rest over level in motion):
#: log-uniform on 1e-4 to 1e2, so that ``rest = 1`` (one level) sits inside with room
#: both ways.
REST_PRIOR = LogUniform(1e-4, 1e2)


def speed_weight(y: np.ndarray, dt: float, window_s: float) -> np.ndarray:
    """Each output's speed, averaged over ``window_s`` and scaled to 1 at its peak.

    Parameters
    ----------
    y : ndarray, shape (N, n_out), m
        Measured positions of one record.
    dt : float
        Sample interval, s.
    window_s : float
        Length of the moving average, s (at least one sample).

    Returns
    -------
    ndarray, shape (N, n_out)
        Values in [0, 1]; an output that never moves gets 0 everywhere.

    Examples
    --------
    >>> t = np.arange(0, 1, 0.01)[:, None]
    >>> w = speed_weight(np.where(t < 0.5, 0.0, t - 0.5), 0.01, 0.05)
    >>> float(w[:40].max()), float(w[-1, 0])
    (0.0, 1.0)
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    speed = np.abs(np.gradient(y, dt, axis=0))
    n = max(1, int(round(window_s / dt)))
    env = convolve1d(speed, np.full(n, 1.0 / n), axis=0, mode="nearest")
    peak = env.max(axis=0)
    return np.divide(env, peak, out=np.zeros_like(env), where=peak > 0)


def quantum_of(y: np.ndarray, rtol: float = 1e-6) -> np.ndarray:
    """Each output's quantisation step: the smallest change of its reading when every
    change is a whole multiple of it (within ``rtol`` of the step), else 0.

    Parameters
    ----------
    y : ndarray, shape (N, n_out), m
    rtol : float
        Tolerance on the multiples, in steps (float rounding of a unit conversion).

    Returns
    -------
    ndarray, shape (n_out,), m

    Examples
    --------
    >>> quantum_of(np.array([[0.0, 0.0], [1e-3, 0.2], [4e-3, 0.5]])).tolist()
    [0.001, 0.0]
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    out = np.zeros(y.shape[1])
    for j in range(y.shape[1]):
        d = np.abs(np.diff(y[:, j]))
        d = d[d > 0]
        if d.size == 0:
            continue
        q = d.min()
        k = d / q
        if np.all(np.abs(k - np.round(k)) <= rtol * np.maximum(1.0, k)):
            out[j] = q
    return out


@dataclass(frozen=True)
class MotionAR1Noise(NoiseModel):
    """AR(1) residuals per output whose innovation level follows the output's speed;
    parameters ``sigma_1..n, phi_1..n, rest_1..n``.

    Attributes
    ----------
    window_s : float
        Moving-average length of the speed covariate, s.
    weight : ndarray, shape (N, n_out), or None
        The record's covariate ``w`` (:func:`speed_weight`); set by :meth:`for_record`.
        Without it the model cannot evaluate a record.
    quantum_m : ndarray, shape (n_out,), or None
        Each output's quantisation step ``q``, m (:func:`quantum_of`); None is no floor.

    Examples
    --------
    With ``rest = 1`` and no floor the model is the stationary AR(1) model:

    >>> from bayesmodal.inference.noise.base import AR1Noise
    >>> r = np.random.default_rng(0).normal(size=(1, 50, 2))
    >>> m = MotionAR1Noise(weight=np.random.default_rng(1).uniform(size=(50, 2)))
    >>> p = np.array([[0.5, 2.0, 0.3, -0.2, 1.0, 1.0]])
    >>> bool(np.allclose(m.pointwise(r, p), AR1Noise().pointwise(r, p[:, :4])))
    True
    """

    name: str = "ar1:motion"
    window_s: float = 0.1
    weight: np.ndarray | None = field(default=None, repr=False, compare=False)
    quantum_m: np.ndarray | None = field(default=None, repr=False, compare=False)

    def for_record(self, experiment) -> MotionAR1Noise:
        """This model with the speed covariate and the quantisation step of
        ``experiment`` (an ``Experiment``)."""
        return replace(self, weight=speed_weight(experiment.y_m, experiment.dt,
                                                 self.window_s),
                       quantum_m=quantum_of(experiment.y_m))

    def names(self, n_outputs: int) -> tuple[str, ...]:
        return tuple(f"{p}_{j + 1}" for p in ("sigma", "phi", "rest")
                     for j in range(n_outputs))

    def priors(self, n_outputs: int) -> PriorSet:
        n = n_outputs
        return PriorSet(self.names(n), (SIGMA_PRIOR,) * n + (COEF_PRIOR,) * n
                        + (REST_PRIOR,) * n, ("log",) * n + ("tanh",) * n + ("log",) * n)

    def valid(self, params: np.ndarray) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 3
        sigma, phi, rest = params[:, :n], params[:, n:2 * n], params[:, 2 * n:]
        return (np.all(np.isfinite(params), axis=-1) & np.all(sigma > 0, axis=-1)
                & np.all(np.abs(phi) < 1, axis=-1) & np.all(rest > 0, axis=-1))

    def _weight(self, n_samples: int, n_outputs: int) -> np.ndarray:
        if self.weight is None:
            raise DataError(
                "ar1:motion noise needs the record's speed: build it with "
                "MotionAR1Noise().for_record(experiment) (the likelihoods do)")
        if self.weight.shape != (n_samples, n_outputs):
            raise DataError(
                f"ar1:motion noise has a speed covariate of shape {self.weight.shape} for a "
                f"record of shape {(n_samples, n_outputs)}; build it with for_record on "
                "that record")
        return self.weight

    def levels(self, params: np.ndarray, n_samples: int) -> np.ndarray:
        """Innovation levels ``s_k``, shape (nb, N, n_out), m, of valid parameter rows."""
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 3
        w = self._weight(n_samples, n)[None]
        sigma, phi, rest = (params[:, None, :n], params[:, None, n:2 * n],
                             params[:, None, 2 * n:])
        s = sigma * (rest + (1.0 - rest) * w)
        if self.quantum_m is None or not np.any(self.quantum_m):
            return s
        return np.sqrt(s**2 + (1.0 + phi**2) * self.quantum_m**2 / 12.0)

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        nb, N, n = r.shape
        params = self._params(params, n)
        ok = self.valid(params)
        safe = np.where(ok[:, None], params, np.r_[np.ones(n), np.zeros(n), np.ones(n)])
        phi = safe[:, None, n:2 * n]
        s = self.levels(safe, N)                                 # (nb, N, n)
        e = np.empty_like(r)
        e[:, 1:] = r[:, 1:] - phi * r[:, :-1]
        e[:, :1] = r[:, :1] * np.sqrt(1.0 - phi**2)              # stationary start
        out = -HALF_LOG_2PI - np.log(s) - 0.5 * (e / s) ** 2
        out[:, :1] += 0.5 * np.log(1.0 - phi**2)
        out[~ok] = -np.inf
        return out

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        return self._loglik_by_terms(R, params)

    def start(self, r: np.ndarray) -> np.ndarray:
        """AR(1) moments, and the rest fraction from a straight line through the
        innovations' sizes: ``E|e_k|`` is proportional to ``rest + (1 - rest) w_k``, so
        the least-squares line ``a + b w`` through ``|e_k|`` gives ``rest = a / (a + b)``
        (1 for an output that never moves; the floor is left out of the start)."""
        r = check_residual(r)
        n = r.shape[1]
        w = self._weight(*r.shape)[1:]
        phi = AR1Noise().start(r)[n:]   # the AR(1) moment estimate of phi
        e = np.abs(r[1:] - phi * r[:-1])
        rest = np.ones(n)
        for j in range(n):
            if np.ptp(w[:, j]) > 0:
                b, a = np.polyfit(w[:, j], e[:, j], 1)
                if a > 0 and a + b > 0:
                    rest[j] = a / (a + b)
        rest = np.clip(rest, REST_PRIOR.lo * 1.01, REST_PRIOR.hi * 0.99)
        sigma = np.sqrt(np.mean((e / (rest + (1.0 - rest) * w)) ** 2, axis=0))
        return np.r_[sigma, phi, rest]

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 3
        s = self.levels(params, int(n_samples))
        phi = params[:, n:2 * n]
        e = np.random.default_rng(rng).standard_normal(s.shape) * s
        out = np.empty_like(e)
        out[:, 0] = e[:, 0] / np.sqrt(1.0 - phi**2)
        for k in range(1, int(n_samples)):
            out[:, k] = phi * out[:, k - 1] + e[:, k]
        return out
