"""The temperature table of docs/uncertainty.md: a tempered posterior calibrated by
leave-one-record-out coverage on the four measured records.

    python docs/make_temperature_table.py --workers 2       # five studies, see --steps

For each temperature of the grid the default several-record model (AR(1), a gain per
record from its population, one shared offset) is sampled on three records and predicts the
fourth, for each record in turn (``bayesmodal.inference.temperature.calibrate_loro``); the
temperature at which the chosen criterion reaches 90 % coverage is interpolated in log T and
measured once more.  Writes ``docs/figures/temperature.json`` and ``temperature.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _stamp import stamp  # noqa: E402
from make_uncertainty_table import _load  # noqa: E402


def main(argv=None) -> int:
    from bayesmodal.inference.crossval import CrossvalSpec
    from bayesmodal.inference.temperature import calibrate_loro

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps per walker per fold")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--temperatures", default="1,10,100,1000")
    ap.add_argument("--criterion", default="worst", choices=["mean", "worst"])
    args = ap.parse_args(argv)
    exps = _load()
    t0 = time.perf_counter()
    spec = CrossvalSpec(n_walkers=48, n_steps=args.steps, seed=args.seed)
    cal, res = calibrate_loro(exps, spec, temperatures=[float(t) for t in
                                                        args.temperatures.split(",")],
                              criterion=args.criterion, workers=args.workers, joint=False,
                              progress=lambda line: print(f"  {line}", flush=True))
    out = {"calibration": cal.to_dict(), "at_chosen": res.to_dict(),
           "settings": vars(args), "wall_time_s": time.perf_counter() - t0, "stamp": stamp()}
    (HERE / "figures" / "temperature.json").write_text(json.dumps(out, indent=1))
    rows = ["| held-out record | 90 % band covers (carts 1, 2, 3) | width / sd "
            "| fit % of median | lpd (nats) | max R-hat |", "|---|---|---|---|---|---|"]
    for f in res.folds:
        s = f.scores
        rows.append(f"| {s.name} | {', '.join(f'{100 * c:.0f}' for c in s.coverage_90)} "
                    f"| {', '.join(f'{w:.2f}' for w in s.width_90)} "
                    f"| {', '.join(f'{x:.1f}' for x in s.fit_percent)} | {s.lpd:.0f} "
                    f"| {f.max_rhat:.2f} |")
    text = ("```\n" + cal.table() + "\n```\n\n"
            + f"At T = {cal.temperature:.4g} ({args.steps} steps per fold):\n\n"
            + "\n".join(rows) + "\n")
    (HERE / "figures" / "temperature.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
