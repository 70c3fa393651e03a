"""Sampler and likelihood throughput against the bare simulator, in CPU time.

CPU time (``time.process_time``, best of repeats) is robust to other jobs on a shared
machine, where wall-clock rates are not comparable between runs.  Two cases on records of
7400 samples: one record with AR(1) noise (32 walkers), and three records with the
several-record default layout (``inference.records.DEFAULT_LAYOUT``; record evaluations,
i.e. parameter sets times records).  To compare two versions of the package, run it with
PYTHONPATH at each::

    PYTHONPATH=. python benchmarks/sampler_cpu_time.py after
"""

from __future__ import annotations

import sys
import time

import emcee
import numpy as np

from bayesmodal.bench import _TABLE3, rig_input
from bayesmodal.data import Experiment
from bayesmodal.inference.likelihood import Likelihood, simulate_noise
from bayesmodal.inference.priors import default_priors
from bayesmodal.inference.records import (
    DEFAULT_LAYOUT,
    RecordsLikelihood,
    record_priors,
    records_start,
)
from bayesmodal.inference.sampling import LogPosterior
from bayesmodal.simulate import simulate_linear
from bayesmodal.system import LinearModel, Rig

N, DT, STEPS = 7400, 0.005, 40


def cpu_per_call(f, reps: int) -> float:
    best = np.inf
    for _ in range(5):
        t = time.process_time()
        for _ in range(reps):
            f()
        best = min(best, (time.process_time() - t) / reps)
    return best


def measure(model, u, lik, priors, centre, n_walkers, n_records, rng) -> str:
    half = n_walkers // 2
    log_post = LogPosterior(lik, priors)
    mech = _TABLE3 * (1 + 1e-4 * rng.standard_normal((half, _TABLE3.size)))
    theta = centre * (1 + 1e-4 * rng.standard_normal((half, centre.size)))
    lik(theta)  # compile
    t_sim = cpu_per_call(lambda: simulate_linear(model, mech, u, DT), 40)
    t_lik = cpu_per_call(lambda: lik(theta), 40)
    z0 = priors.to_sampling(centre * (1 + 1e-4 * rng.standard_normal((n_walkers,
                                                                      centre.size))))
    sampler = emcee.EnsembleSampler(n_walkers, centre.size, log_post, vectorize=True)
    sampler.run_mcmc(emcee.State(z0, random_state=np.random.RandomState(1).get_state()), 2)
    best = np.inf
    for _ in range(3):
        t = time.process_time()
        sampler.run_mcmc(None, STEPS)
        best = min(best, time.process_time() - t)
    sim = half / t_sim
    lk = half * n_records / t_lik
    sm = n_walkers * STEPS * n_records / best
    return (f"  sim {sim:.0f}/s  lik {lk:.0f}/s  sampler {sm:.0f}/s  "
            f"sampler/sim {sm / sim:.2f}  lik/sim {lk / sim:.2f}")


def main(label: str) -> int:
    rng = np.random.default_rng(0)
    model = LinearModel(Rig(), "free")
    u = rig_input(N, DT)
    y = simulate_linear(model, _TABLE3, u, DT) + simulate_noise(
        np.full((1, 3), 2e-6), np.full((1, 3), 0.99), N, rng)[0]
    t = np.arange(N) * DT
    print(label, "one record, 32 walkers")
    centre = np.r_[_TABLE3 + 1e-3, 2e-6, 2e-6, 2e-6, 0.99, 0.99, 0.99]
    print(measure(model, u, Likelihood(model, (Experiment(t, u, y, name="b"),), "ar1"),
                  default_priors(model, noise="ar1"), centre, 32, 1, rng))
    exps = tuple(Experiment(t, u, y * (1 + 0.03 * r), name=f"r{r}") for r in range(3))
    lik = RecordsLikelihood(model, exps, "ar1", layout=DEFAULT_LAYOUT)
    centre = records_start(lik, _TABLE3)
    print(label, "three records, default layout,", 2 * centre.size, "walkers")
    print(measure(model, u, lik, record_priors(lik), centre, 2 * centre.size, 3, rng))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else ""))
