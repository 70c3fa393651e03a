"""Detection benchmark of forward selection: the newer effects alone and effects in pairs.

For every case of ``tests/hidden_pairs.py`` (input offset, drive dead band, directional
Coulomb levels, friction + offset, friction + dead band; data from the independent
reference simulators, sensor noise, encoder counts) ``--seeds`` experiments, and
``--nulls`` experiments without any effect (``tests/hidden_effects.py``).  ``diagnose``
(least squares only, ``posterior=False``, forward selection up to ``--max-effects``) must
name every effect of the case with its location (``hidden_pairs.judge``); on the null
data it must answer ``none``.  Prints the rate per case with the exact one-sided 95 %
Clopper-Pearson bound, the effects found when wrong, the seconds per data set, and
writes JSON (rewritten after every data set, so a partial run keeps its rows).

Usage::

    python benchmarks/detection_pairs.py --seeds 20 --nulls 50 --workers 2 --out pairs.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from multiprocessing import Pool
from pathlib import Path

# the hidden-effect cases live in tests/
_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "tests"))

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

SEED_OFFSET = 20_000  # disjoint from the tests' seeds and from detection.py's


def _job(args):
    case, seed, n_null, n_samples, max_effects = args
    import warnings

    from hidden_effects import make
    from hidden_pairs import judge, make_case

    from bayesmodal.discrepancy.diagnosis import diagnose

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    h = make(None, seed, n_samples) if case == "none" else make_case(case, seed, n_samples)
    try:
        d = diagnose(h.experiment, posterior=False, n_null=n_null, rng=seed,
                     max_effects=max_effects)
        if case == "none":
            ok, found = d.cause == "none", [(c.cause, c.location) for c in d.causes]
        else:
            ok, found = judge(h, d)
        err = None
    except Exception as exc:  # record, do not stop the benchmark
        ok, found, err = False, [], f"{type(exc).__name__}: {exc}"
    truth = {} if case == "none" else h.effects
    return {"case": case, "seed": seed, "truth": truth, "found": found, "correct": bool(ok),
            "error": err, "seconds": time.perf_counter() - t0}


def _bound(k, n, upper):
    """Exact one-sided 95 % Clopper-Pearson bound of a binomial rate."""
    if upper:
        return 1.0 if k == n else float(stats.beta.ppf(0.95, k + 1, n - k))
    return 0.0 if k == 0 else float(stats.beta.ppf(0.05, k, n - k + 1))


def table(rows, cases):
    out = {}
    for case in ["none"] + list(cases):
        sel = [r for r in rows if r["case"] == case]
        if not sel:
            continue
        k, n = sum(r["correct"] for r in sel), len(sel)
        if case == "none":
            fp = n - k
            out[case] = {"n": n, "false_positives": fp, "rate": fp / n,
                         "upper_95": _bound(fp, n, True)}
        else:
            out[case] = {"n": n, "correct": k, "rate": k / n, "lower_95": _bound(k, n, False)}
        out[case]["wrong"] = [r["found"] for r in sel if not r["correct"]]
        out[case]["median_seconds"] = float(np.median([r["seconds"] for r in sel]))
    return out


def main(argv=None) -> int:
    from hidden_pairs import CASES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="experiments per case")
    ap.add_argument("--nulls", type=int, default=50, help="experiments without an effect")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--calibration-nulls", type=int, default=19,
                    help="null data sets of each calibration inside diagnose (default 19)")
    ap.add_argument("--samples", type=int, default=2400, help="record length (5 ms samples)")
    ap.add_argument("--max-effects", type=int, default=3)
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    ap.add_argument("--out", default="detection_pairs.json", help="JSON output file")
    args = ap.parse_args(argv)
    jobs = []
    for s in range(max(args.seeds, args.nulls)):
        if s < args.nulls:
            jobs.append(("none", SEED_OFFSET + s, args.calibration_nulls, args.samples,
                         args.max_effects))
        if s < args.seeds:
            jobs += [(c, SEED_OFFSET + s, args.calibration_nulls, args.samples,
                      args.max_effects) for c in args.cases]
    t0 = time.perf_counter()
    rows = []
    with Pool(max(1, args.workers)) as pool:
        for i, r in enumerate(pool.imap_unordered(_job, jobs), 1):
            rows.append(r)
            print(f"[{i}/{len(jobs)}] {r['case']:32s} seed {r['seed']}: {r['found']} "
                  f"{'ok' if r['correct'] else 'WRONG'} {r['seconds']:.0f} s", flush=True)
            Path(args.out).write_text(json.dumps(
                {"table": table(rows, args.cases), "rows": rows, "args": vars(args),
                 "complete": i == len(jobs), "wall_seconds": time.perf_counter() - t0},
                indent=2))
    print()
    for case, t in table(rows, args.cases).items():
        if case == "none":
            print(f"{'null data':32s} {t['n']:4d}  false positives {100 * t['rate']:5.1f} % "
                  f"(95 % upper {100 * t['upper_95']:.1f} %)")
        else:
            print(f"{case:32s} {t['n']:4d}  correct {100 * t['rate']:5.1f} % "
                  f"(95 % lower {100 * t['lower_95']:.1f} %)  {t['median_seconds']:.0f} s")
    print(f"\nwrote {args.out} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
