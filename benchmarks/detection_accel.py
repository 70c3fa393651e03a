"""Detection benchmark on accelerometer records: hidden effects and null data.

On the two-cart rig read by an accelerometer on each cart (``tests/hidden_accel.py``:
independent reference simulators, accelerometer noise, 16-bit quantisation), ``--seeds``
records per case hide coulomb_friction, an end stop or a cubic spring at sizes and
locations drawn from the seed; ``--nulls`` records hide nothing.  ``diagnose`` (least
squares only; the default catalogue and the end stop, less what the rig cannot carry on
accelerometers) must name the effect with its location, and ``none`` on the null
records.  Prints the rate per case (goal >= 95 %) with its binomial standard error, and
writes JSON; a missed record lists what was named instead.

Usage::

    python benchmarks/detection_accel.py --seeds 20 --nulls 50 --workers 1 \\
        --out detection_accel.json
    python benchmarks/detection_accel.py --cases end_stop --seeds 3 --nulls 0

With ``--out``, every diagnosis is written as soon as it is done, and a run given an
existing file keeps its rows and runs only the rest (resume after a stop).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

_TESTS = Path(__file__).resolve().parent.parent / "tests"
sys.path.insert(0, str(_TESTS))
sys.path.insert(0, str(_TESTS.parent / "docs"))  # docs/_stamp.py

from detection_layouts import _done_rows, _pool, _write, summarise  # noqa: E402

SEED_OFFSET = 30_000  # benchmark seeds never coincide with the tests' seeds
N_NULL = 19  # null sets of each diagnosis' own calibration (5 % false positives)
LAYOUT = "accelerometers"


def candidates(rig) -> tuple[str, ...]:
    """The default catalogue and the end stop, less what ``rig`` cannot carry."""
    from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES
    from bayesmodal.model.effects import EXTENSIONS

    return tuple(c for c in (*DEFAULT_CANDIDATES, "end_stop")
                 if not EXTENSIONS[c].unsupported(rig))


def run_one(args) -> dict:
    case, seed, n_samples = args
    import warnings

    from hidden_accel import accel_rig, make_accel_case
    from hidden_pairs import judge

    from bayesmodal.discrepancy.diagnosis import diagnose

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    h = make_accel_case(case, seed, n_samples)
    rig = accel_rig()
    ranking = []
    try:
        d = diagnose(h.experiment, rig=rig, posterior=False, n_null=N_NULL, rng=seed,
                     candidates=candidates(rig))
        ok, found = judge(h, d)
        err = None
        # why a record is missed: the first step's scores (BIC gain) of the fitted ones
        ranking = [[s.name, float(s.score), bool(s.significant), bool(s.passes)]
                   for s in d.ranking if s.fitted]
        t_stat = [float(d.statistic), float(d.threshold)]
    except Exception as exc:  # record, do not stop the benchmark
        ok, found, err, t_stat = False, [], f"{type(exc).__name__}: {exc}", None
    return {"layout": LAYOUT, "case": case, "seed": seed, "correct": bool(ok),
            "found": [[k, v] for k, v in found], "truth": h.effects, "sizes": h.sizes,
            "statistic_threshold": t_stat, "ranking": ranking, "error": err,
            "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    from hidden_accel import CASES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(c for c in CASES if c != "none"))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--nulls", type=int, default=50)
    ap.add_argument("--samples", type=int, default=2400)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    # seed by seed across the cases, so that a run stopped early has every case
    cases = [c for c in a.cases.split(",") if c]
    jobs = []
    for s in range(max(a.seeds, a.nulls)):
        jobs += [(case, SEED_OFFSET + s, a.samples) for case in cases if s < a.seeds]
        jobs += [("none", SEED_OFFSET + 1000 + s, a.samples)] if s < a.nulls else []
    # rows already in --out are kept (a long run resumes where it stopped); each new
    # diagnosis is written as soon as it is done
    rows = _done_rows(a.out, a.samples)
    done = {(r["case"], r["seed"]) for r in rows}
    todo = [j for j in jobs if j[:2] not in done]
    t0 = time.perf_counter()
    with _pool(a.workers) as pool:
        for row in pool.imap_unordered(run_one, todo, chunksize=1):
            rows.append(row)
            if a.out:
                _write(a.out, rows, a.samples)
    table = summarise(rows)
    print(f"{'case':<20} {'n':>4} {'rate':>7} {'se':>6}")
    for r in table:
        print(f"{r['case']:<20} {r['n']:>4} {r['rate']:>7.1%} {r['se']:>6.1%}")
    print(f"{len(todo)} diagnoses in {time.perf_counter() - t0:.0f} s ({len(rows)} in the table)")
    for r in rows:
        if not r["correct"]:
            print("missed:", r["case"], r["seed"], r["found"], r["truth"],
                  r["statistic_threshold"], r["ranking"][:3], r["error"] or "")
    if a.out:
        _write(a.out, rows, a.samples)
    return 0



if __name__ == "__main__":
    raise SystemExit(main())

