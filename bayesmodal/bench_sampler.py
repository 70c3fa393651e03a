"""Sampler throughput: likelihood evaluations per second in an emcee run, against the bare
simulator at the same record length, measured in the same run.

Three rates, each in parameter sets (likelihood evaluations) per second on one record of
``n_samples`` samples of the rig-like input (``bench.rig_input``):

``simulator``
    the linear simulator with a reused output buffer (``bench.reused_linear``: validation,
    matrices, discretisation and recursion) on a half-ensemble batch (what one emcee
    half-step simulates);
``likelihood``
    ``Likelihood.__call__`` (AR(1)) on the same batch: simulation plus residual statistics;
``sampler``
    emcee's ``EnsembleSampler.run_mcmc`` with the vectorised log posterior (priors,
    transforms, moves and bookkeeping included), walkers x steps / wall time.

All three are timed alike and side by side, as ``bench.bench_extensions`` times its kernels:
in CPU time of the process (``time.process_time``; the compiled code is single-threaded, so
time spent waiting for a core on a shared machine is not counted), over ``rounds`` rounds
that each time the simulator, the likelihood and the sampler in turn (``time_per_call``:
best of three repeats); each reported rate is the median over the rounds and each fraction
the median of the per-round fractions, so a busy spell slows both sides of a ratio alike.
The sampler is timed in chunks of ``CHUNK_STEPS`` steps continuing one chain, each into a
freshly reset in-memory backend (a run grows its backend once).
"""

from __future__ import annotations

import time

import numpy as np

from .bench import _TABLE3, reused_linear, rig_input, time_per_call
from .data import Experiment
from .inference.likelihood import Likelihood, simulate_noise
from .inference.priors import default_priors
from .inference.record_layout import DEFAULT_LAYOUT
from .inference.record_priors import record_priors
from .inference.record_priors import records_start as start
from .inference.sampling import LogPosterior
from .model.simulate import simulate_linear
from .model.system import LinearModel, Rig

__all__ = ["SAMPLER_MIN_FRACTION", "bench_sampler"]

#: Smallest accepted sampler rate as a fraction of the bare simulator's.
SAMPLER_MIN_FRACTION = 0.5

#: emcee steps per timed call of the sampler.
CHUNK_STEPS = 10


def _paired_rates(simulate, likelihood, sampler, state, n_sets: int, n_walkers: int,
                  min_time: float, rounds: int) -> dict:
    """Median rates (sets per CPU second) of the three timings and the median per-round
    sampler / simulator fraction (see the module docstring)."""
    box = [state]

    def chunk():
        sampler.reset()  # a fresh backend: the timing does not include a growing chain
        box[0] = sampler.run_mcmc(box[0], CHUNK_STEPS)

    def cpu(fn):
        return time_per_call(fn, min_time_s=min_time, repeat=3, clock=time.process_time)

    sim, lik, samp = [], [], []
    for _ in range(rounds):
        sim.append(n_sets / cpu(simulate))
        lik.append(n_sets / cpu(likelihood))
        samp.append(n_walkers * CHUNK_STEPS / cpu(chunk))
    sim, lik, samp = map(np.array, (sim, lik, samp))
    return {"simulator": float(np.median(sim)), "likelihood": float(np.median(lik)),
            "sampler": float(np.median(samp)), "fraction": float(np.median(samp / sim)),
            "fraction_per_round": (samp / sim).tolist()}


def bench_sampler(n_samples: int = 7400, n_walkers: int = 32, n_steps: int = 100, *,
                  dt: float = 0.005, rng=0, quick: bool = False) -> dict:
    """Time the sampler, the likelihood and the bare simulator (see the module docstring).

    Parameters
    ----------
    n_samples : int
        Record length (the measured ECP records have about 7400).
    n_walkers : int
        Ensemble size.
    n_steps : int
        Steps run before the timing, so the walkers have left their start ball.
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
    min_time, rounds = (0.2, 2) if quick else (0.6, 5)
    z0 = priors.to_sampling(centre * (1 + 1e-4 * rng.standard_normal((n_walkers, centre.size))))
    sampler = emcee.EnsembleSampler(n_walkers, centre.size, log_post, vectorize=True)
    state = emcee.State(z0, random_state=np.random.RandomState(1).get_state())
    state = sampler.run_mcmc(state, max(2, n_steps // (4 if quick else 1)))  # leave the ball
    r = _paired_rates(reused_linear(model, theta[:, :9], u, dt),
                      lambda: lik(theta), sampler, state, half, n_walkers, min_time, rounds)
    return {"n_samples": int(n_samples), "n_walkers": int(n_walkers), "rounds": rounds,
            "simulator_evals_per_s": r["simulator"], "likelihood_evals_per_s": r["likelihood"],
            "sampler_evals_per_s": r["sampler"], "sampler_fraction": r["fraction"],
            "sampler_fraction_per_round": r["fraction_per_round"],
            "meets_target": bool(r["fraction"] >= SAMPLER_MIN_FRACTION),
            "records": _bench_records(model, u, y, dt, min_time, rounds, rng)}


def _bench_records(model, u, y, dt, min_time, rounds, rng, n_records: int = 3) -> dict:
    """The emcee timing with the several-record default layout (see the module docstring)."""
    import emcee


    n = u.size
    exps = tuple(Experiment(np.arange(n) * dt, u, y * (1 + 0.03 * r), name=f"r{r}")
                 for r in range(n_records))
    lik = Likelihood(model, exps, "ar1", layout=DEFAULT_LAYOUT)
    priors = record_priors(lik)
    log_post = LogPosterior(lik, priors)
    centre = start(lik, _TABLE3)
    n_walkers = 2 * centre.size
    half = n_walkers // 2
    theta = centre * (1 + 1e-4 * rng.standard_normal((half, centre.size)))
    mech = _TABLE3 * (1 + 1e-4 * rng.standard_normal((half, _TABLE3.size)))
    z0 = priors.to_sampling(centre * (1 + 1e-4 * rng.standard_normal((n_walkers,
                                                                      centre.size))))
    sampler = emcee.EnsembleSampler(n_walkers, centre.size, log_post, vectorize=True)
    state = sampler.run_mcmc(
        emcee.State(z0, random_state=np.random.RandomState(1).get_state()), 2)
    # rates in record evaluations: a likelihood call evaluates every record
    r = _paired_rates(reused_linear(model, mech, u, dt), lambda: lik(theta),
                      sampler, state, half, n_walkers, min_time, rounds)
    per_round = [f * n_records for f in r["fraction_per_round"]]
    return {"n_records": n_records, "n_walkers": n_walkers,
            "simulator_evals_per_s": r["simulator"],
            "likelihood_record_evals_per_s": r["likelihood"] * n_records,
            "sampler_record_evals_per_s": r["sampler"] * n_records,
            # the median of the reported rounds (scaling the median instead differs from
            # it by rounding when the median averages two rounds)
            "sampler_fraction": float(np.median(per_round)),
            "sampler_fraction_per_round": per_round}
