"""The likelihood of measured records under the rig model, batched over parameter sets.

One class, :class:`Likelihood`, for one record or several.  The residual of output ``j``
of record ``r`` is ``y_k - yhat_k(theta_r)`` with ``yhat`` the exact ZOH simulation (from
rest, or from estimated initial states for free decays); its noise model is white or
AR(1) (the closed forms of :mod:`.noise_terms`, default AR(1): the rig's residuals have
lag-1 correlation about 0.998, so the white model counts every sample as new information
and is overconfident) or, with a record layout, any model of :mod:`.noise` (AR(p),
integrated AR(1), process noise through the dynamics...).

Which parameters a record has is its *layout*:

``layout=None`` (default)
    One parameter set for every record: the model parameters, then ``sigma_1..n`` (and
    ``phi_1..n`` for AR(1)).  White or AR(1) noise; free decays may estimate their
    initial states (``initial_state="estimate"``).
a :class:`~.record_layout.RecordLayout`
    Per-record, shared or hierarchical parameters (``g_v[r]``, ``v0``, ``mu_g_v``...),
    noise per record and noise levels scaled by each record's size
    (:mod:`bayesmodal.inference.records`).  ``RecordLayout({})`` shares every parameter
    like ``None``: the same names and values; a run built with a layout keeps it in its
    configuration and rebuilds its start and new-record predictions per record.

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
one call; the model parameters are ``extension.names(rig)``, and parameter sets the
extension rejects (``Extension.valid``, e.g. ``Fs_i < Fc_i``) get ``-inf`` like any other
impossible set.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..fit.linear import check_records
from ..model._resid_kernels import ar1_sums, ar1_sums_affine
from ..model.effects import resolve_extension
from ..model.simulate import simulate_linear
from ..model.system import LinearModel
from .linear_path import SimulatorCache, fast_path, linear_record_loglik
from .noise import kalman_loglik, kalman_pointwise
from .noise_choice import resolve_noise
from .noise_spec import NOISE_MODELS
from .noise_terms import (
    ar1_terms,
    level_column,
    loglik_from_sums,
    noise_moments,
    residual_loglik,
    simulate_noise,
    white_terms,
)
from .record_layout import RecordLayout, model_layout, parameter_index, record_key
from .record_mapping import RecordMapping
from .record_priors import noise_start
from .record_scale import RecordScales, record_scales

__all__ = [
    "Likelihood",
    "NOISE_MODELS",
    "white_terms",
    "ar1_terms",
    "simulate_noise",
    "residual_loglik",
    "loglik_from_sums",
]

#: Every parameter shared by the records: the parameter vector of ``layout=None``.
ALL_SHARED = RecordLayout({})


@dataclass(frozen=True, eq=False)
class Likelihood(RecordMapping):
    """Log-likelihood of one or several records of one rig.

    Parameters
    ----------
    model : LinearModel
    experiments : sequence of Experiment
        All with ``model.n_outputs`` outputs.
    noise : str or NoiseModel
        ``"ar1"`` (default) or ``"white"``; with a ``layout`` any noise model of
        ``bayesmodal.inference.noise`` (by name, ``noise_choice.resolve_noise``).
    extension : str or Extension, optional
        A model extension (name in ``bayesmodal.model.effects.EXTENSIONS`` or an instance);
        requires ``model`` with free damping.  None (default) is the linear model.
    layout : RecordLayout, optional
        Per-record parameters (:mod:`.record_layout`).  None (default): one parameter set
        for every record.
    scale_at : array_like, shape (n_mech,), or RecordScales, optional
        With ``layout.noise_scale`` other than ``"none"``: the model parameters at which
        each record's response size is simulated (:mod:`.record_scale`).
    initial_state : {"rest", "estimate"}
        ``"rest"`` (default): every record starts at rest.  ``"estimate"`` (no layout, the
        linear model): the initial positions and velocities of each record are parameters
        (free decays), named in ``initial_state_names`` and placed at the end of
        ``mech_names``.

    Attributes
    ----------
    names : tuple of str
        The parameter vector: ``mech_names`` followed by ``sigma_1..n`` (and ``phi_1..n``
        for AR(1)) without a layout; see :mod:`.record_layout` with one.
    mech_names : tuple of str
        The model parameters of one record: ``model.names`` (and the initial states), or
        ``extension.names(model.rig)`` (the linear free-damping names, then the
        extension's).
    record_keys : tuple of str
        Record names as they appear in per-record parameter names, ``p[key]``.

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
    layout: RecordLayout | None = None
    scale_at: object = None
    initial_state: str = "rest"

    def __post_init__(self) -> None:
        if isinstance(self.layout, str):
            raise ConfigError(f"layout must be a RecordLayout or None, got {self.layout!r}; "
                              "pass initial_state by keyword")
        exps = as_experiments(self.experiments)
        if not exps:
            raise DataError("no experiments given")
        for e in exps:
            self.model.check_record(e)
        if self.layout is None and self.noise not in NOISE_MODELS:
            raise ConfigError(
                f"noise must be one of {NOISE_MODELS}, got {self.noise!r}; other noise "
                "models need a record layout (RecordLayout({}) shares every parameter)")
        noise_model = resolve_noise(self.noise, self.model.n_outputs)
        if self.initial_state != "rest":
            if self.layout is not None:
                raise ConfigError("estimated initial states (free decays) are built for one "
                                  "parameter set of all records; drop the record layout")
            check_records(self.model, exps, self.initial_state)
            if self.extension is not None:
                raise ModelError("initial_state='estimate' works with the linear model only; "
                                 "drop the extension or use records that start at rest")
        ext = resolve_extension(self.extension, self.model)
        object.__setattr__(self, "experiments", exps)
        object.__setattr__(self, "extension", ext)
        keys = tuple(record_key(e.name) for e in exps)
        if self.layout is not None and len(set(keys)) != len(keys):
            raise DataError(
                f"record names must be distinct to name per-record parameters, got "
                f"{[e.name for e in exps]}; give each Experiment its own name")
        mech = (self.model.names + self.initial_state_names if ext is None
                else ext.names(self.model.rig))
        layout = None if self.layout is None else model_layout(self.layout, mech, ext)
        plan = ALL_SHARED if layout is None else layout
        _check_process(noise_model, ext, plan)
        object.__setattr__(self, "layout", layout)
        object.__setattr__(self, "noise_model", noise_model)
        # each record's noise model (a model may read a covariate from its record)
        object.__setattr__(self, "record_noise", tuple(noise_model.for_record(e)
                                                       for e in exps))
        object.__setattr__(self, "noise", self.noise if isinstance(self.noise, str) and
                           self.noise in NOISE_MODELS else noise_model.name)
        object.__setattr__(self, "record_keys", keys)
        object.__setattr__(self, "_index", parameter_index(
            plan, mech, keys, noise_model.names(self.model.n_outputs)))
        object.__setattr__(self, "_sims", SimulatorCache())
        scales = None
        if plan.noise_scale != "none" and self.scale_at is not None:
            given = self.scale_at
            ref = given.reference_m if isinstance(given, RecordScales) else None
            at = given.at if isinstance(given, RecordScales) else given
            scales = record_scales(self._response, at, exps, len(mech), ref)
        object.__setattr__(self, "record_scales", scales)

    # ---------------------------------------------------------------- layout
    @property
    def parameter_layout(self) -> RecordLayout:
        """The layout of the parameter vector: ``layout``, or every parameter shared."""
        return ALL_SHARED if self.layout is None else self.layout

    @property
    def names(self) -> tuple[str, ...]:
        return self._index["names"]

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def n_outputs(self) -> int:
        return self.model.n_outputs

    @property
    def n_records(self) -> int:
        return len(self.experiments)

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
        """The model parameters of one record (linear, then the extension's or the initial
        states)."""
        return self._index["mech"]

    @property
    def n_mech(self) -> int:
        """Number of model parameters of one record (linear plus extension)."""
        return len(self.mech_names)

    @property
    def extension_name(self) -> str | None:
        """Name of the extension, or None for the linear model."""
        return None if self.extension is None else self.extension.name

    @property
    def n_data(self) -> int:
        """Number of scalar observations (samples times outputs over all records)."""
        return sum(e.n_samples * e.n_outputs for e in self.experiments)

    def admissible(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (nb,), of parameter sets with a finite likelihood possible."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[-1] != self.n_params:
            raise ConfigError(
                f"parameter vectors must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}")
        ok = np.all(np.isfinite(theta), axis=-1)
        n_mech = self.n_mech
        rig = self.model.rig
        plan = self.parameter_layout
        # every record has the same values when nothing is per record
        for r in range(self.n_records if plan.per_record or plan.noise_per_record else 1):
            full = self.record_theta(theta, r)[0]
            if self.extension is None:
                ok &= self.model.valid(full[:, : self.model.n_params])
            else:
                with np.errstate(invalid="ignore"):
                    ok &= self.extension.valid(rig, full[:, :n_mech])
            ok &= self.noise_model.valid(full[:, n_mech:])
        for g in self._index["groups"].values():
            if g["kind"] == "hierarchical":
                ok &= theta[:, g["tau"]] > 0
        return ok

    # ---------------------------------------------------------------- prediction
    def record_mech(self, full: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray | None]:
        """Record ``r``'s model parameters and initial state from its single-record rows.

        Parameters
        ----------
        full : ndarray, shape (nb, n_mech + n_noise) or (nb, n_mech)
        r : int

        Returns
        -------
        mech : ndarray, shape (nb, n_mech) (linear parameters only with estimated initial
            states)
        x0 : ndarray, shape (nb, 2 n_free), or None (from rest)
            Positions m, velocities m/s.
        """
        if not self.initial_state_names:
            return full[:, : self.n_mech], None
        p = self.model.n_params
        x0 = full[:, p : self.n_mech].reshape(len(full), self.n_records, -1)[:, r]
        return full[:, :p], x0

    def predict(self, theta_mech: np.ndarray) -> list[np.ndarray]:
        """Noise-free outputs per record of one parameter set, each (nb, N_r, n_out), m.

        ``theta_mech`` (shape (nb, n_mech)) must be admissible.  With an extension every
        parameter set of the batch goes through one ``Extension.simulate`` call per record.
        """
        theta_mech = np.atleast_2d(theta_mech)
        zero = np.zeros(theta_mech.shape[0])
        out = []
        for r, e in enumerate(self.experiments):
            mech, x0 = self.record_mech(theta_mech, r)
            out.append(self.predict_mech(mech, zero, e, x0))
        return out

    def predict_record(self, theta: np.ndarray, r: int, experiment: Experiment | None = None
                       ) -> np.ndarray:
        """Noise-free outputs of record ``r``'s parameters, shape (nb, N, n_out), m.

        ``experiment`` (default: record ``r``) gives the input; ``theta`` must be
        admissible.
        """
        full, v0 = self.record_theta(theta, r)
        mech, x0 = self.record_mech(full, r)
        return self.predict_mech(mech, v0, experiment or self.experiments[r], x0)

    def predict_mech(self, mech: np.ndarray, v0: np.ndarray, e: Experiment, x0=None
                     ) -> np.ndarray:
        """Outputs of single-record parameter sets with input offsets on one input.

        Parameters
        ----------
        mech : ndarray, shape (nb, n_mech)
        v0 : ndarray, shape (nb,), V
        e : Experiment
            Gives the input ``v`` and ``dt``.
        x0 : ndarray, shape (nb, 2 n_free), optional
            Initial states (positions m, velocities m/s); default rest.

        Returns
        -------
        ndarray, shape (nb, N, n_out), m
        """
        if self.extension is not None:
            return self.extension.simulate(self.model.rig, mech, e.v_volt, e.dt)
        if not np.any(v0):
            return simulate_linear(self.model, mech, e.v_volt, e.dt, x0)
        a, b = self._unit_responses(mech, e)
        g = mech[:, 0]
        return g[:, None, None] * (a + v0[:, None, None] * b)

    def _unit_responses(self, mech: np.ndarray, e: Experiment):
        """Unit-gain responses ``a = S1(v)`` and ``b = S1(1)``, each (nb, N, n_out), m/V.

        The linear model is linear in ``g_v`` and in the input, so a record with gain
        ``g`` and input offset ``v0`` predicts ``g (a + v0 b)``.
        """
        unit = mech.copy()
        unit[:, 0] = 1.0
        return (simulate_linear(self.model, unit, e.v_volt, e.dt),
                simulate_linear(self.model, unit, np.ones(e.n_samples), e.dt))

    def predict_theta(self, theta: np.ndarray) -> list[np.ndarray]:
        """Noise-free outputs of every record, each shape (nb, N_r, n_out), m."""
        return [self.predict_record(theta, r) for r in range(self.n_records)]

    # ---------------------------------------------------------------- evaluation
    def pointwise(self, theta: np.ndarray) -> list[np.ndarray]:
        """Pointwise log-likelihood terms per record.

        Parameters
        ----------
        theta : ndarray, shape (nb, P)

        Returns
        -------
        list of ndarray, each shape (nb, N_r, n_out)
            ``-inf`` everywhere for impossible rows.
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        ok = self.admissible(theta)
        out = [np.full((theta.shape[0], e.n_samples, e.n_outputs), -np.inf)
               for e in self.experiments]
        if not np.any(ok):
            return out
        for r, e in enumerate(self.experiments):
            full, v0 = self.record_theta(theta[ok], r)
            yh = self.predict_record(theta[ok], r)
            with np.errstate(all="ignore"):
                r_ = e.y_m[None] - yh
                s = np.reshape(self._scale_rows(theta[ok], r), (-1, 1, 1))
                if self.noise in NOISE_MODELS:
                    sigma, phi = self.sigma_phi(full[:, self.n_mech:])
                    sigma = sigma * s[:, :, 0]
                    t = white_terms(r_, sigma) if phi is None else ar1_terms(r_, sigma, phi)
                elif self.noise == "process":
                    mech, q, sig = self._process_split(full)
                    t = kalman_pointwise(self.model, mech, q, sig, e.v_volt, e.y_m, e.dt,
                                         v0=v0)
                else:
                    t = self.record_noise[r].pointwise(r_ / s, full[:, self.n_mech:]
                                                       ) - np.log(s)
            out[r][ok] = np.where(np.isfinite(t), t, -np.inf)
        return out

    def record_loglik(self, theta: np.ndarray) -> np.ndarray:
        """Log-likelihood of each record, shape (nb, n_records); ``-inf`` if impossible."""
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        ok = self.admissible(theta)
        out = np.full((theta.shape[0], self.n_records), -np.inf)
        if not np.any(ok):
            return out
        th = theta[ok]
        if (self.extension is None and self.noise in NOISE_MODELS
                and not self.initial_state_names and fast_path(self.model)):
            with np.errstate(all="ignore"):
                ll = linear_record_loglik(self, th)
            out[ok] = np.where(np.isfinite(ll), ll, -np.inf)
            return out
        with np.errstate(all="ignore"):
            for r, e in enumerate(self.experiments):
                full, v0 = self.record_theta(th, r)
                params = full[:, self.n_mech:]
                if self.noise in NOISE_MODELS:
                    ll = self._basic_loglik(r, full, v0, self._scale_rows(th, r))
                elif self.noise == "process":
                    mech, q, sigma = self._process_split(full)
                    ll = kalman_loglik(self.model, mech, q, sigma, e.v_volt, e.y_m, e.dt,
                                       initial="rest", v0=v0)
                else:
                    yh = self.predict_record(th, r)
                    ll = self.noise_loglik(e.y_m[:, :, None] - np.moveaxis(yh, 0, -1), params,
                                           self._scale_rows(th, r), record=r)
                out[ok, r] = np.where(np.isfinite(ll), ll, -np.inf)
        return out

    def _basic_loglik(self, r: int, full, v0, scale=1.0) -> np.ndarray:
        """White or AR(1) log-likelihood of record ``r`` from compiled residual sums (a
        per-record gain and offset applied inside the kernel, no temporaries), the noise
        level times ``scale``."""
        e = self.experiments[r]
        mech, x0 = self.record_mech(full, r)
        if self.extension is not None or not np.any(v0):
            sums = ar1_sums(e.y_m, self.predict_mech(mech, v0, e, x0))
        else:
            a, b = self._unit_responses(mech, e)
            sums = ar1_sums_affine(e.y_m, a, b, mech[:, 0], v0)
        sigma, phi = self.sigma_phi(full[:, self.n_mech:])
        return loglik_from_sums(*sums, e.n_samples, sigma * level_column(scale), phi)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Total log-likelihood over the records, shape (nb,), for parameter vectors of
        shape (nb, P); the sum of :meth:`pointwise`, computed from sufficient statistics
        for white and AR(1) noise."""
        ll = self.record_loglik(theta)
        if self.layout is not None:
            return np.sum(ll, axis=1)
        # a running sum over the records (numpy's sum pairs the terms from 8 records on,
        # which would move the last digit of earlier runs without a layout)
        total = np.zeros(ll.shape[0])
        for r in range(ll.shape[1]):
            total += ll[:, r]
        return total

    def residual_noise_start(self, theta: np.ndarray) -> np.ndarray:
        """Moment estimates of the noise parameters (in ``names`` order of the noise).

        Parameters
        ----------
        theta : ndarray, shape (P,), or (n_mech,) without a layout
            A full parameter vector (its noise entries are not read), or without a layout
            the model parameters alone.

        Returns
        -------
        ndarray, shape (n_noise,)
            Without a layout the moments of all records' residuals together: ``sigma``
            (RMS residual for white noise; RMS innovation for AR(1)) followed by the lag-1
            autocorrelation ``phi`` for AR(1).  With one, :func:`.record_priors.noise_start`
            (each record's moments, pooled unless the noise is per record).
        """
        theta = np.asarray(theta, dtype=float)
        if self.layout is not None:
            return noise_start(self, theta)
        mech = theta[: self.n_mech]
        r = np.concatenate([e.y_m - yh[0] for e, yh in zip(
            self.experiments, self.predict(mech[None]), strict=True)])
        return noise_moments(r, self.noise)


def _check_process(noise_model, extension, layout: RecordLayout) -> None:
    """Process noise is built for the linear model and has no level to scale."""
    if noise_model.name != "process":
        return
    if extension is not None:
        raise ConfigError(
            "process noise is built for the linear model: the Kalman filter's "
            "prediction step is linear (friction, backlash and the other effects "
            "would need an extended filter); use noise 'ar1' or 'arP' with extensions")
    if layout.noise_scale != "none":
        raise ConfigError(
            "process noise has no noise level to scale per record (its random "
            "force goes through the dynamics); use noise_scale = 'none' or noise "
            "'ar1' / 'arP'")


def as_experiments(experiments: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    """Normalise one experiment or a sequence to a tuple."""
    if isinstance(experiments, Experiment):
        return (experiments,)
    return tuple(experiments)
