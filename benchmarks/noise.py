"""Speed of the noise models' log-likelihoods against the AR(1) path, in the same run.

At one record length (default 3 outputs, N = 10000, nb = 32 parameter sets) each model's
total ``loglik`` on a residual array ``R`` of shape (N, n_out, nb) is timed against
``AR1Noise.loglik`` (the sufficient-statistics path of ``Likelihood.__call__``).  The
process-noise likelihood has no residual (its filter *is* the simulation), so it is timed
in full (discretisation, Van Loan, DARE, filter) and reported twice: against the AR(1)
noise term alone and against a complete AR(1) evaluation from the parameters,
``Likelihood(model, [experiment], "ar1")(theta)`` (simulation, residual, AR(1) term), on
the same record and parameter sets.  Rounds alternate between baseline and model.  Each
timing is the fastest of many single calls: on a shared, overloaded machine a call is
often descheduled for far longer than it runs, and the fastest call is the estimate of the
work itself.  The reported ratio is the ratio of the fastest calls over all rounds; the
per-round ratios show the spread.

Usage::

    python benchmarks/noise.py [--n-samples 10000] [--batch 32] [--rounds 3] [--out noise.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from bayesmodal.bench import _TABLE3  # noqa: E402
from bayesmodal.data import Experiment  # noqa: E402
from bayesmodal.inference.likelihood import Likelihood  # noqa: E402
from bayesmodal.inference.noise import (  # noqa: E402
    AR1Noise,
    ARpNoise,
    WhiteNoise,
    kalman_loglik,
)
from bayesmodal.model.simulate import simulate_linear  # noqa: E402
from bayesmodal.model.system import LinearModel, Rig  # noqa: E402


def best_time(fn, *, n_calls: int = 15, min_time_s: float = 0.3) -> float:
    """Fastest of at least ``n_calls`` single calls of ``fn()`` (and ``min_time_s``), s."""
    fn()  # warm up (compilation, caches)
    best, t_start, k = np.inf, time.perf_counter(), 0
    while k < n_calls or time.perf_counter() - t_start < min_time_s:
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
        k += 1
    return best


def bench_noise(n_samples: int = 10000, batch: int = 32, *, rounds: int = 3,
                min_time_s: float = 0.3, rng=0) -> dict:
    """Time each noise model's loglik against AR(1) on the same residual array.

    Returns
    -------
    dict
        Per model: ``ms_per_call`` (fastest call, whole batch), ``ratio_to_ar1`` (fastest
        over fastest), ``ratio_per_round``; for ``process_noise`` also
        ``ratio_to_likelihood_ar1`` (also for ``process_noise_rest``, the exact start).
        ``ar1_ms_per_call`` is the baseline.
    """
    rng = np.random.default_rng(rng)
    n_out = 3
    model = LinearModel(Rig(), "free")
    theta = _TABLE3 * (1 + 0.1 * rng.random((batch, model.n_params)))
    t = np.arange(n_samples) * 0.005
    v = np.where((t % 10) < 0.045, 3.0, 0.0)
    y = simulate_linear(model, _TABLE3, v, 0.005) + 1e-5 * rng.normal(size=(n_samples, n_out))
    ar1 = AR1Noise()
    p_ar1 = np.c_[np.full((batch, n_out), 1e-5), rng.uniform(0.9, 0.99, (batch, n_out))]
    R = np.ascontiguousarray(np.moveaxis(ar1.simulate(p_ar1, n_samples, rng), 0, -1))
    cases = {"white": (WhiteNoise(), p_ar1[:, :n_out])}
    for p in (2, 4, 8):
        m = ARpNoise((p,) * n_out)
        kap = rng.uniform(-0.5, 0.9, (batch, n_out, p))
        cases[f"ar{p}"] = (m, m.join(p_ar1[:, :n_out], kap))
    q = np.full((batch, n_out), 1e-6)
    sig = np.full((batch, n_out), 1e-5)

    def base():
        return ar1.loglik(R, p_ar1)

    lik = Likelihood(model, [Experiment(t, v, y)], "ar1")
    full = np.c_[theta, p_ar1]

    def lik_ar1():
        return lik(full)

    def kalman():
        return kalman_loglik(model, theta, q, sig, v, y, 0.005)

    fns = {name: (lambda m=m, p=p: m.loglik(R, p)) for name, (m, p) in cases.items()}
    fns["likelihood_ar1"] = lik_ar1
    fns["process_noise"] = kalman
    fns["process_noise_rest"] = lambda: kalman_loglik(model, theta, q, sig, v, y, 0.005,
                                                      initial="rest")
    t_base, t = [], {name: [] for name in fns}
    for _ in range(rounds):
        t_base.append(best_time(base, min_time_s=min_time_s))
        for name, fn in fns.items():
            t[name].append(best_time(fn, min_time_s=min_time_s))
    t_base = np.array(t_base)
    out = {"n_samples": n_samples, "batch": batch, "n_outputs": n_out,
           "ar1_ms_per_call": float(t_base.min()) * 1e3}
    for name, ts in t.items():
        ts = np.array(ts)
        out[name] = {"ms_per_call": float(ts.min()) * 1e3,
                     "ratio_to_ar1": float(ts.min() / t_base.min()),
                     "ratio_per_round": [float(r) for r in ts / t_base]}
    for name in ("process_noise", "process_noise_rest"):
        out[name]["ratio_to_likelihood_ar1"] = float(
            np.min(t[name]) / np.min(t["likelihood_ar1"]))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-samples", type=int, default=10000)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    res = bench_noise(args.n_samples, args.batch, rounds=args.rounds)
    text = json.dumps(res, indent=2)
    if args.out:
        args.out.write_text(text)
    sys.stdout.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
