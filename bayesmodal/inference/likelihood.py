"""Gaussian likelihoods of measured cart positions, batched over parameter sets.

The residual of output ``j`` of experiment ``e`` is ``r_k = y_k - yhat_k(theta)`` with
``yhat`` the exact ZOH simulation from rest.  Two noise models, independent per output:

``"white"``
    ``r_k ~ N(0, sigma^2)`` independently.

``"ar1"`` (default)
    ``r_k = phi r_{k-1} + e_k`` with innovations ``e_k ~ N(0, sigma^2)`` and a stationary
    start, written in the exact innovations (prediction-error) form

        log p(r) = log N(r_0; 0, sigma^2 / (1 - phi^2))
                   + sum_{k>=1} log N(r_k - phi r_{k-1}; 0, sigma^2),

    which is the exact Gaussian log density of a stationary AR(1) record (no conditioning
    on the first sample is dropped).  Residuals of the rig are strongly autocorrelated
    (lag-1 correlation about 0.998 with the linear model), so the white model counts
    every sample as new information and is overconfident.

The pointwise terms (one per sample and output; for AR(1) the first stationary term and
then the conditional innovation terms) sum exactly to the total log-likelihood.  They are
what PSIS-LOO and WAIC use; for autocorrelated records leave-one-sample-out is only an
approximation of predictive performance (see docs/inference.md).

Impossible parameter sets (non-positive masses or g_v, negative damping, ``sigma <= 0``,
``|phi| >= 1``, non-finite values, or a simulation that is not finite) get ``-inf``; they
are never simulated and never raise, so an MCMC walker that strays there is simply
rejected.

Model extensions: with ``extension`` (a name in ``bayesmodal.model.effects.EXTENSIONS`` or an
``Extension``) the model output is ``Extension.simulate`` of the free-damping model plus
the extension's parameters (e.g. Coulomb friction), for all parameter sets of a batch in
one call; the parameter vector is ``extension.names(rig)`` followed by the noise
parameters, and parameter sets the extension rejects (``Extension.valid``, e.g.
``Fs_i < Fc_i``) get ``-inf`` like any other impossible set.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..fit.linear import check_records
from ..model._resid_kernels import ar1_sums
from ..model.effects import resolve_extension
from ..model.simulate import LinearSimulator, simulate_linear
from ..model.system import LinearModel
from .noise_spec import NOISE_MODELS
from .priors import noise_names

__all__ = [
    "Likelihood",
    "NOISE_MODELS",
    "white_terms",
    "ar1_terms",
    "simulate_noise",
    "residual_loglik",
    "loglik_from_sums",
]


_HALF_LOG_2PI = 0.5 * float(np.log(2 * np.pi))


def white_terms(r: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Pointwise log densities of independent Gaussian residuals.

    Parameters
    ----------
    r : ndarray, shape (nb, N, n_out), m
    sigma : ndarray, shape (nb, n_out), m

    Returns
    -------
    ndarray, shape (nb, N, n_out)
    """
    s = sigma[:, None, :]
    return -_HALF_LOG_2PI - np.log(s) - 0.5 * (r / s) ** 2


