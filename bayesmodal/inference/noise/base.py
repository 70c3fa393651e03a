"""The noise-model protocol: Gaussian residual models with a narrow array interface.

A noise model describes the residual ``r = y - yhat(theta)`` of each output of one record
(m) given a few noise parameters per output.  It knows nothing about the mechanical model,
so any likelihood (single record, several records with per-record noise) can call it on
the residual arrays it already has.  Shapes, with ``nb`` parameter sets (emcee walkers):

- ``params``: ``(nb, n_noise)``, ordered as ``names(n_outputs)``;
- ``R``: ``(N, n_out, nb)``, batch innermost (the simulator's memory layout), for the
  fast total :meth:`NoiseModel.loglik`;
- ``r``: ``(nb, N, n_out)`` for :meth:`NoiseModel.pointwise` (terms that sum exactly to
  ``loglik``) and :meth:`NoiseModel.simulate`.

Rows with parameters outside ``valid`` get ``-inf`` (never an exception), like the
likelihood's impossible mechanical parameters.  ``sigma_j`` is always the innovation
standard deviation of output ``j`` in m, so the existing ``LogUniform(1e-7, 0.1)`` prior
applies to every model; the other parameters live in ``(-1, 1)`` with the ``tanh``
transform of :mod:`bayesmodal.inference.priors`.

:class:`WhiteNoise` and :class:`AR1Noise` are the two models of
:mod:`bayesmodal.inference.likelihood` in this form (same numbers as ``white_terms`` and
``ar1_terms``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..._errors import DataError
from ..noise_terms import (
    ar1_terms,
    residual_loglik,  # the sufficient-statistics form
    simulate_noise,
    white_terms,
)
from ..priors import LogUniform, PriorSet, Uniform

__all__ = ["NoiseModel", "WhiteNoise", "AR1Noise", "HALF_LOG_2PI", "SIGMA_PRIOR",
           "COEF_PRIOR", "check_residual"]

HALF_LOG_2PI = 0.5 * float(np.log(2 * np.pi))

#: Prior of every innovation standard deviation ``sigma_j`` (m), as in ``default_priors``.
SIGMA_PRIOR = LogUniform(1e-7, 0.1)
#: Prior of every coefficient in (-1, 1) (AR(1) ``phi_j``, partial autocorrelations).
COEF_PRIOR = Uniform(-1.0, 1.0)


def check_residual(r: np.ndarray, n_outputs: int | None = None) -> np.ndarray:
    """A residual record as a float array of shape (N, n_out); one-line DataError otherwise."""
    r = np.asarray(r, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    if r.ndim != 2 or r.shape[0] < 2:
        raise DataError(f"residual record must have shape (N >= 2, n_out), got {r.shape}")
    if n_outputs is not None and r.shape[1] != n_outputs:
        raise DataError(f"residual record has {r.shape[1]} outputs, expected {n_outputs}")
    if not np.all(np.isfinite(r)):
        raise DataError("residual record has non-finite values (NaN or inf); drop those samples")
    return r


class NoiseModel(ABC):
    """A Gaussian model of per-output residuals (subclasses are frozen dataclasses).

    Attributes
    ----------
    name : str
        Short label (``"white"``, ``"ar1"``, ``"ar(2,3,1)"``).
    """

    name: str

    @abstractmethod
    def names(self, n_outputs: int) -> tuple[str, ...]:
        """Parameter names in vector order, ``sigma_1..n`` first."""

    def for_record(self, experiment) -> NoiseModel:
        """The model for one record (an ``Experiment``): itself unless the model reads a
        covariate from the record (a level that follows the record's motion, say).

        The likelihoods call it once per record and evaluate, draw and start that
        record's noise with the model it returns; a held-out record gets its own.
        """
        return self

    def n_params(self, n_outputs: int) -> int:
        """Number of noise parameters for ``n_outputs`` outputs."""
        return len(self.names(n_outputs))

    @abstractmethod
    def valid(self, params: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (nb,), of parameter sets with a finite likelihood possible."""

    @abstractmethod
    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Total log density of residuals ``R``, shape (N, n_out, nb), m; returns (nb,)."""

    @abstractmethod
    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Log density terms, shape (nb, N, n_out), of ``r`` (nb, N, n_out); sum = loglik."""

    @abstractmethod
    def start(self, r: np.ndarray) -> np.ndarray:
        """Moment estimates, shape (n_noise,), from one residual record ``r`` (N, n_out)."""

    @abstractmethod
    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        """Residual records, shape (nb, n_samples, n_out), m, with a stationary start."""

    def priors(self, n_outputs: int) -> PriorSet:
        """Default priors of the noise parameters (``sigma`` log-uniform, others in (-1, 1)).

        Concatenate with the mechanical priors of ``default_priors`` (same classes and
        transforms) to build a joint prior.
        """
        names = self.names(n_outputs)
        pri = tuple(SIGMA_PRIOR if nm.startswith("sigma") else COEF_PRIOR for nm in names)
        trs = tuple("log" if nm.startswith("sigma") else "tanh" for nm in names)
        return PriorSet(names, pri, trs)

    # helpers shared by the subclasses ------------------------------------------------
    def _loglik_by_terms(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        """``loglik`` as the sum of ``pointwise``: ``R`` of shape (N, n_out, nb), the
        likelihood's layout; returns (nb,).  For a model without a faster total."""
        return self.pointwise(np.moveaxis(np.asarray(R, dtype=float), -1, 0),
                              params).sum(axis=(1, 2))

    def _params(self, params: np.ndarray, n_outputs: int) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        k = self.n_params(n_outputs)
        if params.ndim != 2 or params.shape[1] != k:
            raise DataError(
                f"{self.name} noise needs parameter rows of length {k} "
                f"{self.names(n_outputs)}, got shape {params.shape}")
        return params


def _sigma_ok(sigma: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(sigma) & (sigma > 0), axis=-1)


@dataclass(frozen=True)
class WhiteNoise(NoiseModel):
    """Independent ``N(0, sigma_j^2)`` residuals per output; parameters ``sigma_1..n``.

    Examples
    --------
    >>> r = np.zeros((1, 4, 2))
    >>> float(WhiteNoise().pointwise(r, np.ones((1, 2))).sum()) == -8 * HALF_LOG_2PI
    True
    """

    name: str = "white"

    def names(self, n_outputs: int) -> tuple[str, ...]:
        return tuple(f"sigma_{j + 1}" for j in range(n_outputs))

    def valid(self, params: np.ndarray) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        return _sigma_ok(params)

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        R = np.asarray(R, dtype=float)
        params = self._params(params, R.shape[1])
        ok = self.valid(params)
        s = np.where(ok[None, :], params.T, 1.0)  # (n_out, nb)
        ss = np.einsum("kjb,kjb->jb", R, R)
        t = -R.shape[0] * (HALF_LOG_2PI + np.log(s)) - 0.5 * ss / s**2
        return np.where(ok, t.sum(axis=0), -np.inf)

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        params = self._params(params, r.shape[2])
        ok = self.valid(params)
        out = white_terms(r, np.where(ok[:, None], params, 1.0))
        out[~ok] = -np.inf
        return out

    def start(self, r: np.ndarray) -> np.ndarray:
        r = check_residual(r)
        return np.sqrt(np.mean(r**2, axis=0))

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        return simulate_noise(params, None, int(n_samples), rng)


@dataclass(frozen=True)
class AR1Noise(NoiseModel):
    """Stationary AR(1) residuals per output; parameters ``sigma_1..n, phi_1..n``.

    ``sigma_j`` is the innovation standard deviation, ``|phi_j| < 1`` the lag-1
    coefficient; the density is the exact stationary one (see ``ar1_terms``).
    """

    name: str = "ar1"

    def names(self, n_outputs: int) -> tuple[str, ...]:
        return (tuple(f"sigma_{j + 1}" for j in range(n_outputs))
                + tuple(f"phi_{j + 1}" for j in range(n_outputs)))

    def valid(self, params: np.ndarray) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 2
        phi = params[:, n:]
        return _sigma_ok(params[:, :n]) & np.all(np.isfinite(phi) & (np.abs(phi) < 1), axis=-1)

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        R = np.asarray(R, dtype=float)
        n_out = R.shape[1]
        params = self._params(params, n_out)
        ok = self.valid(params)
        safe = np.where(ok[:, None], params, np.r_[np.ones(n_out), np.zeros(n_out)])
        ll = residual_loglik(R, safe[:, :n_out], safe[:, n_out:])
        return np.where(ok, ll, -np.inf)

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        n_out = r.shape[2]
        params = self._params(params, n_out)
        ok = self.valid(params)
        safe = np.where(ok[:, None], params, np.r_[np.ones(n_out), np.zeros(n_out)])
        out = ar1_terms(r, safe[:, :n_out], safe[:, n_out:])
        out[~ok] = -np.inf
        return out

    def start(self, r: np.ndarray) -> np.ndarray:
        r = check_residual(r)
        phi = np.sum(r[1:] * r[:-1], axis=0) / np.sum(r[:-1] ** 2, axis=0)
        phi = np.clip(phi, -0.9999, 0.9999)
        sigma = np.sqrt(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0))
        return np.r_[sigma, phi]

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 2
        return simulate_noise(params[:, :n], params[:, n:], int(n_samples), rng)
