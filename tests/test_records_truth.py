"""Known truth with records that disagree: the several-record posterior against the
single-record one (a reduced version of benchmarks/records_coverage.py, which measures the
coverage over replicates)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats


@pytest.mark.slow
def test_joint_posterior_finds_the_truth_the_single_record_model_misses():
    """One replicate (four records, gains spread by 5 %, input offsets, AR(1) noise,
    encoder quantisation).  The quantities are correlated (masses and frequencies move
    together), so one replicate is no binomial sample of ten; instead every quantity must
    lie within z standard deviations of its posterior, z the two-sided 1e-3 / 10 normal
    quantile (about 4).  Negative control: the single-record AR(1) model of the pulse
    record takes that record's own gain for the rig's, and its g_v misses the population
    centre by far more than that."""
    from records_truth import QUANTITIES, replicate

    rep = replicate(3, n_samples=1500, steps=2500)
    z_max = stats.norm.isf(1e-3 / (2 * len(QUANTITIES)))

    def z(label, q):
        lo, med, hi, truth = rep[label + "_intervals"][q]
        sd = (hi - lo) / (2 * stats.norm.isf(0.05))  # the 90 % interval's width
        return abs(med - truth) / sd

    joint = {q: z("joint", q) for q in QUANTITIES}
    assert max(joint.values()) < z_max, joint
    assert z("single", "mu_gv") > z_max  # its g_v is the pulse record's gain
    assert rep["joint"]["mu_gv"]
    assert np.isfinite(rep["joint_diag"]["max_rhat"])
