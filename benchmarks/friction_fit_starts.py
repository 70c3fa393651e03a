"""Where the least-squares fit of stick-slip friction ends, against where it starts.

The pair cases of forward selection that end wrong (docs/diagnose.md, "Several effects")
carry friction on one cart behind an input effect.  This script takes one such data set
(``tests/hidden_pairs.py``, case ``--case``, seed ``--seed``: the independent reference
simulator, sensor noise, encoder counts) and fits the true model structure by least
squares (``fit_extension_lsq``) from:

- the package's own starts (``best_starts``: start grids, one cart at a time, dampers
  scaled), as the first step of ``diagnose`` does;
- the true parameters (the optimum's basin, a reference);
- each start of the grid "one cart's friction x the input effect's grid" on the linear
  fit, in the order of its start cost (sum of squares), and in the order of its AR(1)
  log density.

For each it prints the AR(1) log density of the fitted model (the criterion forward
selection judges by, ``ar1_pointwise``) next to the truth's.  A fit far below the truth
means the nested comparison of that step judges an optimiser's stop, not the data.

Usage::

    python benchmarks/friction_fit_starts.py                     # friction + dead band, seed 1
    python benchmarks/friction_fit_starts.py --case coulomb_friction+input_offset --seed 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "tests"))

import numpy as np  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", default="coulomb_friction+drive_deadband")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--samples", type=int, default=2400)
    ap.add_argument("--fits", type=int, default=3, help="fits from the top of each ranking")
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)

    from hidden_pairs import make_case

    from bayesmodal.discrepancy.diagnosis.gains import _lpd
    from bayesmodal.discrepancy.diagnosis.starts import best_starts, extra_starts
    from bayesmodal.fit import fit_extension_lsq, fit_lsq
    from bayesmodal.fit.effects import extension_residuals
    from bayesmodal.model.effects import get_extension
    from bayesmodal.model.system import LinearModel, Rig

    h = make_case(args.case, args.seed, args.samples)
    names = args.case.split("+")
    if "coulomb_friction" not in names or len(names) != 2:
        ap.error("--case must be coulomb_friction with one input effect, e.g. "
                 "coulomb_friction+drive_deadband")
    other = next(n for n in names if n != "coulomb_friction")
    e, rig = h.experiment, Rig()
    ext = get_extension(["coulomb_friction", other])
    lin = fit_lsq([e], LinearModel(rig, "free"))
    p = lin.theta.size
    truth = np.r_[h.theta_lin, h.sizes["coulomb_friction"], h.sizes[other]]

    def lpd(theta) -> float:
        return float(_lpd([e], [ext.simulate(rig, theta, e.v_volt, e.dt)]).sum())

    def fitted(theta0) -> dict:
        t0 = time.perf_counter()
        f = fit_extension_lsq([e], ext, rig, theta0=theta0, linear=lin)
        return {"start": np.round(theta0[p:], 3).tolist(), "start_lpd": lpd(theta0),
                "fit": np.round(f.theta[p:], 3).tolist(), "fit_lpd": lpd(f.theta),
                "seconds": time.perf_counter() - t0}

    rows = {"case": args.case, "seed": args.seed, "names": list(ext.extension_names(rig)),
            "truth": np.round(truth[p:], 3).tolist(), "truth_lpd": lpd(truth)}
    rows["from_truth"] = fitted(truth)
    rows["package_starts"] = [fitted(s) for s in best_starts(ext, rig, lin.theta, [e],
                                                             args.fits)]
    cf = get_extension("coulomb_friction")
    one_cart = extra_starts(cf, rig, lin.theta, [e])
    own = get_extension(other).start_grid(rig)
    grid = np.array([np.r_[lin.theta, f, g] for f in one_cart for g in own])
    cost = np.sum(extension_residuals(ext, rig, grid, [e]) ** 2, axis=1)
    dens = np.array([lpd(g) for g in grid])
    rows["by_start_cost"] = [fitted(grid[k]) for k in np.argsort(cost)[: args.fits]]
    rows["by_start_lpd"] = [fitted(grid[k]) for k in np.argsort(-dens)[: args.fits]]
    # the best row of the grid after a fit, found by fitting every row on the true cart
    i = int(np.argmax(h.sizes["coulomb_friction"][: rig.n_carts]))
    on_cart = [k for k in range(len(grid)) if grid[k, p + i] > 0]
    rows["true_cart"] = [fitted(grid[k]) for k in on_cart]

    print(f"{args.case}, seed {args.seed}: parameters {rows['names']}")
    print(f"truth {rows['truth']}: AR(1) log density {rows['truth_lpd']:.0f}")
    print(f"fit from the truth: {rows['from_truth']['fit_lpd']:.0f}")
    for key in ("package_starts", "by_start_cost", "by_start_lpd", "true_cart"):
        for r in rows[key]:
            print(f"{key:15s} start {r['start']} -> {r['fit_lpd']:9.0f}  {r['fit']}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