def ar1_terms(r: np.ndarray, sigma: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Pointwise log densities of a stationary AR(1) residual in innovations form.

    Parameters
    ----------
    r : ndarray, shape (nb, N, n_out), m
    sigma : ndarray, shape (nb, n_out)
        Innovation standard deviation, m.
    phi : ndarray, shape (nb, n_out)
        Lag-1 coefficient, ``|phi| < 1``.

    Returns
    -------
    ndarray, shape (nb, N, n_out)
        Element 0 is ``log N(r_0; 0, sigma^2/(1-phi^2))``, element k >= 1 is
        ``log N(r_k - phi r_{k-1}; 0, sigma^2)``.

    Examples
    --------
    With ``phi = 0`` the terms are the white-noise terms:

    >>> r = np.random.default_rng(0).normal(size=(1, 5, 2))
    >>> s = np.ones((1, 2))
    >>> bool(np.allclose(ar1_terms(r, s, 0 * s), white_terms(r, s)))
    True
    """
    s = sigma[:, None, :]
    p = phi[:, None, :]
    out = np.empty_like(r)
    e = r[:, 1:, :] - p * r[:, :-1, :]
    out[:, 1:, :] = -_HALF_LOG_2PI - np.log(s) - 0.5 * (e / s) ** 2
    one_m_p2 = 1.0 - phi**2
    out[:, 0, :] = (
        -_HALF_LOG_2PI - np.log(sigma) + 0.5 * np.log(one_m_p2)
        - 0.5 * r[:, 0, :] ** 2 * one_m_p2 / sigma**2
    )
    return out


def residual_loglik(R: np.ndarray, sigma: np.ndarray, phi: np.ndarray | None) -> np.ndarray:
    """Total log density of residual records under white or AR(1) noise, batched.

    Computed from sufficient statistics: with ``S00 = sum_{k>=1} r_k^2``,
    ``S01 = sum_{k>=1} r_k r_{k-1}`` and ``S11 = sum_{k<=N-2} r_k^2``, the innovation sum
    of squares is ``S00 - 2 phi S01 + phi^2 S11``.  The cancellation costs about three of
    sixteen digits (the innovations are some 20 times smaller than the residuals), far
    below what matters for the log-likelihood, and the three sums run over the
    simulator's batch-innermost memory layout, which makes this several times faster
    than summing :func:`ar1_terms`.

    Parameters
    ----------
    R : ndarray, shape (N, n_out, nb)
        Residuals ``y - yhat``, m (batch innermost).
    sigma : ndarray, shape (nb, n_out)
        (Innovation) standard deviations, m.
    phi : ndarray, shape (nb, n_out), or None for white noise

    Returns
    -------
    ndarray, shape (nb,)
        Equal to the sum over samples and outputs of :func:`white_terms` or
        :func:`ar1_terms`.
    """
    # the sums of ``_resid_kernels.ar1_sums``, here from an array of residuals
    s00 = np.einsum("kjb,kjb->jb", R[1:], R[1:])
    s01 = np.einsum("kjb,kjb->jb", R[1:], R[:-1])
    return loglik_from_sums(s00, s01, R[0], R[-1], R.shape[0], sigma, phi)


def loglik_from_sums(s00, s01, r0, rl, n: int, sigma: np.ndarray,
                     phi: np.ndarray | None) -> np.ndarray:
    """:func:`residual_loglik` from the residual sums of ``_resid_kernels.ar1_sums``.

    Parameters
    ----------
    s00, s01, r0, rl : ndarray, shape (n_out, nb)
    n : int
        Record length.
    sigma, phi : ndarray, shape (nb, n_out) (phi None for white noise)

    Returns
    -------
    ndarray, shape (nb,)
    """
    s = sigma.T
    if phi is None:
        t = -n * (_HALF_LOG_2PI + np.log(s)) - 0.5 * (s00 + r0**2) / s**2
    else:
        p = phi.T
        s11 = s00 - rl**2 + r0**2
        ss = s00 - 2 * p * s01 + p**2 * s11
        one_m_p2 = 1.0 - p**2
        t = (-n * (_HALF_LOG_2PI + np.log(s)) + 0.5 * np.log(one_m_p2)
             - 0.5 * r0**2 * one_m_p2 / s**2 - 0.5 * ss / s**2)
    return t.sum(axis=0)


def simulate_noise(
    sigma: np.ndarray, phi: np.ndarray | None, n_samples: int, rng=None, start=None
) -> np.ndarray:
    """Draw residual records from the noise model (stationary start, or a given one).

    Parameters
    ----------
    sigma : ndarray, shape (nb, n_out)
        (Innovation) standard deviations, m.
    phi : ndarray, shape (nb, n_out), or None for white noise
    n_samples : int
    rng : numpy.random.Generator or int, optional
    start : array_like, shape (nb, n_out) or (n_out,), optional
        AR(1) only: the residual at sample 0, known (a record that starts at rest, where
        the model and the rig agree, has 0).  The draws are then the AR(1) process
        conditioned on it: mean ``phi^k r_0``, variance ``sigma^2 (1 - phi^(2k)) / (1 -
        phi^2)``, finite for ``phi`` at 1 (a random walk, ``k sigma^2``), where the
        stationary start's spread ``sigma / sqrt(1 - phi^2)`` is unbounded.

    Returns
    -------
    ndarray, shape (nb, n_samples, n_out), m
    """
    rng = np.random.default_rng(rng)
    sigma = np.asarray(sigma, dtype=float)
    e = rng.standard_normal((sigma.shape[0], n_samples, sigma.shape[1])) * sigma[:, None, :]
    if phi is None:
        if start is not None:
            raise DataError("a known start is for AR(1) noise (white noise has no memory)")
        return e
    phi = np.asarray(phi, dtype=float)
    out = np.empty_like(e)
    if start is None:
        out[:, 0] = e[:, 0] / np.sqrt(1.0 - phi**2)
    else:
        out[:, 0] = np.broadcast_to(np.asarray(start, dtype=float), out[:, 0].shape)
    for k in range(1, n_samples):
        out[:, k] = phi * out[:, k - 1] + e[:, k]
    return out


class SimulatorCache:
    """Simulators (``LinearSimulator``) kept between likelihood calls, one per thread and key.

    A simulator reuses its output buffer, so a sampler's thousands of calls do not
    allocate and page in a fresh (N, n_out, nb) array each time; the buffer is
    overwritten by the next call, hence one set per thread.  Pickling drops the buffers
    (a process pool rebuilds them on first use).
    """

    def __init__(self) -> None:
        self._by_thread: dict = {}

    def get(self, key, u: np.ndarray, dt: float, n_out: int) -> LinearSimulator:
        sims = self._by_thread.setdefault(threading.get_ident(), {})
        sim = sims.get(key)
        if sim is None:
            sim = sims[key] = LinearSimulator(u, dt, n_out)
        return sim

    def __getstate__(self) -> dict:
        return {}

    def __setstate__(self, state: dict) -> None:
        self._by_thread = {}


def prepare_linear(model: LinearModel, theta: np.ndarray, sim: LinearSimulator) -> tuple:
    """The modal form of admissible linear-model parameter rows ``theta`` (nb, n_params)
    for ``sim.run_prepared`` (what ``simulate_linear`` computes before its recursion)."""
    M, C, K, b = model.matrices(theta)
    return sim.prepare_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)


def fast_path(model: LinearModel) -> bool:
    """True when the model's outputs are the simulator's leading states (chain rigs), so
    that the likelihood can read the simulator's buffer directly."""
    return getattr(model, "output_index", None) is None


@dataclass(frozen=True, eq=False)
class Likelihood:
    """Log-likelihood of one or several experiments under the linear rig model.

    Parameters
    ----------
    model : LinearModel
    experiments : sequence of Experiment
        All with ``model.n_carts`` outputs; they share the mechanical and noise parameters.
    noise : {"ar1", "white"}
    extension : str or Extension, optional
        A model extension (name in ``bayesmodal.model.effects.EXTENSIONS`` or an instance);
        requires ``model`` with free damping.  None (default) is the linear model.
    initial_state : {"rest", "estimate"}
        ``"rest"`` (default): every record starts at rest.  ``"estimate"``: the initial
        positions and velocities of each record are parameters (free decays), named in
        ``initial_state_names`` and placed at the end of ``mech_names``.

    Attributes
    ----------
    names : tuple of str
        ``mech_names`` followed by ``sigma_1..n`` (and ``phi_1..n`` for AR(1)).
    mech_names : tuple of str
        The model parameters: ``model.names``, or ``extension.names(model.rig)`` (the
        linear free-damping names, then the extension's).

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> t = np.arange(400) * 0.005
    >>> v = 3.0 * (t < 0.05)
    >>> theta = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])
    >>> e = Experiment(t, v, simulate_linear(model, theta, v, 0.005))
    >>> lik = Likelihood(model, [e], noise="white")
    >>> full = np.r_[theta, 1e-4, 1e-4, 1e-4]
    >>> lik(full[None]).shape
    (1,)
    >>> float(lik(np.r_[theta[:1], -1.0, theta[2:], 1e-4, 1e-4, 1e-4][None])[0])
    -inf
    """

    model: LinearModel
    experiments: tuple[Experiment, ...]
    noise: str = "ar1"
    extension: object = None
    initial_state: str = "rest"

    def __post_init__(self) -> None:
        if isinstance(self.experiments, Experiment):
            exps = (self.experiments,)
        else:
            exps = tuple(self.experiments)
        if not exps:
            raise DataError("no experiments given")
        for e in exps:
            if e.n_outputs != self.model.n_outputs:
                raise DataError(
                    f"{e.name}: {e.n_outputs} outputs but the model has "
                    f"{self.model.n_outputs} {'carts' if self.model.rig.is_chain else 'sensors'}"
                )
        if self.noise not in NOISE_MODELS:
            raise ConfigError(f"noise must be one of {NOISE_MODELS}, got {self.noise!r}")
        if self.initial_state != "rest":
            check_records(self.model, exps, self.initial_state)
            if self.extension is not None:
                raise ModelError("initial_state='estimate' works with the linear model only; "
                                 "drop the extension or use records that start at rest")
        object.__setattr__(self, "experiments", exps)
        object.__setattr__(self, "extension", resolve_extension(self.extension, self.model))
        object.__setattr__(self, "_sims", SimulatorCache())

    # ---------------------------------------------------------------- layout
    @property
    def n_outputs(self) -> int:
        return self.model.n_outputs

    @property
    def initial_state_names(self) -> tuple[str, ...]:
        """Initial positions ``x<i>_0`` (m) and velocities ``v<i>_0`` (m/s) per record.

        Empty unless ``initial_state="estimate"``; with several records each name ends in
        ``_e<j>`` (1-based record number).
        """
        if self.initial_state == "rest":
            return ()
        rig = self.model.rig
        carts = [rig.cart_index(c) for c in rig.free_carts]
        states = [f"x{i}_0" for i in carts] + [f"v{i}_0" for i in carts]
        if len(self.experiments) == 1:
            return tuple(states)
        return tuple(f"{s}_e{j + 1}" for j in range(len(self.experiments)) for s in states)

    @property
    def mech_names(self) -> tuple[str, ...]:
        """Model parameter names (linear, then the extension's or the initial states)."""
        if self.extension is None:
            return self.model.names + self.initial_state_names
        return self.extension.names(self.model.rig)

    @property
    def n_mech(self) -> int:
        """Number of model parameters (linear plus extension)."""
        return len(self.mech_names)

    @property
    def extension_name(self) -> str | None:
        """Name of the extension, or None for the linear model."""
        return None if self.extension is None else self.extension.name

    @property
    def names(self) -> tuple[str, ...]:
        return self.mech_names + noise_names(self.n_outputs, self.noise)

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def n_data(self) -> int:
        """Number of scalar observations (samples times outputs over all experiments)."""
        return sum(e.n_samples * e.n_outputs for e in self.experiments)

    def split(self, theta: np.ndarray):
        """Split full vectors, shape (nb, P), into mechanical, sigma and phi (or None)."""
        theta = np.asarray(theta, dtype=float)
        p = self.n_mech
        n = self.n_outputs
        mech = theta[:, :p]
        sigma = theta[:, p : p + n]
        phi = theta[:, p + n : p + 2 * n] if self.noise == "ar1" else None
        return mech, sigma, phi

    def admissible(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (nb,), of parameter sets with a finite likelihood possible."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[-1] != self.n_params:
            raise ConfigError(
                f"parameter vectors must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}"
            )
        mech, sigma, phi = self.split(theta)
        ok = np.all(np.isfinite(theta), axis=-1)
        if self.extension is None:
            ok &= self.model.valid(mech[:, : self.model.n_params])
        else:
            with np.errstate(invalid="ignore"):
                ok &= self.extension.valid(self.model.rig, mech)
        ok &= np.all(sigma > 0, axis=-1)
        if phi is not None:
            ok &= np.all(np.abs(phi) < 1, axis=-1)
        return ok

    # ---------------------------------------------------------------- evaluation
    def predict(self, theta_mech: np.ndarray) -> list[np.ndarray]:
        """Noise-free model outputs per experiment, each shape (nb, N_e, n_out), m.

        ``theta_mech`` must be admissible (shape (nb, n_mech)).  With an extension every
        parameter set of the batch goes through one ``Extension.simulate`` call per
        experiment.
        """
        theta_mech = np.atleast_2d(theta_mech)
        if self.extension is not None:
            rig = self.model.rig
            return [self.extension.simulate(rig, theta_mech, e.v_volt, e.dt)
                    for e in self.experiments]
        if self.initial_state != "rest":
            p = self.model.n_params
            x0 = theta_mech[:, p:].reshape(len(theta_mech), len(self.experiments), -1)
            return [simulate_linear(self.model, theta_mech[:, :p], e.v_volt, e.dt, x0[:, j])
                    for j, e in enumerate(self.experiments)]
        return [
            simulate_linear(self.model, theta_mech, e.v_volt, e.dt) for e in self.experiments
        ]

    def _terms(self, r: np.ndarray, sigma: np.ndarray, phi) -> np.ndarray:
        if phi is None:
            return white_terms(r, sigma)
        return ar1_terms(r, sigma, phi)

    def pointwise(self, theta: np.ndarray) -> list[np.ndarray]:
        """Pointwise log-likelihood terms per experiment.

        Parameters
        ----------
        theta : ndarray, shape (nb, P)

        Returns
        -------
        list of ndarray, each shape (nb, N_e, n_out)
            ``-inf`` everywhere for impossible rows.
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        ok = self.admissible(theta)
        out = [np.full((theta.shape[0], e.n_samples, e.n_outputs), -np.inf)
               for e in self.experiments]
        if not np.any(ok):
            return out
        mech, sigma, phi = self.split(theta[ok])
        for o, e, yh in zip(out, self.experiments, self.predict(mech), strict=True):
            with np.errstate(all="ignore"):
                t = self._terms(e.y_m[None] - yh, sigma, phi)
            o[ok] = np.where(np.isfinite(t), t, -np.inf)
        return out

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Total log-likelihood, shape (nb,), for parameter vectors of shape (nb, P).

        Equal to the sum of :meth:`pointwise`, computed from sufficient statistics
        (:func:`residual_loglik`).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        ok = self.admissible(theta)
        total = np.full(theta.shape[0], -np.inf)
        if not np.any(ok):
            return total
        mech, sigma, phi = self.split(theta[ok])
        nb = int(ok.sum())
        acc = np.zeros(nb)
        with np.errstate(all="ignore"):
            if self.extension is None and self.initial_state == "rest" and fast_path(
                    self.model):
                # one modal form per sample interval, and the residual sums accumulated
                # inside the simulator's recursion (the prediction is never stored): the
                # same numbers as ``predict`` + ``ar1_sums``, bit for bit
                prep = {}
                for i, e in enumerate(self.experiments):
                    sim = self._sims.get(i, e.v_volt, e.dt, self.model.n_carts)
                    if e.dt not in prep:
                        prep[e.dt] = prepare_linear(self.model, mech, sim)
                    acc += loglik_from_sums(*sim.residual_sums(prep[e.dt], e.y_m),
                                            e.n_samples, sigma, phi)
            else:
                for e, yh in zip(self.experiments, self.predict(mech), strict=True):
                    acc += loglik_from_sums(*ar1_sums(e.y_m, yh), e.n_samples, sigma, phi)
        total[ok] = np.where(np.isfinite(acc), acc, -np.inf)
        return total

    def residual_noise_start(self, theta_mech: np.ndarray) -> np.ndarray:
        """Moment estimates of the noise parameters at a mechanical estimate.

        Parameters
        ----------
        theta_mech : ndarray, shape (n_mech,)

        Returns
        -------
        ndarray, shape (n_noise,)
            ``sigma`` (RMS residual for white noise; RMS innovation for AR(1)) followed by
            the lag-1 autocorrelation ``phi`` for AR(1).
        """
        r = np.concatenate(
            [e.y_m - yh[0] for e, yh in zip(self.experiments,
                                             self.predict(theta_mech[None]), strict=True)]
        )
        return noise_moments(r, self.noise)


def noise_moments(r: np.ndarray, noise: str) -> np.ndarray:
    """Moment estimates of white or AR(1) noise parameters from residuals ``r`` (N, n_out).

    Returns ``sigma`` (RMS residual for white noise; RMS innovation for AR(1)) followed,
    for AR(1), by the lag-1 autocorrelation ``phi`` (clipped inside (-1, 1)).
    """
    if noise == "white":
        return np.sqrt(np.mean(r**2, axis=0))
    phi = np.sum(r[1:] * r[:-1], axis=0) / np.sum(r[:-1] ** 2, axis=0)
    phi = np.clip(phi, -0.9999, 0.9999)
    sigma = np.sqrt(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0))
    return np.r_[sigma, phi]


def as_experiments(experiments: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    """Normalise one experiment or a sequence to a tuple."""
    if isinstance(experiments, Experiment):
        return (experiments,)
    return tuple(experiments)
