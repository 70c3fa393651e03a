"""Likelihood: closed forms of the Gaussian densities, batching, impossible parameters."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS
from scipy import stats

from bayesmodal._errors import ConfigError, DataError
from bayesmodal.data import Experiment
from bayesmodal.inference.likelihood import Likelihood, ar1_terms, simulate_noise, white_terms
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

THETA_P = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])


def _experiment(model, theta, n=800, noise=1e-5, seed=0, name="syn"):
    t = np.arange(n) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(model, theta, v, 0.005)
    y = y + noise * np.random.default_rng(seed).standard_normal(y.shape)
    return Experiment(t, v, y, name=name)


def test_ar1_terms_equal_the_exact_multivariate_normal_density():
    """Sum of innovation terms = log N(r; 0, Sigma) with Sigma_ij = s^2 phi^|i-j| / (1-phi^2)."""
    rng = np.random.default_rng(1)
    n = 40
    for phi, sig in ((0.95, 2e-3), (-0.6, 0.5), (0.0, 1.3)):
        r = rng.normal(size=(1, n, 1))
        lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
        cov = sig**2 * phi**lags / (1 - phi**2)
        exact = stats.multivariate_normal(np.zeros(n), cov).logpdf(r[0, :, 0])
        got = ar1_terms(r, np.array([[sig]]), np.array([[phi]])).sum()
        # scipy factorises cov: quadratic form and log-determinant each within
        # n eps cond(cov) of their size; the n terms add n eps of their magnitudes
        quad = r[0, :, 0] @ np.linalg.solve(cov, r[0, :, 0])
        logdet = np.linalg.slogdet(cov)[1]
        tol = n * EPS * (np.linalg.cond(cov) * (abs(quad) + abs(logdet)) + abs(exact))
        assert got == pytest.approx(exact, rel=0, abs=tol)


def test_white_terms_are_normal_logpdf():
    r = np.random.default_rng(2).normal(size=(2, 30, 3))
    s = np.array([[0.5, 1.0, 2.0], [1.0, 1.0, 1.0]])
    ref = stats.norm.logpdf(r, scale=s[:, None, :])
    assert np.allclose(white_terms(r, s), ref)


@pytest.mark.parametrize("noise", ["ar1", "white"])
def test_total_equals_sum_of_pointwise_for_several_experiments(noise):
    model = LinearModel(Rig(), "proportional")
    e1 = _experiment(model, THETA_P, n=600, seed=1, name="a")
    e2 = _experiment(model, THETA_P * 1.01, n=300, seed=2, name="b")
    lik = Likelihood(model, [e1, e2], noise)
    rng = np.random.default_rng(3)
    k = lik.n_params - model.n_params
    noise_part = np.r_[[1e-5] * 3, [0.3, -0.2, 0.9]][:k]
    theta = np.r_[THETA_P, noise_part] * (1 + 1e-3 * rng.standard_normal((5, lik.n_params)))
    total = lik(theta)
    pw = lik.pointwise(theta)
    assert [p.shape for p in pw] == [(5, 600, 3), (5, 300, 3)]
    # the same terms summed in another order: n eps of the sum of their magnitudes
    n_terms = sum(p[0].size for p in pw)
    tol = n_terms * EPS * sum(np.abs(p).sum(axis=(1, 2)) for p in pw)
    assert np.all(np.abs(total - sum(p.sum(axis=(1, 2)) for p in pw)) <= tol)


def test_impossible_parameters_give_minus_inf_without_exception():
    model = LinearModel(Rig(), "free")
    lik = Likelihood(model, [_experiment(model, np.r_[THETA_P[:4], 2.9, 1.8, 2.0, 0.3, 0.2])])
    good = np.r_[6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.3, 0.2, 1e-5, 1e-5, 1e-5, .5, .5, .5]
    rows = [good.copy() for _ in range(8)]
    rows[1][1] = -1.0       # negative mass
    rows[2][1] = 0.0        # zero mass
    rows[3][7] = -0.1       # negative damping
    rows[4][12] = 1.0       # |phi| = 1
    rows[5][9] = 0.0        # sigma = 0
    rows[6][0] = np.nan     # not a number
    rows[7][2] = np.inf
    out = lik(np.array(rows))
    assert np.isfinite(out[0])
    assert np.all(out[1:] == -np.inf)
    pw = lik.pointwise(np.array(rows))[0]
    assert np.all(pw[1:] == -np.inf) and np.all(np.isfinite(pw[0]))


def test_likelihood_is_maximised_near_truth_negative_control():
    """The true parameters beat a 1 % wrong mass by far more than the noise level."""
    model = LinearModel(Rig(), "proportional")
    e = _experiment(model, THETA_P, n=1000, noise=1e-5)
    lik = Likelihood(model, [e], "white")
    wrong = THETA_P.copy()
    wrong[2] *= 1.01
    ll = lik(np.array([np.r_[THETA_P, [1e-5] * 3], np.r_[wrong, [1e-5] * 3]]))
    assert ll[0] - ll[1] > 100


def test_simulated_ar1_noise_has_stationary_variance_and_lag_correlation():
    sig, phi, n = np.array([[2.0]]), np.array([[0.8]]), 200_000
    x = simulate_noise(sig, phi, n, rng=5)[0, :, 0]
    var = sig[0, 0] ** 2 / (1 - phi[0, 0] ** 2)
    # standard errors: var of an AR(1) sample variance ~ 2 var^2 (1+phi^2)/(1-phi^2) / n
    se_var = np.sqrt(2 * var**2 * (1 + 0.64) / (1 - 0.64) / n)
    assert abs(x.var() - var) < 4 * se_var
    rho = np.corrcoef(x[1:], x[:-1])[0, 1]
    assert abs(rho - 0.8) < 4 * np.sqrt((1 - 0.64) / n)


def test_validation_messages():
    model = LinearModel(Rig(), "proportional")
    e = _experiment(model, THETA_P, n=50)
    with pytest.raises(ConfigError, match="noise must be one of"):
        Likelihood(model, [e], "pink")
    with pytest.raises(ConfigError, match="need a record layout"):
        Likelihood(model, [e], "ar2")
    with pytest.raises(ConfigError, match="pass initial_state by keyword"):
        Likelihood(model, [e], "ar1", None, "estimate")
    with pytest.raises(DataError, match="no experiments"):
        Likelihood(model, [], "ar1")
    lik = Likelihood(model, [e], "ar1")
    with pytest.raises(ConfigError, match="length 12"):
        lik(np.zeros((1, 5)))


def test_ar1_draws_from_a_known_start_follow_the_conditional_closed_form():
    """Started at a known residual ``r_0``: mean ``phi^k r_0`` and variance
    ``sigma^2 (1 - phi^(2k)) / (1 - phi^2)`` (Monte Carlo tolerance: 4.5 standard errors,
    Bonferroni over the lags).  At ``phi`` = 1 - 1e-13 the draws are a random walk with
    variance ``k sigma^2``, where the stationary start's spread is ``sigma / sqrt(2e-13)``
    (negative control: millions of times wider)."""
    nb, n, sig, phi, r0 = 20000, 40, 1e-4, 0.9, 3e-4
    x = simulate_noise(np.full((nb, 1), sig), np.full((nb, 1), phi), n, rng=7,
                       start=np.full((nb, 1), r0))[:, :, 0]
    k = np.arange(n)
    mean = phi**k * r0
    var = sig**2 * (1 - phi ** (2 * k)) / (1 - phi**2)
    assert np.array_equal(x[:, 0], np.full(nb, r0))
    se_mean = np.sqrt(var[1:] / nb)
    se_var = var[1:] * np.sqrt(2 / (nb - 1))
    assert np.all(np.abs(x[:, 1:].mean(axis=0) - mean[1:]) < 4.5 * se_mean)
    assert np.all(np.abs(x[:, 1:].var(axis=0) - var[1:]) < 4.5 * se_var)
    near1 = 1 - 1e-13
    rw = simulate_noise(np.full((nb, 1), sig), np.full((nb, 1), near1), n, rng=8,
                        start=np.zeros((nb, 1)))[:, -1, 0]
    want = (n - 1) * sig**2
    assert abs(rw.var() - want) < 4.5 * want * np.sqrt(2 / (nb - 1))
    stat = simulate_noise(np.full((nb, 1), sig), np.full((nb, 1), near1), n, rng=8)[:, -1, 0]
    assert stat.std() > 1e5 * np.sqrt(want)
    with pytest.raises(DataError, match="white noise has no memory"):
        simulate_noise(np.full((2, 1), sig), None, n, start=np.zeros((2, 1)))


def test_a_new_records_ar1_draws_start_at_its_first_residual():
    """``predict_new_record`` conditions AR(1) draws on the record's start: every
    predictive sample at t = 0 is the measured first sample (the record starts at rest)."""
    from bayesmodal.inference.predictive import predict_new_record

    model = LinearModel(Rig(), "free")
    theta = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
    t = np.arange(500) * 0.005
    v = 3.0 * (t < 0.05)
    y = simulate_linear(model, theta, v, 0.005)
    e = Experiment(t, v, y + 1e-5 * np.random.default_rng(1).standard_normal(y.shape))
    lik = Likelihood(model, (e,), "ar1")
    draws = np.tile(np.r_[theta, [1e-5] * 3, [1 - 1e-12] * 3], (50, 1))
    y_hat, y_pred, _ = predict_new_record(lik, draws, e, rng=2)
    assert np.allclose(y_pred[:, 0], e.y_m[0], rtol=0, atol=4 * EPS * np.abs(y_hat).max())
    # the band of a random-walk draw is bounded by sqrt(N) sigma, not sigma / sqrt(2e-12)
    assert np.max(np.abs(y_pred - y_hat)) < 6 * np.sqrt(e.n_samples) * 1e-5 + np.abs(
        e.y_m - y_hat).max()
