"""How often a *calibrated* 90 % band covers one record 80-95 %, by the record's correlation.

A record whose misfit is AR(1) with coefficient ``phi`` (started at rest, as the rig's
records are) is drawn from exactly the process its predictive band is made of; the band
is the pointwise 5-95 % range of ``--draws`` other draws of the same process, i.e. a band
that is calibrated by construction.  Over ``--records`` such records the script prints
the quantiles of the share of samples inside the band, the probability that one output
is covered within 80-95 %, and that three independent outputs all are (three carts of
one record share much of their misfit, so the truth for a record lies between the two).
It also checks the package's leave-one-out reference (``coverage_reference``) against
this brute force: the reference's median and 5-95 % range from one ensemble.

Usage::

    python benchmarks/coverage_window.py [--n-samples 7400] [--records 2000] [--draws 200]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from bayesmodal.inference.coverage_reference import (  # noqa: E402
    COVERAGE_WINDOW_90,
    coverage_reference,
)


def ar1_from_rest(rng, n_paths: int, n: int, phi: float) -> np.ndarray:
    """AR(1) paths with unit innovations started at 0, shape (n_paths, n)."""
    e = rng.standard_normal((n_paths, n))
    x = np.zeros_like(e)
    for t in range(1, n):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    return x


def study(phi: float, n: int, records: int, draws: int, rng) -> dict:
    band = ar1_from_rest(rng, draws, n, phi)
    lo, hi = np.quantile(band, [0.05, 0.95], axis=0)
    cov = np.concatenate([np.mean((x >= lo) & (x <= hi), axis=1)
                          for x in (ar1_from_rest(rng, 500, n, phi)
                                    for _ in range(max(1, records // 500)))])
    w0, w1 = COVERAGE_WINDOW_90
    p1 = float(np.mean((cov >= w0) & (cov <= w1)))
    ref = coverage_reference(band[:, :, None]).coverage[1][:, 0]
    return {"phi": phi, "n_samples": n, "records": int(cov.size),
            "coverage_q05_q50_q95": np.quantile(cov, [0.05, 0.5, 0.95]).round(3).tolist(),
            "p_window_one_output": round(p1, 3), "p_window_three_outputs": round(p1**3, 3),
            "reference_q05_q50_q95": np.quantile(ref, [0.05, 0.5, 0.95]).round(3).tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-samples", type=int, default=7400)
    ap.add_argument("--records", type=int, default=2000)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--phi", default="0.9,0.99,0.996,0.999,0.9995")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    rows = [study(float(p), a.n_samples, a.records, a.draws, rng) for p in a.phi.split(",")]
    print("phi      coverage q05 q50 q95    P(80-95 %) one output, three    "
          "reference q05 q50 q95")
    for r in rows:
        q, rq = r["coverage_q05_q50_q95"], r["reference_q05_q50_q95"]
        print(f"{r['phi']:<8} {q[0]:5.3f} {q[1]:5.3f} {q[2]:5.3f}           "
              f"{r['p_window_one_output']:5.3f}  {r['p_window_three_outputs']:5.3f}          "
              f"{rq[0]:5.3f} {rq[1]:5.3f} {rq[2]:5.3f}")
    if a.out:
        a.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
