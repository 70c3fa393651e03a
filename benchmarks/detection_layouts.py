"""Detection benchmark on several rig layouts: hidden effects and null data.

For every layout of ``tests/hidden_layouts.py`` (one cart, two carts with the frame
spring at the driven cart, the three-cart chain) and every case there (single effects and
pairs), ``--seeds`` records hide the case at sizes and locations drawn from the seed
(independent reference simulators, noise, quantisation); ``--nulls`` records per layout
hide nothing.  ``diagnose`` (least squares only, the default catalogue and the end stop)
must name every effect of the case with its location, and ``none`` on the null records.
Prints the rate per layout and case (goal >= 95 %) with its binomial standard error, and
writes JSON.

Usage::

    python benchmarks/detection_layouts.py --seeds 20 --nulls 50 --workers 2 \\
        --out detection_layouts.json
    python benchmarks/detection_layouts.py --layouts two_frame_at_drive --cases \\
        coulomb_friction,end_stop --seeds 3 --nulls 0

With ``--slow-drive`` every record goes on with a slow triangle of the drive
(``hidden_layouts.slow_triangle``, half as many samples again): on one cart, friction
with a drive offset and directional friction move the cart alike under pulses and steps
alone.

With ``--out``, every diagnosis is written as soon as it is done, and a run given an
existing file keeps its rows and runs only the rest (resume after a stop).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

_TESTS = Path(__file__).resolve().parent.parent / "tests"
sys.path.insert(0, str(_TESTS))
sys.path.insert(0, str(_TESTS.parent / "docs"))  # docs/_stamp.py

import numpy as np  # noqa: E402

SEED_OFFSET = 20_000  # benchmark seeds never coincide with the tests' seeds
N_NULL = 19  # null sets of each diagnosis' own calibration (5 % false positives)


def candidates() -> tuple[str, ...]:
    from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES

    return tuple(DEFAULT_CANDIDATES) + ("end_stop",)


def run_one(args) -> dict:
    layout, case, seed, n_samples, slow = args
    import warnings

    from hidden_layouts import layout_rig, make_layout_case
    from hidden_pairs import judge

    from bayesmodal.discrepancy.diagnosis import diagnose

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    h = make_layout_case(layout, case, seed, n_samples, slow_drive=slow)
    rig = layout_rig(layout)
    try:
        d = diagnose(h.experiment, rig=rig, posterior=False, n_null=N_NULL, rng=seed,
                     candidates=candidates())
        ok, found = judge(h, d)
        err, notes = None, list(d.notes)
    except Exception as exc:  # record, do not stop the benchmark
        ok, found, err, notes = False, [], f"{type(exc).__name__}: {exc}", []
    return {"layout": layout, "case": case, "seed": seed, "correct": bool(ok),
            "found": [[k, v] for k, v in found], "truth": h.effects, "sizes": h.sizes,
            "error": err, "notes": notes, "seconds": time.perf_counter() - t0,
            "slow_drive": bool(slow)}


def summarise(rows: list[dict]) -> list[dict]:
    """Rate and binomial standard error per layout and case."""
    out = []
    keys = sorted({(r["layout"], r["case"]) for r in rows})
    for layout, case in keys:
        ok = np.array([r["correct"] for r in rows if (r["layout"], r["case"]) == (layout, case)])
        p = ok.mean()
        out.append({"layout": layout, "case": case, "n": int(ok.size), "rate": float(p),
                    "se": float(np.sqrt(max(p * (1 - p), 1e-12) / ok.size))})
    return out


def main(argv=None) -> int:
    from hidden_layouts import CASES, LAYOUTS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", default=",".join(LAYOUTS))
    ap.add_argument("--cases", default=",".join(c for c in CASES if c != "none"))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--nulls", type=int, default=50)
    ap.add_argument("--samples", type=int, default=2400)
    ap.add_argument("--slow-drive", action="store_true",
                    help="records go on with a slow triangle of the drive")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    slow = bool(a.slow_drive)
    jobs = [(lay, case, SEED_OFFSET + s, a.samples, slow) for lay in a.layouts.split(",")
            for case in a.cases.split(",") if case for s in range(a.seeds)]
    jobs += [(lay, "none", SEED_OFFSET + 1000 + s, a.samples, slow)
             for lay in a.layouts.split(",") for s in range(a.nulls)]
    # rows already in --out are kept (a long run resumes where it stopped); each new
    # diagnosis is written as soon as it is done
    rows = _done_rows(a.out, a.samples)
    if any(r.get("slow_drive", False) != slow for r in rows):
        raise SystemExit(f"{a.out} holds diagnoses of records {'without' if slow else 'with'}"
                         " the slow drive; give another --out")
    done = {(r["layout"], r["case"], r["seed"]) for r in rows}
    todo = [j for j in jobs if j[:3] not in done]
    t0 = time.perf_counter()
    with _pool(a.workers) as pool:
        for row in pool.imap_unordered(run_one, todo, chunksize=1):
            rows.append(row)
            if a.out:
                _write(a.out, rows, a.samples)
    table = summarise(rows)
    print(f"{'layout':<20} {'case':<33} {'n':>4} {'rate':>7} {'se':>6}")
    for r in table:
        print(f"{r['layout']:<20} {r['case']:<33} {r['n']:>4} {r['rate']:>7.1%} {r['se']:>6.1%}")
    print(f"{len(todo)} diagnoses in {time.perf_counter() - t0:.0f} s ({len(rows)} in the table)")
    for r in rows:
        if not r["correct"]:
            print("missed:", r["layout"], r["case"], r["seed"], r["found"], r["truth"],
                  r["error"] or "")
    if a.out:
        _write(a.out, rows, a.samples)
    return 0


def _pool(workers: int):
    """``workers`` processes, each with its share of the cores for BLAS, or this process
    for one (``_Serial``)."""
    if workers <= 1:
        return _Serial()
    from bayesmodal._blas import blas_pool

    return blas_pool(workers)


class _Serial:
    """``Pool``'s ``imap_unordered`` in this process (``--workers 1``)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    @staticmethod
    def imap_unordered(fn, jobs, chunksize=1):
        return map(fn, jobs)


def _done_rows(out: Path | None, n_samples: int) -> list[dict]:
    """The rows of an earlier run in ``out`` (empty without one); refused when that run
    used records of another length."""
    if out is None or not out.exists():
        return []
    old = json.loads(out.read_text())
    if old.get("samples", n_samples) != n_samples:
        raise SystemExit(f"{out} holds diagnoses of {old['samples']}-sample records, this "
                         f"run asks for {n_samples}; give another --out")
    # rows of a run that did not record their commit take the commit of its stamp
    earlier = (old.get("stamp") or {}).get("commit")
    return [r if "commit" in r else {**r, "commit": earlier} for r in old["rows"]]


def _commits(rows: list[dict]) -> str | None:
    """The commits that made ``rows`` (each row's ``commit``), in order, with their row
    counts when several (a resumed run's rows may come from several commits)."""
    counts = Counter(r.get("commit") for r in rows)
    if len(counts) <= 1:
        return next(iter(counts), None)
    return ", ".join(f"{c} ({n} rows)" for c, n in counts.items())


def _write(out: Path, rows: list[dict], n_samples: int) -> None:
    from _stamp import stamp  # date, commit and machine of the output

    st = stamp()
    for r in rows:
        r.setdefault("commit", st["commit"])
    st["commit"] = _commits(rows)
    out.write_text(json.dumps({"samples": n_samples, "table": summarise(rows), "rows": rows,
                               "stamp": st}, indent=1, default=str))


if __name__ == "__main__":
    raise SystemExit(main())
