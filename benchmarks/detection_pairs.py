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
``--resume`` reads that file and runs only the data sets it lacks, so a run that was stopped
goes on where it stopped (the file's settings must match the command's).

Usage::

    python benchmarks/detection_pairs.py --seeds 20 --nulls 50 --workers 2 --out pairs.json
    python benchmarks/detection_pairs.py --seeds 20 --nulls 50 --out pairs.json --resume
    python benchmarks/detection_pairs.py --records 2 --cases input_offset drive_deadband \
        --seeds 13 --nulls 13 --workers 1 --out pairs2.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

# the hidden-effect cases live in tests/
_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "tests"))
sys.path.insert(0, str(_HERE.parent / "docs"))  # docs/_stamp.py

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

SEED_OFFSET = 20_000  # disjoint from the tests' seeds and from detection.py's


def _records(e, seed: int, n_records: int) -> list:
    """``n_records`` training records of one rig: ``e`` and copies of its response with
    more sensor noise (half an encoder count, rms), quantised again (same input; the
    tests' two-record data too).  Several records switch diagnose to its several-record
    test (AR(1) or output error) and the leave-one-record-out test."""
    from bayesmodal.data import ECP_M_PER_COUNT as q
    from bayesmodal.data import Experiment

    out = [e]
    rng = np.random.default_rng(seed + 1)
    for k in range(1, n_records):
        y = np.round((e.y_m + rng.normal(0, 0.5 * q, e.y_m.shape)) / q) * q
        out.append(Experiment(e.t_s, e.v_volt, y, name=f"{e.name}-{k}"))
    return out


def _job(args):
    case, seed, n_null, n_samples, max_effects, n_records = args
    import warnings

    from hidden_effects import make
    from hidden_pairs import judge, make_case

    from bayesmodal.discrepancy.diagnosis import diagnose

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    h = make(None, seed, n_samples) if case == "none" else make_case(case, seed, n_samples)
    try:
        exps = _records(h.experiment, seed, n_records)
        d = diagnose(exps, train=list(range(n_records)), posterior=False, n_null=n_null,
                     rng=seed, max_effects=max_effects)
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


#: settings a resumed run must share with the stored rows (the rest may differ)
SAME_SETTINGS = ("calibration_nulls", "samples", "max_effects", "records")


def _stored_rows(path: Path, args) -> list:
    """Rows of an earlier run in ``path`` made with the same settings, for ``--resume``."""
    if not path.exists():
        return []
    old = json.loads(path.read_text())
    for key in SAME_SETTINGS:
        stored = old["args"].get(key, 1 if key == "records" else None)
        if stored != getattr(args, key):
            raise SystemExit(f"--resume: {path} was made with {key} = {stored}, "
                             f"this command has {getattr(args, key)}; use another --out")
    return old["rows"]


def main(argv=None) -> int:
    from _stamp import stamp  # date, commit and machine of the output
    from hidden_pairs import CASES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="experiments per case")
    ap.add_argument("--nulls", type=int, default=50, help="experiments without an effect")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--calibration-nulls", type=int, default=19,
                    help="null data sets of each calibration inside diagnose (default 19)")
    ap.add_argument("--samples", type=int, default=2400, help="record length (5 ms samples)")
    ap.add_argument("--max-effects", type=int, default=3)
    ap.add_argument("--records", type=int, default=1,
                    help="training records per data set: the case's record and re-noised "
                    "copies of it (default 1; 2 or more test the several-record criterion)")
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    ap.add_argument("--out", default="detection_pairs.json", help="JSON output file")
    ap.add_argument("--resume", action="store_true",
                    help="keep the rows already in --out and run only the missing data sets")
    args = ap.parse_args(argv)
    rows = _stored_rows(Path(args.out), args) if args.resume else []
    done = {(r["case"], r["seed"]) for r in rows}
    # the null sets first (seconds each), then the cases seed by seed, so a partial run
    # has every case at about the same number of seeds
    wanted = [("none", SEED_OFFSET + s) for s in range(args.nulls)]
    wanted += [(c, SEED_OFFSET + s) for s in range(args.seeds) for c in args.cases]
    if args.records < 1:
        raise SystemExit(f"--records must be at least 1, got {args.records}")
    jobs = [(c, s, args.calibration_nulls, args.samples, args.max_effects, args.records)
            for c, s in wanted if (c, s) not in done]
    cases = list(dict.fromkeys(list(args.cases) + [r["case"] for r in rows if r["case"] != "none"]))
    t0 = time.perf_counter()
    from bayesmodal._blas import blas_pool  # a BLAS share per process
    with blas_pool(max(1, args.workers)) as pool:
        for i, r in enumerate(pool.imap_unordered(_job, jobs), 1):
            rows.append(r)
            print(f"[{i}/{len(jobs)}] {r['case']:32s} seed {r['seed']}: {r['found']} "
                  f"{'ok' if r['correct'] else 'WRONG'} {r['seconds']:.0f} s", flush=True)
            Path(args.out).write_text(json.dumps(
                {"table": table(rows, cases), "rows": rows, "args": vars(args),
                 "complete": i == len(jobs), "wall_seconds": time.perf_counter() - t0,
                 "stamp": stamp()},
                indent=2))
    print()
    for case, t in table(rows, cases).items():
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
