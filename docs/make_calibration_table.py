"""Which noise model's held-out bands are calibrated by their own yardstick?

Makes the table of docs/uncertainty.md, "Noise models against their own yardstick": the
main job's leave-one-record-out study (``runs/records_free.toml``: gain population, one
input offset, its ``[crossval]`` sampler settings) with each noise model, scored by the
coverage reference of ``bayesmodal.inference.coverage_reference``: per held-out record the
coverage of the 90 % band and the factor that would make it cover 90 %, next to the range
a calibrated band shows on that record, their ranks, and whether the report's verdict
(``bayesmodal.runs.verdict.record_status``, family-wise over the four records) calls the
band too narrow, too wide or consistent.  Per study: records consistent, mean band width,
summed lpd.

Usage (needs the measured data; on 2 idle cores about 12 minutes, 45 with ``--slow``)::

    python docs/make_calibration_table.py [--slow] [--workers 2] [--only LABEL ...]

Writes ``docs/figures/calibration.json`` and ``docs/figures/calibration.md``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from _measured import run_studies  # docs/_measured.py (run as docs/<script>.py)

from bayesmodal.inference.record_layout import RecordLayout
from bayesmodal.runs.config import load_config
from bayesmodal.runs.verdict import record_status

ROOT = Path(__file__).resolve().parents[1]


def studies(slow: bool) -> dict:
    """The studies by label: ``CrossvalSpec`` of each."""
    base = load_config(ROOT / "runs" / "records_free.toml").crossval_spec()
    per = base.layout.per_record
    out = {
        "AR(1), level per response size (main job)": base,
        "AR(1), one level": replace(base, layout=RecordLayout(per)),
        "AR(1), level per response size, one gain for all records": replace(
            base, layout=RecordLayout({"v0": "shared"}, noise_scale="response")),
        "AR(1), noise parameters per record": replace(
            base, layout=RecordLayout(per, noise_per_record=True, noise_scale="response")),
        "white, level per response size": replace(base, noise="white"),
        "process noise": replace(base, noise="process", layout=RecordLayout(per)),
    }
    if slow:
        out["AR(p), p by BIC, level per response size"] = replace(base, noise="ar:auto")
        out["integrated AR(1), level per response size"] = replace(base, noise="iar1")
    return out


def summarise(result, wall_s: float) -> dict:
    recs = {}
    n = len(result.folds)
    for fold in result.folds:
        d = fold.to_dict()
        recs[fold.heldout] = {
            "coverage_90": np.round(100 * np.asarray(d["coverage_90"]), 1).tolist(),
            "coverage_90_expected": np.round(100 * np.asarray(d["coverage_90_expected"]),
                                             1).tolist(),
            "band_factor_90": np.round(d["band_factor_90"], 2).tolist(),
            "band_factor_90_expected": np.round(d["band_factor_90_expected"], 2).tolist(),
            "record_pit_90": round(d["record_pit_90"], 3),
            "record_band_factor_pit_90": round(d["record_band_factor_pit_90"], 3),
            "window_probability_90": round(d["window_probability_90"], 3),
            "status": record_status(d, n_records=n),
            "width_90": np.round(d["width_90"], 2).tolist(),
            "fit_percent": np.round(d["fit_percent"], 1).tolist(),
            "lpd": round(float(d["lpd"])), "max_rhat": round(float(fold.max_rhat), 3)}
    width = np.array([r["width_90"] for r in recs.values()])
    total = result.to_dict()["total"]
    return {"records": recs,
            "consistent": sum(r["status"] == "ok" for r in recs.values()),
            "n_records": n, "mean_width": round(float(width.mean()), 2),
            "window_probability_all": total["calibration"]["window_probability_all"],
            "lpd": round(total["lpd"]), "lpd_se": round(total["lpd_se"]),
            "wall_s": round(wall_s)}


def _pairs(pairs, fmt):
    return ", ".join(f"{format(a, fmt)}-{format(b, fmt)}" for a, b in pairs)


def markdown(out: dict) -> str:
    lines = ["| study | held-out record | 90 % covers (carts 1-3) | calibrated | x90 | "
             "calibrated x90 | ranks: coverage, x90 | verdict | width / sd | fold R-hat |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for label, s in out.items():
        for name, r in s["records"].items():
            lines.append(
                f"| {label} | {name} | {', '.join(f'{c:.0f}' for c in r['coverage_90'])} | "
                f"{_pairs(r['coverage_90_expected'], '.0f')} | "
                f"{', '.join(f'{x:.2f}' for x in r['band_factor_90'])} | "
                f"{_pairs(r['band_factor_90_expected'], '.2f')} | "
                f"{r['record_pit_90']:.2f}, {r['record_band_factor_pit_90']:.2f} | "
                f"{r['status']} | {', '.join(f'{w:.2f}' for w in r['width_90'])} | "
                f"{r['max_rhat']} |")
    lines += ["", "| study | records consistent with a calibrated band | mean width / sd | "
              "P(calibrated bands meet 80-95 % on all cells) | summed lpd (nats) | "
              "wall time (s) |", "|---|---|---|---|---|---|"]
    for label, s in out.items():
        lines.append(f"| {label} | {s['consistent']} of {s['n_records']} | {s['mean_width']} "
                     f"| {s['window_probability_all']:.3f} | {s['lpd']} +- {s['lpd_se']} | "
                     f"{s['wall_s']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slow", action="store_true", help="also AR(p) and integrated AR(1)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", action="append", help="run only this study (repeatable)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "calibration"),
                    help="output path without suffix (.json and .md are written)")
    args = ap.parse_args(argv)
    run_studies(studies(args.slow), summarise, args.out, markdown, workers=args.workers,
                only=args.only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
