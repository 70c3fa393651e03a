"""Speed benchmarks, each with a baseline measured in the same run.

``linear``: the batched exact ZOH simulator (parameter-dependent discretisation included)
against ``scipy.signal.lsim(..., interp=False)`` on the same systems.  Two timings are
reported: through a ``LinearSimulator`` whose output buffer is reused between calls (what a
likelihood does), and through ``simulate_linear`` allocating a fresh output array each call.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.signal

from .simulate import LinearSimulator, simulate_linear
from .system import LinearModel, Rig

__all__ = ["bench_linear", "time_per_call"]

#: Report Table 3 (free damping), the centre of the benchmark parameter cloud.
_TABLE3 = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])


def time_per_call(fn: Callable[[], object], *, min_time_s: float = 0.5, repeat: int = 5) -> float:
    """Best-of-``repeat`` mean wall time of ``fn()``, s, each repeat lasting ``min_time_s``."""
    fn()  # warm up (compilation, caches)
    best = np.inf
    for _ in range(repeat):
        n, t0 = 0, time.perf_counter()
        while True:
            fn()
            n += 1
            el = time.perf_counter() - t0
            if el >= min_time_s / repeat:
                break
        best = min(best, el / n)
    return best


def bench_linear(
    n_samples: int = 8000, batch: int = 64, *, dt: float = 0.005, rng=0, quick: bool = False
) -> dict:
    """Time the batched linear simulator against ``scipy.signal.lsim``.

    Parameters
    ----------
    n_samples : int
        Record length N.
    batch : int
        Parameter sets per call.
    dt : float
        Sample interval, s.
    rng : int or numpy.random.Generator
        Seed for the random input and the parameter cloud.
    quick : bool
        Shorter timing (for tests).

    Returns
    -------
    dict
        ``n_samples, batch, us_per_eval`` (reused buffer), ``us_per_eval_fresh_output``,
        ``lsim_us_per_eval``, ``speedup`` (lsim / us_per_eval), ``speedup_fresh_output``,
        ``max_rel_diff_vs_lsim``.
    """
    rng = np.random.default_rng(rng)
    model = LinearModel(Rig(), "free")
    theta = _TABLE3 * (1 + 0.1 * rng.random((batch, model.n_params)))
    u = rng.normal(size=n_samples)
    sim = LinearSimulator(u, dt, model.n_carts)
    min_time = 0.2 if quick else 1.0

    def reused():
        M, C, K, b = model.matrices(model.check(theta))
        return sim.run_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)

    t_sim = time_per_call(reused, min_time_s=min_time)
    t_fresh = time_per_call(lambda: simulate_linear(model, theta, u, dt), min_time_s=min_time)

    t = np.arange(n_samples) * dt
    A, B = model.state_space(theta[0])
    system = (A, B[:, None], np.eye(2 * model.n_carts)[: model.n_carts],
              np.zeros((model.n_carts, 1)))

    def one_lsim():
        return scipy.signal.lsim(system, u, t, interp=False)[1]

    t_lsim = time_per_call(one_lsim, min_time_s=min_time, repeat=3)
    y_lsim = one_lsim()
    y = simulate_linear(model, theta[0], u, dt)
    rel = float(np.max(np.abs(y - y_lsim)) / np.max(np.abs(y_lsim)))
    us = t_sim / batch * 1e6
    us_fresh = t_fresh / batch * 1e6
    return {
        "n_samples": int(n_samples),
        "batch": int(batch),
        "us_per_eval": us,
        "us_per_eval_fresh_output": us_fresh,
        "lsim_us_per_eval": t_lsim * 1e6,
        "speedup": t_lsim * 1e6 / us,
        "speedup_fresh_output": t_lsim * 1e6 / us_fresh,
        "max_rel_diff_vs_lsim": rel,
    }
