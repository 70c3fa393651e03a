"""Speed of the linear simulator on a logger's recorded time stamps.

A logger paced by a software loop stamps its samples in whole milliseconds with jitter, so
a record's steps take a few distinct values (``bayesmodal.model.simulate.step_groups``).
``bench_stamps`` times the simulator on such stamps against the uniform simulator at their
mean step, in the same run; at most ``STAMPS_MAX_RATIO``.
"""

from __future__ import annotations

import numpy as np

from .bench import _bench_problem, reused_linear, time_per_call
from .model.simulate import step_groups

__all__ = ["STAMPS_MAX_RATIO", "bench_stamps", "logger_steps"]

#: Target cost of a simulation on a logger's recorded stamps, relative to the uniform
#: simulator on the same record length and batch.
STAMPS_MAX_RATIO = 1.5


def logger_steps(n_samples: int, rng, loop_ms: float = 1.127) -> np.ndarray:
    """Steps of a logger loop paced at ``loop_ms`` with up to 0.12 ms of latency and its
    stamps rounded to whole ms.

    Parameters
    ----------
    n_samples : int
        Samples of the record.
    rng : int or numpy.random.Generator
        Seed of the latencies.
    loop_ms : float
        The loop's period, ms.

    Returns
    -------
    ndarray, shape (n_samples - 1,)
        The steps, s (1 and 2 ms).
    """
    rng = np.random.default_rng(rng)
    k = np.arange(n_samples)
    return np.diff(np.round(k * loop_ms + rng.uniform(0.0, 0.12, n_samples)) / 1000.0)


def bench_stamps(n_samples: int = 8000, batch: int = 64, *, rng=0, quick: bool = False,
                 rounds: int = 3) -> dict:
    """Time the linear simulator on a logger's jittered stamps against the uniform one.

    Both run the benchmark's model, parameter cloud and input (``bench_linear``'s) as
    ``reused_linear`` times them, the uniform one at the stamps' mean step; the rounds
    alternate, so that both see the same machine load.

    Parameters
    ----------
    n_samples : int
        Record length N.
    batch : int
        Parameter sets per call.
    rng : int or numpy.random.Generator
        Seed for the input, the parameter cloud and the stamps.
    quick : bool
        Shorter timing (for tests).
    rounds : int
        Alternating rounds; the ratio is their median.

    Returns
    -------
    dict
        ``n_samples, batch, n_distinct_steps, us_per_eval_uniform, us_per_eval_stamps``
        (per parameter set), ``ratio`` (stamps / uniform, median over rounds),
        ``ratio_per_round``, ``target`` (``STAMPS_MAX_RATIO``), ``meets_target``.
    """

    model, theta, u = _bench_problem(n_samples, batch, rng)
    steps = logger_steps(n_samples, rng)
    min_time = 0.2 if quick else 1.0
    uniform = reused_linear(model, theta, u, float(np.mean(steps)))
    stamps = reused_linear(model, theta, u, steps)
    t_u, t_s = [], []
    for _ in range(rounds):
        t_u.append(time_per_call(uniform, min_time_s=min_time))
        t_s.append(time_per_call(stamps, min_time_s=min_time))
    ratios = np.array(t_s) / np.array(t_u)
    ratio = float(np.median(ratios))
    return {
        "n_samples": int(n_samples),
        "batch": int(batch),
        "n_distinct_steps": int(step_groups(steps)[0].size),
        "us_per_eval_uniform": float(np.median(t_u)) / batch * 1e6,
        "us_per_eval_stamps": float(np.median(t_s)) / batch * 1e6,
        "ratio": ratio,
        "ratio_per_round": [float(r) for r in ratios],
        "target": STAMPS_MAX_RATIO,
        "meets_target": bool(ratio <= STAMPS_MAX_RATIO),
    }
