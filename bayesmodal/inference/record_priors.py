"""Priors and a starting point of the several-record parameter vector.

The vector of a :class:`~.likelihood.Likelihood` (:mod:`.record_layout`) holds
shared parameters, per-record values, population means and spreads and the noise
parameters.  :func:`record_priors` gives each its default prior (the single-record
defaults, a half-normal prior on each population spread); :func:`records_start` a
starting point from a joint single-record estimate, with each record's gain and input
offset fitted in closed form (linear model) or on a grid (extended model) and the noise
parameters estimated from the residuals (:func:`noise_start`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError
from ..model.simulate import simulate_linear
from .noise_spec import NOISE_MODELS
from .noise_terms import noise_moments
from .priors import Normal, PriorSet, Uniform, default_priors
from .record_layout import SIGNED
from .record_scale import POWER_BOUNDS, POWER_NAME, POWER_START

if TYPE_CHECKING:  # the likelihood's type only: it is built on this module
    from .likelihood import Likelihood

__all__ = ["record_priors", "records_start", "noise_start", "TAU_SCALE", "GAIN_GRID"]

#: Scale of the half-normal prior of a population spread ``tau_p``: relative for a
#: log-sampled parameter (0.1 = 10 %), V for the input offset.
TAU_SCALE = {"log": 0.1, "v0": 0.05}

#: Prior of an independent input offset, and of a hierarchical offset's mean, V.
V0_PRIOR = Normal(0.0, 0.1, lo=-1.0, hi=1.0)


def record_priors(lik: Likelihood, overrides: Mapping[str, object] | None = None
                  ) -> PriorSet:
    """Default priors of a :class:`Likelihood`'s parameters.

    Shared parameters and per-record values get the single-record defaults
    (``default_priors``); a population mean ``mu_p`` the default of ``p``; a spread
    ``tau_p`` a half-normal prior of scale :data:`TAU_SCALE`, truncated at 1 (relative) or
    1 V; the input offset :data:`V0_PRIOR`.  Noise parameters per record copy the shared
    defaults.

    Parameters
    ----------
    lik : Likelihood
    overrides : mapping of str to prior, optional
        Replacements by name in ``lik.names``.

    Returns
    -------
    PriorSet
    """
    base = default_priors(lik.model, noise="white", n_outputs=lik.n_outputs,
                          extension=lik.extension)
    table = dict(zip(base.names, zip(base.priors, base.transforms, strict=True), strict=True))
    noise = lik.noise_model.priors(lik.n_outputs)
    table.update(zip(noise.names, zip(noise.priors, noise.transforms, strict=True),
                     strict=True))
    table["v0"] = (V0_PRIOR, "identity")
    table[POWER_NAME] = (Uniform(*POWER_BOUNDS), "identity")
    priors, trs = [], []
    for nm in lik.names:
        m = re.fullmatch(r"(mu|tau)_(.+)", nm)
        base_name = nm.split("[", 1)[0]
        if m and m.group(2) in lik.parameter_layout.per_record and base_name == nm:
            p = m.group(2)
            if m.group(1) == "mu":
                pr, tr = table[p]
            else:
                scale = TAU_SCALE["v0"] if p in SIGNED else TAU_SCALE["log"]
                if p not in SIGNED and table[p][1] != "log":
                    raise ConfigError(
                        f"hierarchical {p}: a population needs a parameter sampled on a log "
                        f"scale (positive); declare {p} independent instead")
                pr, tr = Normal(0.0, scale, lo=0.0, hi=1.0), "log"
        else:
            pr, tr = table[base_name]
        priors.append(pr)
        trs.append(tr)
    ps = PriorSet(lik.names, tuple(priors), tuple(trs))
    return ps.replace(overrides) if overrides else ps


def records_start(lik: Likelihood, theta_mech: np.ndarray) -> np.ndarray:
    """A starting point of the full parameter vector from a joint single-record estimate.

    Shared parameters come from ``theta_mech`` (e.g. a least-squares fit of all records
    with shared parameters).  For the linear model each record's ``g_v`` and ``v0`` are
    then the least-squares solution of ``y = g a + h b`` with the unit-gain simulations
    ``a = S(v)``, ``b = S(1)`` and ``h = g v0`` (closed form, all outputs pooled); other
    per-record values start at the shared estimate.  Population means and spreads start
    at the mean and spread of the per-record values (spreads at least 1 % or 5 mV).  For
    an extended model each record's ``g_v`` is the best of a grid of :data:`GAIN_GRID`
    values (one batched likelihood call): a shared least-squares gain left the start
    thousands of nats below the posterior's typical set on the four ECP records.
    Noise parameters are moment estimates of the residuals.

    Parameters
    ----------
    lik : Likelihood
    theta_mech : ndarray, shape (n_mech,)

    Returns
    -------
    ndarray, shape (P,)
    """
    theta_mech = np.asarray(theta_mech, dtype=float)
    ix = lik._index
    R = lik.n_records
    values = {p: np.full(R, theta_mech[lik.mech_names.index(p)]) if p != "v0" else np.zeros(R)
              for p in lik.parameter_layout.per_record}
    if lik.extension is None and ("g_v" in values or "v0" in values):
        unit = theta_mech.copy()
        unit[0] = 1.0
        for r, e in enumerate(lik.experiments):
            a = simulate_linear(lik.model, unit, e.v_volt, e.dt).ravel()
            cols = [a]
            if "v0" in values:
                cols.append(simulate_linear(lik.model, unit, np.ones(e.n_samples), e.dt).ravel())
            coef = np.linalg.lstsq(np.column_stack(cols), e.y_m.ravel(), rcond=None)[0]
            g = coef[0] if coef[0] > 0 else theta_mech[0]
            if "g_v" in values:
                values["g_v"][r] = g
            if "v0" in values:
                values["v0"][r] = float(np.clip(coef[1] / g, -0.5, 0.5))
    out = _assemble_start(lik, values, theta_mech)
    if lik.extension is not None and "g_v" in values:
        # an extended model is not linear in g_v: each record's gain is the best of a grid
        # around the shared estimate, all records in one batched call (a record's
        # likelihood depends on its own gain only); the population then starts at them
        grid = theta_mech[0] * np.exp(np.linspace(np.log(0.6), np.log(1.5), GAIN_GRID))
        batch = np.repeat(out[None], grid.size, axis=0)
        batch[:, ix["groups"]["g_v"]["records"]] = grid[:, None]
        ll = lik.record_loglik(batch)
        ok = np.isfinite(ll)
        best = np.argmax(np.where(ok, ll, -np.inf), axis=0)
        values["g_v"] = np.where(ok.any(axis=0), grid[best], theta_mech[0])
        out = _assemble_start(lik, values, theta_mech)
    return out


#: Gain values tried per record by ``records_start`` for an extended model (0.6-1.5 times
#: the shared estimate: the ECP records' gains span 4.5-6.1 N/V).
GAIN_GRID = 46


def _assemble_start(lik: Likelihood, values: dict, theta_mech: np.ndarray
                    ) -> np.ndarray:
    ix = lik._index
    out = np.empty(lik.n_params)
    out[ix["shared_pos"]] = theta_mech[ix["shared"]]
    for p, g in ix["groups"].items():
        x = values[p]
        out[g["records"]] = np.mean(x) if g["kind"] == "shared" else x
        if g["kind"] == "hierarchical":
            if p in SIGNED:
                out[g["mu"]], out[g["tau"]] = np.mean(x), max(np.std(x), 0.005)
            else:
                out[g["mu"]] = np.exp(np.mean(np.log(x)))
                out[g["tau"]] = max(np.std(np.log(x)), 0.01)
    first = ix["noise"][0][0]
    end = len(out) if ix["power"] is None else ix["power"]
    if ix["power"] is not None:
        out[ix["power"]] = POWER_START
    out[first:end] = lik.residual_noise_start(out)
    return out


def noise_start(lik: Likelihood, theta: np.ndarray) -> np.ndarray:
    """Moment estimates of the noise parameters (in ``names`` order of the noise) from the
    residuals of each record at ``theta`` (``Likelihood.residual_noise_start``).

    Parameters
    ----------
    lik : Likelihood
    theta : ndarray, shape (P,)
        A full parameter vector; its noise entries are not read.

    Returns
    -------
    ndarray, shape (n_noise,)
        Shared noise parameters pool the records' estimates (RMS of ``sigma``, mean of
        the coefficients); per record, the records' estimates one after the other.
    """
    starts = []
    # (with a sampled power the residuals are scaled at its start value)
    power = POWER_START if lik._index["power"] is not None else 1.0
    for r in range(lik.n_records):
        full, v0 = lik.record_theta(theta[None], r)
        mech = full[0, : len(lik.mech_names)]
        e = lik.experiments[r]
        res = (e.y_m - lik.predict_mech(mech[None], v0, e)[0]) / lik.scale(r) ** power
        if lik.noise in NOISE_MODELS:
            starts.append(noise_moments(res, lik.noise))
        elif lik.noise == "process":
            # a small random force (N^2 s) and the residual RMS as measurement noise:
            # the posterior-mode refinement moves both
            starts.append(np.r_[np.full(lik.n_outputs, 1e-6),
                                np.sqrt(np.mean(res**2, axis=0))])
        else:
            starts.append(lik.record_noise[r].start(res))
    if lik.parameter_layout.noise_per_record:
        return np.concatenate(starts)
    # shared: pool the per-record moments (RMS of sigma, mean of the coefficients)
    s = np.array(starts)
    n = lik.n_outputs
    sig = np.sqrt(np.mean(s[:, :n] ** 2, axis=0))
    return np.r_[sig, np.mean(s[:, n:], axis=0)]

