"""What threads buy one ensemble: a half-ensemble's log posterior, serial against threaded.

For each run configuration given (default: the linear main job ``runs/records_free.toml``
and the extended model ``runs/records_friction.toml``), builds its log posterior on its
records, takes half an ensemble of walkers near the start, and times the batched call in
one thread and in ``--threads`` threads (``bayesmodal.inference.ThreadedLogPosterior``),
interleaved over ``--rounds`` rounds (best of ``--repeats`` each; ratio = median of the
per-round ratios, both sides timed in the same round).  It also checks that the values
are equal bit for bit, which is the promise that makes threads safe to use.

Usage::

    python benchmarks/threads.py
    python benchmarks/threads.py runs/records_friction.toml --threads 2 --json out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(_ROOT))

DEFAULT = ("runs/records_free.toml", "runs/records_friction.toml")


def _log_post(config: str):
    """The configuration's log posterior (as its run builds it) and a half-ensemble."""
    from bayesmodal.inference import sample_posterior
    from bayesmodal.inference.sampling import LogPosterior
    from bayesmodal.runs.config import load_config
    from bayesmodal.runs.runner import prepare_run

    cfg = load_config(config)
    prep = prepare_run(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # a few steps from a ball at the start (no mode search): the likelihood, priors
        # and a spread of walkers of the right shape
        run = sample_posterior(
            list(prep.experiments), prep.model, noise=prep.noise or cfg.likelihood.noise,
            priors=prep.priors, n_walkers=cfg.sampler.walkers, n_steps=24, burn=4,
            moves=prep.moves, rng=cfg.sampler.seed, warn=False, extension=prep.extension,
            layout=cfg.layout, init="ball", refine=False)
    lp = LogPosterior(run.likelihood, run.priors)
    z = run.priors.to_sampling(run.chain[-1])[: cfg.sampler.walkers // 2]
    return cfg, lp, z


def _best(f, z, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        f(z)
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="*", default=[str(_ROOT / c) for c in DEFAULT])
    ap.add_argument("--threads", default="auto", help="threads to compare with one")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=None, help="write the figures to this file")
    args = ap.parse_args(argv)
    from bayesmodal.bench import machine_load
    from bayesmodal.inference import ThreadedLogPosterior, resolve_threads

    n = resolve_threads(args.threads)
    out = {"machine": machine_load(), "threads": n, "configs": []}
    load = out["machine"]["load_average"]
    print(f"load average at start: {load}; {n} threads against 1")
    for config in args.configs:
        cfg, lp, z = _log_post(config)
        with ThreadedLogPosterior(lp, n) as tp:
            equal = bool(np.array_equal(tp(z), lp(z)))  # also compiles and warms up
            rounds = []
            for _ in range(args.rounds):
                serial = _best(lp, z, args.repeats)
                threaded = _best(tp, z, args.repeats)
                rounds.append((serial, threaded))
        ratios = [s / t for s, t in rounds]
        row = {"config": config, "extensions": list(cfg.model.extensions),
               "walkers_per_call": int(z.shape[0]),
               "serial_ms": [1e3 * s for s, _ in rounds],
               "threaded_ms": [1e3 * t for _, t in rounds],
               "speedup": float(np.median(ratios)), "speedup_rounds": ratios,
               "equal_bit_for_bit": equal}
        out["configs"].append(row)
        print(f"{Path(config).name}: {z.shape[0]} walkers per call, serial "
              f"{np.median(row['serial_ms']):.1f} ms, {n} threads "
              f"{np.median(row['threaded_ms']):.1f} ms, speedup {row['speedup']:.2f}x "
              f"(rounds {', '.join(f'{r:.2f}' for r in ratios)}), "
              f"{'equal' if equal else 'NOT EQUAL'} bit for bit")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0 if all(r["equal_bit_for_bit"] for r in out["configs"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
