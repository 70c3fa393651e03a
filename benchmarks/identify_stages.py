"""Where the time of ``bayesmodal identify`` goes: each stage's wall time and rate.

Runs the workflow of CONFIG into OUT (reusing every stage already there, so that a
finished folder is only read) and prints one row per stage: wall time, the sampler's
evaluations per second and bulk ESS per second where it samples, and the leave-one-
record-out check's wall time and its folds' rates.  The table in docs/performance.md
("The identify workflow") comes from this script on the four measured records.

    python benchmarks/identify_stages.py runs/records_free.toml --out runs/records_identify

Timings of a stage reused from the folder are those recorded when it ran (timing.json,
diagnosis.json), so the table describes the folder's runs, not this call.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bayesmodal.runs.config import load_config
from bayesmodal.runs.identify import IdentifySpec, identify


def _run_rows(folder: Path, label: str) -> list[tuple]:
    timing = json.loads((folder / "timing.json").read_text())
    summary = json.loads((folder / "summary.json").read_text())
    perf = timing.get("performance") or {}
    cv = summary.get("crossval") or {}
    rows = [(f"{label}: posterior", perf.get("sampling_time_s"),
             perf.get("evaluations_per_s"), perf.get("ess_per_s"),
             summary.get("diagnostics", {}).get("max_rhat"),
             summary.get("diagnostics", {}).get("min_ess"))]
    if cv:
        folds = cv.get("records") or []
        # the clock's numbers are in timing.json (in summary.json in older run folders)
        clock = timing.get("crossval") or {"wall_time_s": cv.get("wall_time_s"),
                                           "records": folds}
        rates = [f.get("evaluations_per_s") for f in clock["records"]
                 if f.get("evaluations_per_s")]
        rows.append((f"{label}: leave-one-record-out ({len(folds)} folds)",
                     clock.get("wall_time_s"), float(np.median(rates)) if rates else None, None,
                     max((f.get("max_rhat") or np.nan for f in folds), default=None),
                     min((f.get("min_ess") or np.nan for f in folds), default=None)))
    other = timing["wall_time_s"] - sum(r[1] or 0.0 for r in rows)
    rows.append((f"{label}: checks, plots, report", other, None, None, None, None))
    return rows


def stage_table(out: Path) -> list[tuple]:
    """Rows ``(stage, wall s, evaluations/s, ESS/s, max R-hat, min bulk ESS)``."""
    rows = _run_rows(out / "linear", "linear")
    diag = json.loads((out / "diagnosis.json").read_text())
    rows.append(("diagnosis", diag.get("elapsed_s"), None, None, None, None))
    if (out / "final" / "timing.json").is_file():
        rows += _run_rows(out / "final", "final")
    return rows


def _fmt(x, spec):
    return "-" if x is None or not np.isfinite(x) else format(x, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", help="the linear model's run configuration")
    ap.add_argument("--out", required=True, help="the workflow's folder")
    args = ap.parse_args(argv)
    out = Path(args.out)
    identify(IdentifySpec(load_config(args.config)), out, progress=True)
    rows = stage_table(out)
    print("| stage | wall (min) | evaluations/s | bulk ESS/s | max R-hat | min bulk ESS |")
    print("|---|---|---|---|---|---|")
    for name, wall, rate, ess, rhat, ess_min in rows:
        print(f"| {name} | {_fmt(None if wall is None else wall / 60, '.1f')} | "
              f"{_fmt(rate, '.0f')} | {_fmt(ess, '.1f')} | {_fmt(rhat, '.3f')} | "
              f"{_fmt(ess_min, '.0f')} |")
    total = sum(r[1] or 0.0 for r in rows)
    print(f"\ntotal {total / 60:.1f} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
