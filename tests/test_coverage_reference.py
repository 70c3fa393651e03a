"""The coverage a calibrated band shows on one record (``inference.coverage_reference``):
the leave-one-out bands against brute force, the reference distribution against fresh
records of the same process, and the PIT of a calibrated record against a control."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesmodal._errors import ConfigError
from bayesmodal.inference.coverage_reference import (
    MIN_REFERENCE_DRAWS,
    calibration_summary,
    coverage_reference,
    pit,
)
from bayesmodal.inference.predictive import band_factor, score_samples

#: Significance of the distribution tests below (a calibrated case fails once in 1000).
ALPHA = 1e-3


def _ar1(rng, n_paths: int, n: int, phi: float, n_out: int = 1, scale: float = 1.0):
    """AR(1) paths started at 0 (a record starting at rest), shape (n_paths, n, n_out)."""
    e = scale * rng.standard_normal((n_paths, n, n_out))
    x = np.zeros_like(e)
    for t in range(1, n):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    return x


def test_leave_one_out_bands_equal_numpy_quantiles_of_the_others():
    """Each member's coverage and band factor against the band of the other S - 1
    members, computed from one sort, equal the brute-force np.quantile of the others."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((MIN_REFERENCE_DRAWS + 5, 60, 2))
    ref = coverage_reference(x, probs=(0.5, 0.9))
    for j in range(x.shape[0]):
        others = np.delete(x, j, axis=0)
        for k, p in enumerate((0.5, 0.9)):
            lo, hi = np.quantile(others, [(1 - p) / 2, (1 + p) / 2], axis=0)
            np.testing.assert_array_equal(ref.coverage[k, j],
                                          np.mean((x[j] >= lo) & (x[j] <= hi), axis=0))
        lo, mid, hi = np.quantile(others, [0.05, 0.5, 0.95], axis=0)
        # the interpolation is written out (NumPy's lerp rounds differently): a few ulps
        np.testing.assert_allclose(ref.band_factor_90[j], band_factor(x[j], lo, mid, hi),
                                   rtol=8 * np.finfo(float).eps)


def test_reference_is_the_coverage_of_fresh_records_of_the_same_process():
    """Brute force: fresh AR(1) records (phi 0.995, 1500 samples, start at rest) scored
    against the ensemble's band have the coverage distribution of the reference
    (two-sample KS at ALPHA); white records of the same spread do not (control)."""
    rng = np.random.default_rng(1)
    n, phi, s = 1500, 0.995, 200
    ens = _ar1(rng, s, n, phi)
    ref = coverage_reference(ens)
    lo, hi = np.quantile(ens, [0.05, 0.95], axis=0)
    fresh = _ar1(rng, 400, n, phi)
    cov = np.mean((fresh >= lo) & (fresh <= hi), axis=1)[:, 0]
    assert stats.ks_2samp(ref.coverage[1][:, 0], cov).pvalue > ALPHA
    # control: white noise with each sample's marginal spread covers ~90 % every time
    sd = np.std(ens, axis=0)
    white = sd * rng.standard_normal((400, n, 1))
    cov_w = np.mean((white >= lo) & (white <= hi), axis=1)[:, 0]
    assert stats.ks_2samp(ref.coverage[1][:, 0], cov_w).pvalue < ALPHA
    # the probability of a fixed window, against the fresh records' frequency
    w = ref.window_probability((0.8, 0.95))
    f = np.mean((cov >= 0.8) & (cov <= 0.95))
    se = np.sqrt(w * (1 - w) / s + f * (1 - f) / cov.size)
    assert abs(w - f) < 4 * se


def test_pit_of_a_calibrated_record_is_uniform_and_of_a_narrow_band_is_not():
    """Over replicates, a record drawn from the ensemble's own process has a uniform
    record-level PIT (KS at ALPHA); a record with twice the noise sits at the bottom
    (coverage PIT) and the top (band-factor PIT) of its reference."""
    rng = np.random.default_rng(2)
    n, phi, s, reps = 600, 0.99, 60, 150
    u, u_bad, f_bad = [], [], []
    for _ in range(reps):
        ens = _ar1(rng, s, n, phi, n_out=2)
        y, y_bad = _ar1(rng, 1, n, phi, 2)[0], _ar1(rng, 1, n, phi, 2, scale=2.0)[0]
        for obs, store in ((y, u), (y_bad, u_bad)):
            sc = score_samples("r", obs, ens, np.zeros(s))
            store.append(sc.reference.record_pit(sc.coverage_90))
            if store is u_bad:
                f_bad.append(sc.reference.record_band_factor_pit(sc.band_factor_90))
    assert stats.kstest(u, "uniform").pvalue > ALPHA
    assert stats.kstest(u_bad, "uniform").pvalue < ALPHA
    assert np.mean(u_bad) < 0.25 and np.mean(f_bad) > 0.75


def test_pit_splits_ties_and_summary_counts_records_outside():
    ref = np.array([0.5, 1.0, 1.0, 1.0])
    assert float(pit(ref, np.array(1.0))) == pytest.approx((1 + 0.5 * 3) / 4)
    cal = calibration_summary([0.01, 0.5, 0.99, 0.6], window_probabilities=[0.5, 0.2,
                                                                             0.4, 0.3])
    assert (cal["n_below"], cal["n_above"], cal["n_outside"]) == (1, 1, 2)
    # P(at least 2 of 4 outside | each with probability 0.1)
    assert cal["p_value"] == pytest.approx(1 - 0.9**4 - 4 * 0.1 * 0.9**3)
    assert cal["window_probability_all"] == pytest.approx(0.5 * 0.2 * 0.4 * 0.3)
    cal = calibration_summary([0.5] * 3, band_factor_pits=[0.99, 0.5, 0.01])
    assert (cal["n_outside"], cal["n_band_factor_above"], cal["n_band_factor_below"]) == \
        (0, 1, 1)


def test_reference_needs_enough_draws_and_names_the_fix():
    x = np.zeros((MIN_REFERENCE_DRAWS - 1, 10, 1))
    with pytest.raises(ConfigError, match="at least 20 predictive draws.*n_predictive"):
        coverage_reference(x)
    with pytest.raises(ConfigError, match=r"shape \(S, N, n_out\)"):
        coverage_reference(np.zeros((30, 10)))
    # scores of a small ensemble simply carry no reference
    rng = np.random.default_rng(0)
    sc = score_samples("r", rng.standard_normal((10, 1)), rng.standard_normal(
        (MIN_REFERENCE_DRAWS - 1, 10, 1)), np.zeros(MIN_REFERENCE_DRAWS - 1))
    assert sc.reference is None and "coverage_90_pit" not in sc.to_dict()
