"""Reduced frequentist coverage check of the 90 % intervals (slow; the full study is
benchmarks/linear_coverage.py, reported in docs/inference.md).

R replicated synthetic records (short, fresh AR(1) noise each) are fitted with the matching
AR(1) likelihood and with the white-noise likelihood.  For each of the 10 quantities
(omega 1-3, zeta 1-3, g_v, m1-m3) the fraction of replicates whose 90 % interval holds the
truth estimates the coverage, with binomial standard error sqrt(0.9 * 0.1 / R) per quantity.
"""

from __future__ import annotations

import numpy as np
import pytest
from _benchmarks import load_benchmark

pytestmark = pytest.mark.slow

R = 24


def _benchmark():
    return load_benchmark("linear_coverage")


def test_matching_likelihood_covers_and_white_on_ar1_data_covers_worse():
    cov = _benchmark()
    cfg = cov.Config(damping="proportional", n_samples=800, n_walkers=24, n_steps=900,
                     burn=300)
    res = cov.run_coverage(cfg, ["ar1/ar1", "ar1/white"], R, processes=1, seed0=1000)
    table = cov.tabulate(res)

    def pooled(setting):
        hits = [np.concatenate([np.ravel(r["hits"][k]) for k in r["hits"]])
                for r in res if r["setting"] == setting]
        return np.mean(hits)

    se = np.sqrt(0.9 * 0.1 / R)  # one quantity; pooling correlated quantities helps little
    good, bad = pooled("ar1/ar1"), pooled("ar1/white")
    assert abs(good - 0.9) < 3 * se, table["ar1/ar1"]
    # the white likelihood ignores the correlation: its intervals are too narrow
    assert bad < good - 2 * se * np.sqrt(2), (good, bad)
    for k in ("omega", "zeta", "g_v", "mass"):
        assert table["ar1/ar1"][k]["coverage"] > 0.9 - 4 * se
