"""How big each measured record's misfit is against its response (docs/uncertainty.md).

The linear model fitted to the four records together (least squares, then the main job's
per-record gains and shared offset at their start), and per record: the RMS of the
model's response to the input, of its quasi-static part (``K^-1 b v``) subtracted from it,
and of the residual, with the residual's share of each.  About 10 s.

Usage::

    python docs/make_misfit_shares.py [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measured import measured_records  # noqa: E402

from bayesmodal.fit import fit_lsq  # noqa: E402
from bayesmodal.inference.record_layout import parse_layout  # noqa: E402
from bayesmodal.inference.record_priors import records_start  # noqa: E402
from bayesmodal.inference.records import RecordsLikelihood  # noqa: E402
from bayesmodal.model.system import LinearModel, Rig  # noqa: E402


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    exps = measured_records()
    model = LinearModel(Rig(), "free")
    lsq = fit_lsq(exps, model)
    lik = RecordsLikelihood(model, exps, "ar1", None,
                            parse_layout("g_v=hierarchical, v0=shared", noise_scale="response"),
                            scale_at=lsq.theta)
    preds = lik.predict_theta(records_start(lik, lsq.theta)[None])
    _, _, k, b = model.matrices(lsq.theta)
    static = np.linalg.solve(k, b).ravel()        # m per V at the fit's gain
    rows = []
    print("record                  response mm  dynamic mm  residual mm  "
          "residual/response  residual/dynamic")
    for r, e in enumerate(exps):
        y = lik.predict_mech(lsq.theta[None], np.zeros(1), e)[0]
        dyn = y - np.outer(e.v_volt, static)
        res = e.y_m - preds[r][0]
        # the response's RMS is the likelihood's own record size (record_scale)
        row = {"name": e.name, "response_m": float(lik.record_scales.rms_m[r]),
               "dynamic_m": _rms(dyn),
               "residual_m": _rms(res)}
        rows.append(row)
        print(f"{e.name:22s} {1e3 * row['response_m']:11.2f} {1e3 * row['dynamic_m']:11.2f} "
              f"{1e3 * row['residual_m']:12.2f} {row['residual_m'] / row['response_m']:18.3f} "
              f"{row['residual_m'] / row['dynamic_m']:17.3f}")
    if args.json:
        from _stamp import stamp  # docs/_stamp.py

        args.json.write_text(json.dumps({"rows": rows, "stamp": stamp()}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
