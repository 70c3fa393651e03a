"""One noise level for every record, or one per record size: leave-one-record-out tables.

Makes the tables of docs/uncertainty.md, "A noise level per record size": the main job's
leave-one-record-out study (``runs/records_free.toml``: gain population, one input offset,
AR(1) noise, its ``[crossval]`` sampler settings) with the noise level shared in metres
(``noise_scale = "none"``) and sized by each record's simulated response
(``"response"``, the main job's setting), and with ``--final`` the same study of the final
model of docs/discrepancy.md (stick-slip friction per cart, drive dead band, one input
offset, one gain; scaled level; Laplace start).  Per held-out record and cart: coverage of
the 90 % band, its width over the record's standard deviation, the fit of the predictive
median, the record's log predictive density and the fold's largest R-hat; per study the
number of record-cart cells covered 80-95 %, the mean width and the summed lpd with its
standard error.

Usage (needs the measured data; on 2 idle cores about 6 minutes, 15 with ``--final``)::

    python docs/make_noise_scale_table.py [--final] [--workers 2]

Writes ``docs/figures/noise_scale.json`` and ``docs/figures/noise_scale.md``.
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

ROOT = Path(__file__).resolve().parents[1]
#: The final model of docs/discrepancy.md, nothing per record.
FINAL = "coulomb_friction+input_offset+drive_deadband"


def studies(final: bool) -> dict:
    """The studies by label: ``CrossvalSpec`` of each."""
    base = load_config(ROOT / "runs" / "records_free.toml").crossval_spec()
    per = base.layout.per_record
    out = {"linear, one level (m)": replace(base, layout=RecordLayout(per)),
           "linear, level per response size": replace(
               base, layout=RecordLayout(per, noise_scale="response"))}
    if final:
        out["final model, level per response size"] = replace(
            base, extension=FINAL, layout=RecordLayout({}, noise_scale="response"),
            n_walkers=48, init="laplace")
    return out


def summarise(result, wall_s: float) -> dict:
    recs = {}
    for fold in result.folds:
        d = fold.to_dict()
        recs[fold.heldout] = {
            "coverage_90": np.round(100 * np.asarray(d["coverage_90"]), 1).tolist(),
            "width_90": np.round(d["width_90"], 2).tolist(),
            "fit_percent": np.round(d["fit_percent"], 1).tolist(),
            "lpd": round(float(d["lpd"])), "max_rhat": round(float(fold.max_rhat), 3)}
    cov = np.array([r["coverage_90"] for r in recs.values()])
    width = np.array([r["width_90"] for r in recs.values()])
    total = result.to_dict()["total"]
    return {"records": recs, "cells_in_80_95": int(np.sum((cov >= 80) & (cov <= 95))),
            "cells": int(cov.size), "mean_width": round(float(width.mean()), 2),
            "lpd": round(total["lpd"]), "lpd_se": round(total["lpd_se"]),
            "wall_s": round(wall_s)}


def markdown(out: dict) -> str:
    lines = ["| study | held-out record | 90 % band covers (carts 1-3) | width / sd | "
             "fit % of the median | lpd (nats) | fold R-hat |", "|---|---|---|---|---|---|---|"]
    for label, s in out.items():
        for name, r in s["records"].items():
            lines.append(f"| {label} | {name} | {', '.join(f'{c:.0f}' for c in r['coverage_90'])}"
                         f" | {', '.join(f'{w:.2f}' for w in r['width_90'])} | "
                         f"{', '.join(f'{f:.1f}' for f in r['fit_percent'])} | {r['lpd']} | "
                         f"{r['max_rhat']} |")
    lines += ["", "| study | cells covered 80-95 % | mean width / sd | summed lpd (nats) | "
              "wall time (s) |", "|---|---|---|---|---|"]
    for label, s in out.items():
        lines.append(f"| {label} | {s['cells_in_80_95']} of {s['cells']} | {s['mean_width']} "
                     f"| {s['lpd']} +- {s['lpd_se']} | {s['wall_s']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--final", action="store_true", help="also the final friction model")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "noise_scale"),
                    help="output path without suffix (.json and .md are written)")
    args = ap.parse_args(argv)
    run_studies(studies(args.final), summarise, args.out, markdown, workers=args.workers)
    return 0


if __name__ == "__main__":
    sys.exit(main())
