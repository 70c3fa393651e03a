"""Detection benchmark of ``bayesmodal.discrepancy.diagnosis``: hidden effects and null data.

For every extension in the catalogue, ``--seeds`` synthetic experiments hide the effect at
a size and location drawn from the seed (``tests/hidden_effects.py``: the independent
reference simulators of ``tests/reference_sim.py``, sensor noise, encoder quantisation);
``--nulls`` experiments hide nothing.  ``diagnose`` (least squares only,
``posterior=False``) must name the cause AND the cart or spring; on the null data it must
answer ``none``.  Prints the detection rate per effect (goal >= 95 %) and the
false-positive rate (goal <= 5 %), with binomial standard errors, and writes JSON.

Usage::

    python benchmarks/detection.py --seeds 20 --nulls 50 --workers 2 --out detection.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

# the hidden-effect cases live in tests/
_HERE = Path(__file__).resolve().parent
_TESTS = _HERE.parent / "tests"
sys.path.insert(0, str(_TESTS))
sys.path.insert(0, str(_HERE.parent / "docs"))  # docs/_stamp.py

import numpy as np  # noqa: E402

SEED_OFFSET = 10_000  # benchmark seeds never coincide with the tests' seeds


def _job(args):
    effect, seed, n_null, n_samples = args
    import warnings

    from hidden_effects import make

    from bayesmodal.discrepancy.diagnosis import diagnose

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    h = make(effect, seed, n_samples)
    try:
        d = diagnose(h.experiment, posterior=False, n_null=n_null, rng=seed)
        cause, loc, err = d.cause, d.location, None
        params = {k: v.median for k, v in d.parameters.items()}
        stat, thr = d.statistic, d.threshold
    except Exception as exc:  # record, do not stop the benchmark
        cause, loc, err, stat, thr = "error", None, f"{type(exc).__name__}: {exc}", None, None
        params = {}
    truth = h.effect
    ok = cause == truth and (truth == "none" or loc == h.location)
    return {"effect": truth, "seed": seed, "cause": cause, "location": loc,
            "true_location": h.location, "size": h.theta_extension.tolist(),
            "params": params, "correct": bool(ok), "cause_correct": cause == truth,
            "statistic": stat,
            "threshold": thr, "error": err, "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    from hidden_effects import EFFECTS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="experiments per effect")
    ap.add_argument("--nulls", type=int, default=50, help="experiments without an effect")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--calibration-nulls", type=int, default=19,
                    help="null data sets of diagnose's own calibration (default 19)")
    ap.add_argument("--samples", type=int, default=2400,
                    help="record length, samples of 5 ms (default 2400, as in the tests)")
    ap.add_argument("--effects", nargs="*", default=list(EFFECTS))
    ap.add_argument("--out", default="detection.json", help="JSON output file")
    args = ap.parse_args(argv)
    # interleaved (seed by seed) so that a partial run is balanced; the JSON is rewritten
    # after every result
    jobs = []
    for s in range(max(args.seeds, args.nulls)):
        if s < args.nulls:
            jobs.append((None, SEED_OFFSET + s, args.calibration_nulls, args.samples))
        if s < args.seeds:
            jobs += [(e, SEED_OFFSET + s, args.calibration_nulls, args.samples)
                     for e in args.effects]
    t0 = time.perf_counter()
    rows = []
    from bayesmodal._blas import blas_pool  # a BLAS share per process
    with blas_pool(max(1, args.workers)) as pool:
        for i, r in enumerate(pool.imap_unordered(_job, jobs), 1):
            rows.append(r)
            print(f"[{i}/{len(jobs)}] {r['effect']:17s} seed {r['seed']}: {r['cause']} "
                  f"{r['location']} (truth {r['true_location']}) "
                  f"{'ok' if r['correct'] else 'WRONG'} {r['seconds']:.0f} s", flush=True)
            _write(args, rows, t0, final=False)
    table = _write(args, rows, t0, final=True)
    print()
    print(f"{'effect':18s} {'n':>4s} {'rate':>7s} {'se':>6s}  wrong answers")
    for eff, t in table.items():
        label = "false positives" if eff == "none" else eff
        rate = 1 - t["rate"] if eff == "none" else t["rate"]
        se = t["se"]
        print(f"{label:18s} {t['n']:4d} {100 * rate:6.1f}% {100 * se:5.1f}%  "
              f"{', '.join(t['confusions'])}")
    print(f"\nwrote {args.out} ({time.perf_counter() - t0:.0f} s)")
    return 0


def _write(args, rows, t0, *, final):
    from _stamp import stamp  # date, commit and machine of the output

    table = {}
    for eff in ["none"] + list(args.effects):
        sel = [r for r in rows if r["effect"] == eff]
        if not sel:
            continue
        k = sum(r["correct"] for r in sel)
        n = len(sel)
        rate = k / n
        table[eff] = {"n": n, "correct": k, "rate": rate,
                      "se": float(np.sqrt(max(rate * (1 - rate), 1e-12) / n)),
                      "cause_correct": sum(r["cause_correct"] for r in sel),
                      "confusions": sorted({r["cause"] for r in sel if not r["correct"]})}
    out = {"table": table, "rows": rows, "seeds": args.seeds, "nulls": args.nulls,
           "calibration_nulls": args.calibration_nulls, "samples": args.samples,
           "complete": final, "wall_seconds": time.perf_counter() - t0, "stamp": stamp()}
    Path(args.out).write_text(json.dumps(out, indent=2))
    return table


if __name__ == "__main__":
    sys.exit(main())
