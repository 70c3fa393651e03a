"""Several records, one physical system: shared, per-record and hierarchical parameters.

The records of one rig share its physics (masses, dampers, springs, extension
parameters) but not everything: the drive gain ``g_v`` differs from record to record on
the ECP 210 (about 6.1 N/V on the steps, 5.5 on the impulses, 4.5-5.2 on the sweeps), and
the amplifier has an input offset ``v0`` (V).  A :class:`RecordLayout` says which
parameters are per record and how (``"shared"``, ``"independent"`` or
``"hierarchical"``, drawn from a population), and where each sits in the parameter
vector (:mod:`.record_layout`, whose names stay importable from here).  The priors and
a starting point are in :mod:`.record_priors`, the choice of the noise model in
:mod:`.noise_choice`.

The input offset ``v0`` is not a parameter of the single-record model; declaring it adds
``v0[r]`` to every record (``v = v_measured + v0``).  For the linear model the output is
linear in ``g_v`` and in the input, so with unit-gain simulations ``a = S(v)`` and
``b = S(1)`` the prediction is ``y = g_v (a + v0 b)`` (two simulations per record).

Noise parameters (``sigma_j``, ``phi_j``) are shared by the records unless
``noise_per_record``; a new record is then predicted with the shared noise model (or, per
record, with a training record's noise parameters drawn at random).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError, DataError
from ..data import Experiment
from ..model._resid_kernels import ar1_sums, ar1_sums_affine
from ..model.simulate import simulate_linear
from ..model.system import LinearModel
from .likelihood import (
    Likelihood,
    SimulatorCache,
    ar1_terms,
    fast_path,
    loglik_from_sums,
    prepare_linear,
    residual_loglik,
    simulate_noise,
    white_terms,
)
from .noise import NoiseModel, kalman_loglik, kalman_pointwise, simulate_process_noise
from .noise_choice import choose_noise, resolve_noise
from .noise_spec import NOISE_MODELS
from .record_layout import (
    DEFAULT_LAYOUT,
    PER_RECORD_KINDS,
    RecordLayout,
    model_layout,
    parameter_index,
    parse_layout,
    population_log_density,
    record_key,
    record_values,
)
from .record_priors import TAU_SCALE, noise_start, record_priors, records_start
from .record_scale import RecordScales, powered, record_scales, response_rms

__all__ = [
    "RecordLayout",
    "RecordsLikelihood",
    "record_priors",
    "records_start",
    "parse_layout",
    "resolve_noise",
    "choose_noise",
    "PER_RECORD_KINDS",
    "TAU_SCALE",
    "DEFAULT_LAYOUT",
]


@dataclass(frozen=True, eq=False)
class RecordsLikelihood:
    """Log-likelihood of several records of one rig with per-record parameters.

    Parameters
    ----------
    model : LinearModel
    experiments : sequence of Experiment
        At least one; names must be distinct (they name the per-record parameters).
    noise : {"ar1", "white"}
    extension : str or Extension, optional
        A model extension on the free-damping model.
    layout : RecordLayout
        Per-record parameters (default :data:`DEFAULT_LAYOUT`).
    scale_at : array_like, shape (n_mech,), or RecordScales, optional
        With ``layout.noise_scale`` other than ``"none"``: the model parameters
        (single-record order, ``mech_names``) at which each record's response size is
        simulated, e.g. the least-squares estimate (``sample_posterior`` passes its start).
        Required to evaluate the likelihood then (names and priors need none).
        A ``RecordScales`` (a fitted likelihood's ``record_scales``) also keeps its
        reference size, for the same likelihood on other records.

    Attributes
    ----------
    names : tuple of str
        The parameter vector's names (see :mod:`.record_layout`).
    record_keys : tuple of str
        Record names as they appear in parameter names, ``p[key]``.

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> t = np.arange(200) * 0.005
    >>> exps = [Experiment(t, 3.0 * (t < 0.05), np.zeros((200, 3)), name=n) for n in "ab"]
    >>> lik = RecordsLikelihood(LinearModel(Rig(), "proportional"), exps, "white")
    >>> lik.names[:5]
    ('m1', 'm2', 'm3', 'ca', 'cb')
    >>> lik.names[5:9]
    ('mu_g_v', 'tau_g_v', 'g_v[a]', 'g_v[b]')
    """

    model: LinearModel
    experiments: tuple[Experiment, ...]
    noise: str = "ar1"
    extension: object = None
    layout: RecordLayout = DEFAULT_LAYOUT
    scale_at: object = None

    def __post_init__(self) -> None:
        exps = (self.experiments,) if isinstance(self.experiments, Experiment) else tuple(
            self.experiments)
        # one single-record likelihood per record: it validates outputs, noise, extension
        noise_model = resolve_noise(self.noise, self.model.n_outputs)
        basic = self.noise if self.noise in NOISE_MODELS else "white"
        # one single-record likelihood per record: it validates outputs and the extension
        singles = tuple(Likelihood(self.model, (e,), basic, self.extension) for e in exps)
        if not exps:
            raise DataError("no experiments given")
        keys = tuple(record_key(e.name) for e in exps)
        if len(set(keys)) != len(keys):
            raise DataError(
                f"record names must be distinct to name per-record parameters, got "
                f"{[e.name for e in exps]}; give each Experiment its own name")
        mech = singles[0].mech_names
        ext = singles[0].extension
        layout = model_layout(self.layout, mech, ext)
        if noise_model.name == "process":
            if ext is not None:
                raise ConfigError(
                    "process noise is built for the linear model: the Kalman filter's "
                    "prediction step is linear (friction, backlash and the other effects "
                    "would need an extended filter); use noise 'ar1' or 'arP' with "
                    "extensions")
            if layout.noise_scale != "none":
                raise ConfigError(
                    "process noise has no noise level to scale per record (its random "
                    "force goes through the dynamics); use noise_scale = 'none' or noise "
                    "'ar1' / 'arP'")
        object.__setattr__(self, "experiments", exps)
        object.__setattr__(self, "layout", layout)
        object.__setattr__(self, "extension", ext)
        object.__setattr__(self, "noise_model", noise_model)
        # each record's noise model (a model may read a covariate from its record)
        object.__setattr__(self, "record_noise", tuple(noise_model.for_record(e)
                                                       for e in exps))
        object.__setattr__(self, "noise", self.noise if isinstance(self.noise, str) and
                           self.noise in NOISE_MODELS else noise_model.name)
        object.__setattr__(self, "record_keys", keys)
        object.__setattr__(self, "_index", parameter_index(
            layout, mech, keys, noise_model.names(self.model.n_outputs)))
        object.__setattr__(self, "_sims", SimulatorCache())
        scales = None
        if layout.noise_scale != "none" and self.scale_at is not None:
            given = self.scale_at
            ref = given.reference_m if isinstance(given, RecordScales) else None
            at = given.at if isinstance(given, RecordScales) else given
            scales = record_scales(self._response, at, exps, len(mech), ref)
        object.__setattr__(self, "record_scales", scales)

    # ---------------------------------------------------------------- noise scale
    def _response(self, mech: np.ndarray, e: Experiment) -> np.ndarray:
        return self.predict_mech(mech, np.zeros(mech.shape[0]), e)

    def _scales(self) -> RecordScales | None:
        """The records' sizes, None without a noise scale; a one-line error when the
        layout asks for them and ``scale_at`` was not given (names and priors need none)."""
        if self.layout.noise_scale == "none":
            return None
        if self.record_scales is None:
            raise ConfigError(
                f"noise_scale {self.layout.noise_scale!r} needs scale_at, the model "
                "parameters at which each record's response size is simulated (e.g. a "
                "least-squares estimate's theta); sample_posterior passes its start")
        return self.record_scales

    def scale(self, r: int) -> float:
        """Record ``r``'s relative response size ``s_r`` (1 without a noise scale; with
        ``noise_scale = "power"`` the level's factor is ``s_r ** scale_power``)."""
        rs = self._scales()
        return 1.0 if rs is None else float(rs.scales[r])

    def _power(self, theta: np.ndarray | None) -> np.ndarray | None:
        """The sampled exponent per row, shape (nb,), or None (no ``"power"`` scale)."""
        j = self._index.get("power")
        return None if j is None or theta is None else np.atleast_2d(theta)[:, j]

    def _scale_rows(self, theta: np.ndarray, r: int):
        """Record ``r``'s noise-level factor: a number, or one per row (nb,) with a power."""
        return powered(self.scale(r), self._power(theta))

    def scale_of(self, experiment: Experiment, theta: np.ndarray | None = None):
        """The noise-level factor of another record (a held-out one) from its input: a
        number, or per row of ``theta`` (shape (nb,)) with ``noise_scale = "power"``."""
        rs = self._scales()
        if rs is None:
            return 1.0
        return powered(rs.scale_of(response_rms(self._response, rs.at, experiment)),
                       self._power(theta))

    # ---------------------------------------------------------------- layout
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
    def mech_names(self) -> tuple[str, ...]:
        """The single-record model parameters (linear, then the extension's)."""
        return self._index["mech"]

    @property
    def extension_name(self) -> str | None:
        return None if self.extension is None else self.extension.name

    @property
    def initial_state(self) -> str:
        """Records start at rest (free decays are single-record, ``Likelihood``)."""
        return "rest"

    @property
    def initial_state_names(self) -> tuple[str, ...]:
        """Estimated initial states: none (records start at rest)."""
        return ()

    @property
    def n_data(self) -> int:
        return sum(e.n_samples * e.n_outputs for e in self.experiments)

    def hierarchical_names(self) -> tuple[str, ...]:
        return tuple(p for p, k in self.layout.kinds if k == "hierarchical")

    # ---------------------------------------------------------------- mapping
    def record_theta(self, theta: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
        """Record ``r``'s single-record parameters and input offset.

        Parameters
        ----------
        theta : ndarray, shape (nb, P)

        Returns
        -------
        full : ndarray, shape (nb, n_mech + n_noise)
            In the layout of a single-record :class:`Likelihood` of the same model.
        v0 : ndarray, shape (nb,)
            Input offset, V (zero when not per record).
        """
        return record_values(self._index, theta, r)

    def population(self, theta: np.ndarray, p: str) -> tuple[np.ndarray, np.ndarray] | None:
        """``(mu_p, tau_p)`` of a hierarchical parameter, each shape (nb,), else None."""
        g = self._index["groups"].get(p)
        if g is None or g["kind"] != "hierarchical":
            return None
        theta = np.atleast_2d(theta)
        return theta[:, g["mu"]], theta[:, g["tau"]]

    def log_population(self, theta: np.ndarray) -> np.ndarray:
        """Log density of the per-record values under their populations, shape (nb,).

        The term ``sum_p sum_r log p(p[r] | mu_p, tau_p)`` of the joint prior that a
        product of independent priors cannot express; ``LogPosterior`` adds it.  The
        per-record values' own entries in the :class:`PriorSet` are uniform over the
        parameter's support and only truncate the population.
        """
        return population_log_density(self._index, theta)

    def admissible(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        if theta.shape[-1] != self.n_params:
            raise ConfigError(
                f"parameter vectors must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}")
        ok = np.all(np.isfinite(theta), axis=-1)
        n_mech = len(self.mech_names)
        rig = self.model.rig
        for r in range(self.n_records):
            full = self.record_theta(theta, r)[0]
            if self.extension is None:
                ok &= self.model.valid(full[:, :n_mech])
            else:
                with np.errstate(invalid="ignore"):
                    ok &= self.extension.valid(rig, full[:, :n_mech])
            ok &= self.noise_model.valid(full[:, n_mech:])
        for g in self._index["groups"].values():
            if g["kind"] == "hierarchical":
                ok &= theta[:, g["tau"]] > 0
        return ok

    # ---------------------------------------------------------------- evaluation
    def predict_record(self, theta: np.ndarray, r: int, experiment: Experiment | None = None
                       ) -> np.ndarray:
        """Noise-free outputs of record ``r``'s parameters, shape (nb, N, n_out), m.

        ``experiment`` (default: record ``r``) gives the input; ``theta`` must be
        admissible.
        """
        full, v0 = self.record_theta(theta, r)
        mech = full[:, : len(self.mech_names)]
        return self.predict_mech(mech, v0, experiment or self.experiments[r])

    def predict_mech(self, mech: np.ndarray, v0: np.ndarray, e: Experiment) -> np.ndarray:
        """Outputs of single-record parameter sets with input offsets on one input.

        Parameters
        ----------
        mech : ndarray, shape (nb, n_mech)
        v0 : ndarray, shape (nb,), V
        e : Experiment
            Gives the input ``v`` and ``dt``.

        Returns
        -------
        ndarray, shape (nb, N, n_out), m
        """
        if self.extension is not None:
            return self.extension.simulate(self.model.rig, mech, e.v_volt, e.dt)
        if not np.any(v0):
            return simulate_linear(self.model, mech, e.v_volt, e.dt)
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

    def _sigma_phi(self, params: np.ndarray):
        """``(sigma, phi)`` of white (phi None) or AR(1) noise from noise parameter rows."""
        n = self.n_outputs
        return params[:, :n], (params[:, n : 2 * n] if self.noise == "ar1" else None)

    def _noise(self, full: np.ndarray):
        """``(sigma, phi)`` of white or AR(1) noise from single-record rows."""
        return self._sigma_phi(full[:, len(self.mech_names):])

    def noise_of(self, record) -> NoiseModel:
        """The noise model of a record: ``record`` is the index of one of the likelihood's
        records or another ``Experiment`` (a held-out one)."""
        if isinstance(record, Experiment):
            return self.noise_model.for_record(record)
        return self.record_noise[record]

    def noise_loglik(self, R: np.ndarray, params: np.ndarray, scale: float = 1.0, *,
                     record=0) -> np.ndarray:
        """Log density, shape (nb,), of residuals ``R`` (N, n_out, nb) of ``record`` (see
        :meth:`noise_of`) under the noise model with parameter rows ``params``
        (nb, n_noise), its level times ``scale``."""
        if self.noise in NOISE_MODELS:  # the sufficient-statistics path
            sigma, phi = self._sigma_phi(params)
            return residual_loglik(R, sigma * _col(scale), phi)
        noise = self.noise_of(record)
        if np.all(np.asarray(scale) == 1.0):
            return noise.loglik(R, params)
        return noise.loglik(R / scale, params) - R.shape[0] * R.shape[1] * np.log(scale)

    def noise_simulate(self, params: np.ndarray, n_samples: int, rng, scale: float = 1.0,
                       start=None, *, record=0) -> np.ndarray:
        """Residual draws, shape (nb, n_samples, n_out), of ``record`` (see
        :meth:`noise_of`) from noise parameter rows, times ``scale`` (not for process
        noise, whose draws go through the dynamics: see
        ``predictive.predict_new_record``).  ``start`` (AR(1) only): the known residual
        at sample 0, shape (nb, n_out), m (``likelihood.simulate_noise``)."""
        if self.noise in NOISE_MODELS:
            sigma, phi = self._sigma_phi(params)
            return simulate_noise(sigma * _col(scale), phi, n_samples, rng, start)
        return np.reshape(scale, (-1, 1, 1)) * self.noise_of(record).simulate(
            params, n_samples, rng)

    def pointwise(self, theta: np.ndarray) -> list[np.ndarray]:
        """Pointwise log-likelihood terms per record, each shape (nb, N_r, n_out)."""
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
                    sigma, phi = self._noise(full)
                    sigma = sigma * s[:, :, 0]
                    t = white_terms(r_, sigma) if phi is None else ar1_terms(r_, sigma, phi)
                elif self.noise == "process":
                    mech, q, sig = self._process_split(full)
                    t = kalman_pointwise(self.model, mech, q, sig, e.v_volt, e.y_m, e.dt,
                                         v0=v0)
                else:
                    t = self.record_noise[r].pointwise(r_ / s, full[:, len(self.mech_names):]
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
                and fast_path(self.model)):
            with np.errstate(all="ignore"):
                ll = self._linear_record_loglik(th)
            out[ok] = np.where(np.isfinite(ll), ll, -np.inf)
            return out
        with np.errstate(all="ignore"):
            for r, e in enumerate(self.experiments):
                full, v0 = self.record_theta(th, r)
                params = full[:, len(self.mech_names):]
                if self.noise in NOISE_MODELS:
                    ll = self._basic_loglik(e, full, v0, params, self._scale_rows(th, r))
                elif self.noise == "process":
                    ll = self._process_loglik(e, full, v0)
                else:
                    yh = self.predict_record(th, r)
                    ll = self.noise_loglik(e.y_m[:, :, None] - np.moveaxis(yh, 0, -1), params,
                                           self._scale_rows(th, r), record=r)
                out[ok, r] = np.where(np.isfinite(ll), ll, -np.inf)
        return out

    def _linear_record_loglik(self, th: np.ndarray) -> np.ndarray:
        """White or AR(1) log-likelihood per record, shape (nb, n_records), of the linear
        model, the numbers of :meth:`_basic_loglik` bit for bit, faster: one modal form
        serves every record whose simulated parameter rows are equal (with an input
        offset, the unit-gain rows, equal across records whenever only ``g_v`` and ``v0``
        are per record), and the residual sums of ``g (a + v0 b)`` (or of the plain
        simulation when no offset is sampled) are accumulated inside the recursion, which
        runs the unit-gain responses ``a = S1(v)`` and ``b = S1(1)`` side by side without
        storing either (``LinearSimulator.residual_sums``).
        """
        nb = th.shape[0]
        n_mech = len(self.mech_names)
        out = np.empty((nb, self.n_records))
        prep = rows = None  # the current modal form and the parameter rows it is for
        for r, e in enumerate(self.experiments):
            full, v0 = self.record_theta(th, r)
            mech = full[:, :n_mech]
            affine = bool(np.any(v0))  # as _basic_loglik: the gain inside when v0 = 0
            sim_rows = mech
            if affine:
                sim_rows = mech.copy()
                sim_rows[:, 0] = 1.0
            sim = self._sims.get(r, e.v_volt, e.dt, self.model.n_carts)
            if prep is None or prep[0] != e.dt or not np.array_equal(sim_rows, rows):
                prep, rows = prepare_linear(self.model, sim_rows, sim), sim_rows
            sums = (sim.residual_sums(prep, e.y_m, mech[:, 0], v0) if affine
                    else sim.residual_sums(prep, e.y_m))
            sigma, phi = self._sigma_phi(full[:, n_mech:])
            out[:, r] = loglik_from_sums(*sums, e.n_samples,
                                         sigma * _col(self._scale_rows(th, r)), phi)
        return out

    def _process_split(self, full):
        n_mech = len(self.mech_names)
        n = self.n_outputs
        return full[:, :n_mech], full[:, n_mech : n_mech + n], full[:, n_mech + n :]

    def _process_loglik(self, e: Experiment, full, v0) -> np.ndarray:
        """Kalman-filter innovations likelihood (exact start from rest), input ``v + v0``."""
        mech, q, sigma = self._process_split(full)
        return kalman_loglik(self.model, mech, q, sigma, e.v_volt, e.y_m, e.dt,
                             initial="rest", v0=v0)

    def _basic_loglik(self, e: Experiment, full, v0, params, scale: float = 1.0
                      ) -> np.ndarray:
        """White or AR(1) log-likelihood of one record from compiled residual sums (the
        per-record gain and offset applied inside the kernel, no temporaries), the noise
        level times ``scale``."""
        mech = full[:, : len(self.mech_names)]
        if self.extension is not None or not np.any(v0):
            sums = ar1_sums(e.y_m, self.predict_mech(mech, v0, e))
        else:
            a, b = self._unit_responses(mech, e)
            sums = ar1_sums_affine(e.y_m, a, b, mech[:, 0], v0)
        sigma, phi = self._sigma_phi(params)
        return loglik_from_sums(*sums, e.n_samples, sigma * _col(scale), phi)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """Total log-likelihood over the records, shape (nb,)."""
        return np.sum(self.record_loglik(theta), axis=1)

    # ---------------------------------------------------------------- compatibility
    def split(self, theta: np.ndarray):
        """Mechanical parameters at the population centre, and the first record's noise.

        For code written for one record (modal propagation, which does not depend on
        ``g_v`` or ``v0``): a per-record model parameter is replaced by ``mu_p``
        (hierarchical) or by the geometric mean over records (independent).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        full, _ = self.record_theta(theta, 0)
        mech = full[:, : len(self.mech_names)].copy()
        for p, g in self._index["groups"].items():
            if p == "v0":
                continue
            j = self.mech_names.index(p)
            if g["kind"] == "hierarchical":
                mech[:, j] = theta[:, g["mu"]]
            else:
                mech[:, j] = np.exp(np.mean(np.log(theta[:, g["records"]]), axis=1))
        sigma, phi = self._noise(full)
        return mech, sigma, phi

    def predict_theta(self, theta: np.ndarray) -> list[np.ndarray]:
        """Noise-free outputs of every record, each shape (nb, N_r, n_out), m."""
        return [self.predict_record(theta, r) for r in range(self.n_records)]

    def noise_draws(self, theta: np.ndarray, rng=None) -> list[np.ndarray]:
        """Residual draws from each record's noise model, each shape (nb, N_r, n_out)."""
        rng = np.random.default_rng(rng)
        out = []
        for r, e in enumerate(self.experiments):
            full, v0 = self.record_theta(theta, r)
            if self.noise == "process":  # what the random force adds to the prediction
                mech, q, sig = self._process_split(full)
                y = simulate_process_noise(self.model, mech, q, sig, e.v_volt, e.dt, rng,
                                           v0=v0)
                out.append(y - self.predict_mech(mech, v0, e))
                continue
            out.append(self.noise_simulate(full[:, len(self.mech_names):], e.n_samples, rng,
                                           self._scale_rows(theta, r), record=r))
        return out

    def residual_noise_start(self, theta: np.ndarray) -> np.ndarray:
        """Moment estimates of the noise parameters (in ``names`` order of the noise)."""
        return noise_start(self, theta)


def _col(scale):
    """A noise-level factor as a column: shape (1, 1) for a number, (nb, 1) per row."""
    return np.reshape(np.asarray(scale, dtype=float), (-1, 1))


def as_records(experiments: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    if isinstance(experiments, Experiment):
        return (experiments,)
    return tuple(experiments)
