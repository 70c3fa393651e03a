"""Coverage of the several-record posterior on known-truth records that disagree.

Each replicate draws four records (pulses, steps and two chirps at the rig's amplitudes)
from a known truth, each with its own drive gain (log-normal, 5 % spread) and input offset
(10 mV), AR(1) noise and encoder quantisation, simulated independently of the package
(``tests/records_truth.py``).  Two analyses per replicate:

``joint``   the four records together, default layout (g_v and v0 per record from their
            populations), AR(1) noise;
``single``  the pulse record alone with the single-record AR(1) model.

For each analysis it records whether the 90 % equal-tailed intervals of the masses, the
natural frequencies, the modal damping ratios and the population gain ``mu_gv`` (for the
single-record model: its ``g_v``) contain the truth.  The coverage over R replicates has a
binomial standard error ``sqrt(0.9 * 0.1 / R)`` (0.03 for R = 100).

Usage::

    python benchmarks/records_coverage.py --replicates 100 --processes 2 --out rc.json

Each finished replicate is appended at once to ``<out>.jsonl`` (one JSON line with its seed
and settings); a rerun with the same ``--out`` and settings skips the seeds already there,
so an interrupted study loses at most the replicates in flight.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(_ROOT / "tests"))

from records_truth import QUANTITIES, replicate  # noqa: E402


def summarise(reps: list[dict]) -> dict:
    n = len(reps)
    se = float(np.sqrt(0.9 * 0.1 / n))
    res = {"replicates": n, "binomial_se": se}
    for label in ("joint", "single"):
        res[label] = {q: float(np.mean([r[label][q] for r in reps])) for q in QUANTITIES}
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    seeds = [args.seed + i for i in range(args.replicates)]
    settings = {"samples": args.samples, "steps": args.steps}
    log = Path(args.out).with_suffix(".jsonl") if args.out else None
    done = {}
    if log is not None and log.is_file():
        for line in log.read_text().splitlines():
            rec = json.loads(line)
            if rec["settings"] == settings and rec["seed"] in seeds:
                done[rec["seed"]] = rec["result"]
    todo = [s for s in seeds if s not in done]
    print(f"{len(done)} replicates found in {log}, {len(todo)} to run", file=sys.stderr)
    with ProcessPoolExecutor(args.processes) as pool:
        futures = {pool.submit(_one, (s, args.samples, args.steps)): s for s in todo}
        for k, fut in enumerate(as_completed(futures), 1):
            seed = futures[fut]
            done[seed] = fut.result()
            if log is not None:
                with log.open("a") as fh:
                    fh.write(json.dumps({"seed": seed, "settings": settings,
                                         "result": done[seed]}) + "\n")
            print(f"replicate {k}/{len(todo)} (seed {seed}) done, "
                  f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)
    reps = [done[s] for s in seeds]
    res = summarise(reps)
    res["wall_time_s"] = time.perf_counter() - t0
    res["settings"] = vars(args)
    text = json.dumps({"summary": res, "replicates": reps}, indent=1)
    if args.out:
        Path(args.out).write_text(text)
    print(json.dumps(res, indent=1))
    return 0


def _one(args):
    seed, n, steps = args
    return replicate(seed, n_samples=n, steps=steps)


if __name__ == "__main__":
    sys.exit(main())
