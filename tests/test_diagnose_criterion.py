"""diagnose's scoring criteria: the AR(1) log density (one record) and the output error
with an autocorrelation-aware standard error (several records), which sees a level."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesmodal.discrepancy.diagnosis.scoring import (
    AR1,
    EITHER,
    OUTPUT_ERROR,
    ar1_pointwise,
    autocorr_se,
    criterion_for,
    held_out_significant,
    output_error_pointwise,
)


def _ar1(rng, n, m, phi, sigma=1.0):
    """Stationary AR(1) series, shape (n, m)."""
    e = rng.normal(0.0, sigma, (n, m))
    x = np.empty((n, m))
    x[0] = e[0] / np.sqrt(1 - phi**2)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def test_output_error_sums_to_the_closed_form_of_a_profiled_gaussian():
    rng = np.random.default_rng(0)
    r = [rng.normal(0, 2e-4, (500, 3)), rng.normal(0, 5e-5, (300, 3))]
    pw = output_error_pointwise(r)
    assert pw.shape == (500 * 3 + 300 * 3,)
    i = 0
    for x in r:
        n, m = x.shape
        block = pw[i:i + n * m].reshape(n, m)
        i += n * m
        s2 = np.mean(x**2, axis=0)
        closed = -0.5 * n * (np.log(2 * np.pi * s2) + 1)
        np.testing.assert_allclose(block.sum(axis=0), closed, rtol=1e-12)
    # a difference of two models is N/2 log of the ratio of their mean squares
    x = r[0]
    d = output_error_pointwise([0.5 * x]) - output_error_pointwise([x])
    np.testing.assert_allclose(d.sum(), 3 * 500 / 2 * np.log(4.0), rtol=1e-12)


@pytest.mark.parametrize("phi", [0.0, 0.9, 0.99])
def test_autocorr_se_matches_the_spread_of_sums_of_ar1_series(phi):
    """The standard error of a sum of AR(1) terms against the spread of such sums over
    Monte Carlo replicates (one output, so the bound over outputs is exact).  Tolerance:
    the Monte Carlo standard error of a standard deviation, sd / sqrt(2 (R - 1)), plus
    the spread of the SE estimates themselves over the replicates."""
    rng = np.random.default_rng(1)
    n, reps = 4000, 400
    sums, ses = [], []
    for _ in range(reps):
        x = _ar1(rng, n, 1, phi)
        sums.append(x.sum())
        ses.append(autocorr_se(x.ravel(), [(n, 1)]))
    sd = np.std(sums, ddof=1)
    mc = sd / np.sqrt(2 * (reps - 1))
    est = np.mean(ses)
    tol = 3 * np.hypot(mc, np.std(ses, ddof=1) / np.sqrt(reps))
    assert abs(est - sd) < tol, (est, sd, tol)
    # negative control: the iid formula is too small by sqrt(tau) for phi > 0
    iid = np.mean([np.sqrt(n * np.var(_ar1(rng, n, 1, phi))) for _ in range(20)])
    tau = (1 + phi) / (1 - phi)
    if phi > 0:
        assert iid < sd - tol
    np.testing.assert_allclose(sd, iid * np.sqrt(tau), rtol=6 * mc / sd + 0.1 / np.sqrt(20))


def test_autocorr_se_adds_outputs_as_correlated_and_records_as_independent():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(200, 2))
    b = rng.normal(size=(100, 2))
    d = np.r_[a.ravel(), b.ravel()]
    se = autocorr_se(d, [(200, 2), (100, 2)])
    one = [autocorr_se(x.ravel(), [x.shape]) for x in (a, b)]
    cols = [[autocorr_se(x[:, j], [(x.shape[0], 1)]) for j in range(2)] for x in (a, b)]
    np.testing.assert_allclose(one, [sum(c) for c in cols], rtol=1e-12)
    np.testing.assert_allclose(se, np.hypot(*one), rtol=1e-12)
    with pytest.raises(ValueError, match="shapes"):
        autocorr_se(d, [(200, 2)])


def test_the_output_error_sees_a_level_that_the_ar1_score_does_not():
    """A residual that is AR(1) noise with phi = 0.999 plus a constant ``c`` (a model
    without an input offset) against the same noise without it (the model with the
    offset).  The AR(1) score sees the level only through the innovations, shifted by
    ``(1 - phi) c``: its gain is at most ``sum n (1 - phi)^2 c^2 / (2 sigma^2)`` (plus the
    LR's own noise), a few nats, where the output error gains thousands, significantly.
    Negative control: with no level, neither finds a gain."""
    rng = np.random.default_rng(3)
    phi, sigma = 0.999, 1e-5
    shapes = [(3000, 3), (3000, 3)]
    noise = [_ar1(rng, n, m, phi, sigma=sigma) for n, m in shapes]
    c = 2 * max(float(np.std(x)) for x in noise)
    with_level = [x + c for x in noise]
    gains = {}
    for crit in (AR1, OUTPUT_ERROR):
        pw_new = crit.pointwise(noise)
        gains[crit.name] = crit.test(pw_new, crit.pointwise(with_level), 1, shapes, 0.01)
        # negative control: the same residuals, no level
        *_, sig0 = crit.test(pw_new, crit.pointwise([x.copy() for x in noise]), 1, shapes,
                             0.01)
        assert not sig0
    n_terms = sum(n * m for n, m in shapes)
    bound = 0.5 * n_terms * (1 - phi) ** 2 * c**2 / sigma**2 + 0.5 * stats.chi2.ppf(0.99, 1)
    assert gains["ar1"][0] < bound, (gains["ar1"], bound)
    assert gains["output_error"][-1] and gains["output_error"][0] > 100 * bound, gains


def test_the_ar1_test_is_the_likelihood_ratio_with_bic():
    rng = np.random.default_rng(4)
    shapes = [(500, 3)]
    r = _ar1(rng, 500, 3, 0.9)
    pw_cur = ar1_pointwise([r])
    pw_new = ar1_pointwise([0.9 * r])
    g, lr, pv, bic, sig = AR1.test(pw_new, pw_cur, 2, shapes, 0.01)
    assert lr == pytest.approx(2 * (pw_new.sum() - pw_cur.sum()))
    assert pv == pytest.approx(stats.chi2.sf(lr, 2))
    assert bic == pytest.approx(lr - 2 * np.log(1500))
    assert sig == (pv < 0.01 and bic > 0)


def test_criterion_for_one_record_is_ar1_and_for_several_either():
    class E:  # the criterion needs only the number of records
        pass

    assert criterion_for([E()]) is AR1
    assert criterion_for([E(), E()]) is EITHER


def test_either_is_significant_when_one_test_is_at_half_the_level():
    """``"either"`` runs both tests at ``level / 2``: the level seen by the output error
    alone counts, a gain of both counts, no gain counts for neither (negative control);
    its gain, LR and BIC gain are the AR(1) score's and its p-value the Bonferroni one."""
    rng = np.random.default_rng(5)
    phi, sigma = 0.999, 1e-5
    shapes = [(3000, 3), (3000, 3)]
    noise = [_ar1(rng, n, m, phi, sigma=sigma) for n, m in shapes]
    c = 2 * max(float(np.std(x)) for x in noise)
    pw_new = EITHER.pointwise(noise)
    assert pw_new.shape == (2, 2 * 3000 * 3)
    np.testing.assert_array_equal(pw_new[0], AR1.pointwise(noise))
    np.testing.assert_array_equal(pw_new[1], OUTPUT_ERROR.pointwise(noise))
    lvl = 0.01
    for cur, expect in (([x + c for x in noise], True), ([x.copy() for x in noise], False)):
        pw_cur = EITHER.pointwise(cur)
        g, lr, pv, bic, sig = EITHER.test(pw_new, pw_cur, 1, shapes, lvl)
        a = AR1.test(pw_new[0], pw_cur[0], 1, shapes, lvl / 2)
        o = OUTPUT_ERROR.test(pw_new[1], pw_cur[1], 1, shapes, lvl / 2)
        assert (g, lr, bic) == (a[0], a[1], a[3])
        assert pv == pytest.approx(min(1.0, 2 * min(a[2], o[2])))
        assert sig is expect is (a[-1] or o[-1])
    assert EITHER.total(pw_new) == pytest.approx(pw_new[0].sum())
    # held out: either z above the quantile of level / 2
    d = pw_new - EITHER.pointwise([x + c for x in noise])
    ho = dict(EITHER.held_out(d, shapes), criterion="either")
    assert ho["z"] == pytest.approx(d[0].sum() / np.sqrt(d[0].size * np.var(d[0])))
    q = stats.norm.ppf(1 - lvl / 2)
    assert held_out_significant(ho, lvl) is bool(ho["z"] > q or ho["output_error"]["z"] > q)
    assert ho["output_error"]["z"] > q  # the level, seen by the output error
    no = dict(ho, z=0.0, output_error=dict(ho["output_error"], z=0.0))
    assert not held_out_significant(no, lvl)
