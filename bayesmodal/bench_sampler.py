"""Sampler throughput: likelihood evaluations per second in an emcee run, against the bare
simulator at the same record length, measured in the same run.

Three rates, each in parameter sets (likelihood evaluations) per second on one record of
``n_samples`` samples of the rig-like input (``bench.rig_input``):

``simulator``
    ``simulate_linear`` on a half-ensemble batch (what one emcee half-step simulates);
``likelihood``
    ``Likelihood.__call__`` (AR(1)) on the same batch: simulation plus residual statistics;
``sampler``
    emcee's ``EnsembleSampler.run_mcmc`` with the vectorised log posterior (priors,
    transforms, moves and bookkeeping included), walkers x steps / wall time.

The requirement is ``sampler / simulator >= SAMPLER_MIN_FRACTION``.

``records`` repeats the emcee timing with the several-record default
(``inference.records.DEFAULT_LAYOUT``: AR(1), a gain per record from its population, one
shared input offset) on three records of the same length, and counts record evaluations
(parameter sets times records) per second, against the bare simulator at the same batch.
"""

from __future__ import annotations

import time

import numpy as np

from .bench import _TABLE3, rig_input, time_per_call

__all__ = ["SAMPLER_MIN_FRACTION", "bench_sampler"]

#: Smallest accepted sampler rate as a fraction of the bare simulator's.
SAMPLER_MIN_FRACTION = 0.5


def bench_sampler(n_samples: int = 7400, n_walkers: int = 32, n_steps: int = 100, *,
                  dt: float = 0.005, rng=0, quick: bool = False) -> dict:
    """Time the sampler, the likelihood and the bare simulator (see the module docstring).

    Parameters
    ----------
    n_samples : int
        Record length (the measured ECP records have about 7400).
    n_walkers, n_steps : int
        Ensemble size and steps of the timed emcee run.
    dt : float
        Sample interval, s.
    rng : int or numpy.random.Generator
    quick : bool
        Shorter timing (for tests).

    Returns
    -------
    dict
        ``simulator_evals_per_s``, ``likelihood_evals_per_s``, ``sampler_evals_per_s``,
        ``sampler_fraction`` (sampler / simulator), ``meets_target``, and the sizes.
    """
    import emcee

    from .data import Experiment
    from .inference.likelihood import Likelihood, simulate_noise
    from .inference.priors import default_priors
    from .inference.sampling import LogPosterior
    from .simulate import simulate_linear
    from .system import LinearModel, Rig

    rng = np.random.default_rng(rng)
    model = LinearModel(Rig(), "free")
    u = rig_input(n_samples, dt)
    y = simulate_linear(model, _TABLE3, u, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-6), np.full((1, 3), 0.99), n_samples, rng)[0]
    exp = Experiment(np.arange(n_samples) * dt, u, y, name="bench")
    lik = Likelihood(model, (exp,), "ar1")
    priors = default_priors(model, noise="ar1")
    log_post = LogPosterior(lik, priors)
    half = n_walkers // 2
    centre = np.r_[_TABLE3 + 1e-3, 2e-6, 2e-6, 2e-6, 0.99, 0.99, 0.99]
    theta = centre * (1 + 1e-4 * rng.standard_normal((half, centre.size)))
    min_time = 0.2 if quick else 1.0
    t_sim = time_per_call(lambda: simulate_linear(model, theta[:, :9], u, dt),
                          min_time_s=min_time)
    t_lik = time_per_call(lambda: lik(theta), min_time_s=min_time)

    z0 = priors.to_sampling(centre * (1 + 1e-4 * rng.standard_normal((n_walkers, centre.size))))
    steps = max(10, n_steps // (4 if quick else 1))
    sampler = emcee.EnsembleSampler(n_walkers, centre.size, log_post, vectorize=True)
    state = emcee.State(z0, random_state=np.random.RandomState(1).get_state())
    sampler.run_mcmc(state, 2)  # warm up
    t0 = time.perf_counter()
    sampler.run_mcmc(None, steps)
    t_run = time.perf_counter() - t0
    sim_rate = half / t_sim
    samp_rate = n_walkers * steps / t_run
    return {"n_samples": int(n_samples), "n_walkers": int(n_walkers), "n_steps": int(steps),
            "simulator_evals_per_s": sim_rate, "likelihood_evals_per_s": half / t_lik,
            "sampler_evals_per_s": samp_rate, "sampler_fraction": samp_rate / sim_rate,
            "meets_target": bool(samp_rate / sim_rate >= SAMPLER_MIN_FRACTION),
            "records": _bench_records(model, u, y, dt, steps, min_time, rng)}


def _bench_records(model, u, y, dt, steps, min_time, rng, n_records: int = 3) -> dict:
    """The emcee timing with the several-record default layout (see the module docstring)."""
    import emcee

    from .data import Experiment
    from .inference.records import DEFAULT_LAYOUT, RecordsLikelihood, record_priors
    from .inference.records import records_start as start
    from .inference.sampling import LogPosterior
    from .simulate import simulate_linear

    n = u.size
    exps = tuple(Experiment(np.arange(n) * dt, u, y * (1 + 0.03 * r), name=f"r{r}")
                 for r in range(n_records))
    lik = RecordsLikelihood(model, exps, "ar1", layout=DEFAULT_LAYOUT)
    priors = record_priors(lik)
    log_post = LogPosterior(lik, priors)
    centre = start(lik, _TABLE3)
    n_walkers = 2 * centre.size
    half = n_walkers // 2
    theta = centre * (1 + 1e-4 * rng.standard_normal((half, centre.size)))
    mech = _TABLE3 * (1 + 1e-4 * rng.standard_normal((half, _TABLE3.size)))
    t_sim = time_per_call(lambda: simulate_linear(model, mech, u, dt), min_time_s=min_time)
    t_lik = time_per_call(lambda: lik(theta), min_time_s=min_time)
    z0 = priors.to_sampling(centre * (1 + 1e-4 * rng.standard_normal((n_walkers,
                                                                      centre.size))))
    sampler = emcee.EnsembleSampler(n_walkers, centre.size, log_post, vectorize=True)
    sampler.run_mcmc(emcee.State(z0, random_state=np.random.RandomState(1).get_state()), 2)
    t0 = time.perf_counter()
    sampler.run_mcmc(None, steps)
    t_run = time.perf_counter() - t0
    sim_rate = half / t_sim
    samp_rate = n_walkers * steps * n_records / t_run
    return {"n_records": n_records, "n_walkers": n_walkers,
            "simulator_evals_per_s": sim_rate,
            "likelihood_record_evals_per_s": half * n_records / t_lik,
            "sampler_record_evals_per_s": samp_rate, "sampler_fraction": samp_rate / sim_rate}
