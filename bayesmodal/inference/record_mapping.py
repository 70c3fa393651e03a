"""How a likelihood's parameter vector maps onto its records.

:class:`RecordMapping` holds the part of :class:`~.likelihood.Likelihood` that reads one
record's values out of the parameter vector (:func:`.record_layout.record_values`), the
populations of hierarchical parameters, each record's noise model, and each record's
noise level (the shared level times the record's size with a ``noise_scale``,
:mod:`.record_scale`).  It has no state of its own: it reads the likelihood's
``_index``, ``layout``, ``noise_model``, ``record_noise`` and ``record_scales``.

For Gaussian noise models scaling the residual's standard deviation by ``s`` is the same
as dividing the residual by ``s`` and adding ``-N n_out log s``: the white and AR(1)
closed forms (:mod:`.noise_terms`) take the first, the other noise models the second.
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ..data import Experiment
from .noise import NoiseModel, simulate_process_noise
from .noise_spec import NOISE_MODELS
from .noise_terms import level_column, residual_loglik, simulate_noise
from .record_layout import population_log_density, record_values
from .record_scale import RecordScales, powered, response_rms

__all__ = ["RecordMapping"]


class RecordMapping:
    """Record values, populations, noise models and noise levels of a likelihood (a base
    of :class:`~.likelihood.Likelihood`, not used on its own)."""

    # ---------------------------------------------------------------- records
    def record_theta(self, theta: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
        """Record ``r``'s single-record parameters and input offset.

        Parameters
        ----------
        theta : ndarray, shape (nb, P)

        Returns
        -------
        full : ndarray, shape (nb, n_mech + n_noise)
            The model parameters of one record (``mech_names``), then its noise
            parameters.
        v0 : ndarray, shape (nb,)
            Input offset, V (zero when not per record).
        """
        return record_values(self._index, theta, r)

    def hierarchical_names(self) -> tuple[str, ...]:
        """The parameters drawn from a population."""
        return tuple(p for p, k in self.parameter_layout.kinds if k == "hierarchical")

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

    def split(self, theta: np.ndarray):
        """Model parameters at the population centre, and the first record's noise.

        Parameters
        ----------
        theta : ndarray, shape (nb, P)

        Returns
        -------
        mech : ndarray, shape (nb, n_mech)
            For code written for one record (modal propagation, which does not depend on
            ``g_v`` or ``v0``): a per-record model parameter is replaced by ``mu_p``
            (hierarchical) or by the geometric mean over records (independent).
        sigma : ndarray, shape (nb, n_out)
        phi : ndarray, shape (nb, n_out), or None (not AR(1) noise)
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        full, _ = self.record_theta(theta, 0)
        mech = full[:, : self.n_mech].copy()
        for p, g in self._index["groups"].items():
            if p == "v0":
                continue
            j = self.mech_names.index(p)
            if g["kind"] == "hierarchical":
                mech[:, j] = theta[:, g["mu"]]
            else:
                mech[:, j] = np.exp(np.mean(np.log(theta[:, g["records"]]), axis=1))
        sigma, phi = self.sigma_phi(full[:, self.n_mech:])
        return mech, sigma, phi

    # ---------------------------------------------------------------- noise models
    def sigma_phi(self, params: np.ndarray):
        """``(sigma, phi)`` of white (phi None) or AR(1) noise from noise parameter rows
        (nb, n_noise)."""
        n = self.n_outputs
        return params[:, :n], (params[:, n : 2 * n] if self.noise == "ar1" else None)

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
            sigma, phi = self.sigma_phi(params)
            return residual_loglik(R, sigma * level_column(scale), phi)
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
        at sample 0, shape (nb, n_out), m (``noise_terms.simulate_noise``)."""
        if self.noise in NOISE_MODELS:
            sigma, phi = self.sigma_phi(params)
            return simulate_noise(sigma * level_column(scale), phi, n_samples, rng, start)
        return np.reshape(scale, (-1, 1, 1)) * self.noise_of(record).simulate(
            params, n_samples, rng)

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
            out.append(self.noise_simulate(full[:, self.n_mech:], e.n_samples, rng,
                                           self._scale_rows(theta, r), record=r))
        return out

    def _process_split(self, full):
        """Model parameters, random-force intensities and measurement noise of process
        noise rows."""
        n_mech = self.n_mech
        n = self.n_outputs
        return full[:, :n_mech], full[:, n_mech : n_mech + n], full[:, n_mech + n :]

    # ---------------------------------------------------------------- noise scale
    def _response(self, mech: np.ndarray, e: Experiment) -> np.ndarray:
        return self.predict_mech(mech, np.zeros(mech.shape[0]), e)

    def _scales(self) -> RecordScales | None:
        """The records' sizes, None without a noise scale; a one-line error when the
        layout asks for them and ``scale_at`` was not given (names and priors need none)."""
        scale = self.parameter_layout.noise_scale
        if scale == "none":
            return None
        if self.record_scales is None:
            raise ConfigError(
                f"noise_scale {scale!r} needs scale_at, the model "
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
