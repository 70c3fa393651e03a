"""Is the discrepancy of the measured records proportional to each record's size?

A check for docs/uncertainty.md ("A noise level per record size").  The main job's
leave-one-record-out bands (AR(1) noise, one level per cart shared by the records) are too
narrow on the impulses and far too wide on the sweeps, while the linear model's relative
misfit (residual RMS over the record's RMS) is about the same on every record.  If the
discrepancy scales with the record, one shared *relative* level should give bands of one
width in record units and coverage near 90 % everywhere.

The check needs no new likelihood: each record's input and outputs are divided by one
number ``c_r`` (its RMS cart position over the geometric mean of the four), which leaves
the linear model unchanged (``y / c = model(v / c)``) and turns a shared noise level into
one proportional to ``c_r``.  ``c_r`` is read from the record's own positions: an oracle
that a scale predicted by the model (or from the input's amplitude) would approximate.
Both studies use the main job's settings (``runs/records_free.toml``) with the input offset
per record from its population (``v0 = "hierarchical"``: a shared offset in volts is not
invariant under the scaling), so the two rows differ only by the scaling.

Usage (about 10 minutes on 2 idle cores; needs the measured data)::

    python docs/make_scaled_noise_check.py [--workers 2] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from _measured import RECORDS, measured_records  # docs/_measured.py
from _stamp import stamp  # docs/_stamp.py

from bayesmodal.data import Experiment
from bayesmodal.inference.crossval import crossval
from bayesmodal.inference.record_layout import parse_layout
from bayesmodal.runs.config import load_config

ROOT = Path(__file__).resolve().parents[1]


def scales(exps) -> np.ndarray:
    """``c_r``: each record's RMS mean-removed cart position over their geometric mean."""
    rms = np.array([np.sqrt(np.mean((e.y_m - e.y_m.mean(0)) ** 2)) for e in exps])
    return rms / np.exp(np.mean(np.log(rms)))


def scaled(exps, c) -> list[Experiment]:
    return [Experiment(e.t_s, e.v_volt / ci, e.y_m / ci, name=e.name)
            for e, ci in zip(exps, c, strict=True)]


def rows(result) -> dict:
    out = {}
    for fold in result.folds:
        d = fold.to_dict()
        out[fold.heldout] = {"coverage_90": np.round(100 * np.asarray(d["coverage_90"])).tolist(),
                             "width_90": np.round(d["width_90"], 2).tolist(),
                             "fit_percent": np.round(d["fit_percent"], 1).tolist(),
                             "max_rhat": round(float(fold.max_rhat), 3)}
    return out


def table(out: dict) -> str:
    """The stored result as the Markdown table the script prints: per study and held-out
    record, the record's scale and the 90 % band's coverage, width, fit and R-hat."""
    names = {"shared_level": "one level shared by the records",
             "record_scaled": "each record divided by its scale"}
    lines = ["| study | held-out record | scale c_r | 90 % band covers (carts 1-3) | "
             "width / sd | fit % of the median | fold R-hat |", "|---|---|---|---|---|---|---|"]
    for label in ("shared_level", "record_scaled"):
        for name, r in out[label].items():
            lines.append(f"| {names[label]} | {name} | {out['scale'][name]} | "
                         f"{', '.join(f'{c:.0f}' for c in r['coverage_90'])} | "
                         f"{', '.join(f'{w:.2f}' for w in r['width_90'])} | "
                         f"{', '.join(f'{f:.1f}' for f in r['fit_percent'])} | "
                         f"{r['max_rhat']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "scaled_noise_check.json"))
    args = ap.parse_args(argv)
    exps = measured_records()
    cfg = load_config(ROOT / "runs" / "records_free.toml")
    spec = replace(cfg.crossval_spec(),
                   layout=parse_layout("g_v=hierarchical,v0=hierarchical"))
    c = scales(exps)
    out = {"scale": dict(zip(RECORDS, np.round(c, 4).tolist(), strict=True)),
           "settings": "runs/records_free.toml, v0 = hierarchical"}
    for label, data in (("shared_level", exps), ("record_scaled", scaled(exps, c))):
        res = crossval(data, spec, workers=args.workers, joint=False,
                       progress=lambda line: print(line, file=sys.stderr))
        out[label] = rows(res)
    out["stamp"] = stamp()
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(table(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
