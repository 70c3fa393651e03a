"""Integrated AR(1) noise (ARIMA(1, 1, 0) started at rest) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesmodal.data import Experiment
from bayesmodal.inference.noise import AR1Noise, IntegratedAR1Noise
from bayesmodal.inference.noise_choice import resolve_noise
from bayesmodal.inference.record_layout import RecordLayout
from bayesmodal.inference.records import RecordsLikelihood
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

EPS = np.finfo(float).eps


def _cov(n, sigma, phi):
    """Covariance of r = cumsum(d), d stationary AR(1): L S L^T (L lower ones)."""
    k = np.arange(n)
    s_d = sigma**2 / (1 - phi**2) * phi ** np.abs(k[:, None] - k[None, :])
    low = np.tril(np.ones((n, n)))
    return low @ s_d @ low.T


@pytest.mark.parametrize("phi", [-0.4, 0.0, 0.7, 0.97])
def test_density_is_the_multivariate_normal_of_the_integrated_process(phi):
    rng = np.random.default_rng(1)
    n, n_out, sig = 40, 2, 3e-4
    cov = _cov(n, sig, phi)
    r = rng.multivariate_normal(np.zeros(n), cov, size=n_out).T  # (n, n_out)
    want = sum(stats.multivariate_normal(np.zeros(n), cov).logpdf(r[:, j]) for j in range(n_out))
    params = np.array([[sig, sig, phi, phi]])
    got = IntegratedAR1Noise().loglik(r[:, :, None], params)[0]
    # rounding of a dense Cholesky of cov: eps times its condition number, relative
    tol = 10 * n * EPS * np.linalg.cond(cov) * abs(want)
    assert abs(got - want) <= tol, (got, want, tol)
    # negative control: the stationary AR(1) density of the same numbers is another one
    assert abs(AR1Noise().loglik(r[:, :, None], params)[0] - want) > tol
    pw = IntegratedAR1Noise().pointwise(r[None], params)
    assert abs(pw.sum() - got) <= n * n_out * EPS * abs(got)


def test_draws_have_the_integrated_variance_and_start_at_rest():
    nb, n, sig, phi = 20000, 30, 1e-4, 0.6
    x = IntegratedAR1Noise().simulate(np.tile([sig, phi], (nb, 1)), n, rng=3)[:, :, 0]
    var = np.diag(_cov(n, sig, phi))
    se = var * np.sqrt(2 / (nb - 1))
    assert np.all(np.abs(x.var(axis=0) - var) < 4.5 * se)  # Bonferroni over 30 lags
    # negative control: the stationary AR(1) of the same parameters does not grow
    y = AR1Noise().simulate(np.tile([sig, phi], (nb, 1)), n, rng=3)[:, :, 0]
    assert y[:, -1].var() < var[-1] - 10 * se[-1]


def test_moments_recover_the_increments_and_the_stationary_model_hits_its_edge():
    """Known truth: a wandering residual (phi of the increments 0.5).  The integrated
    model's start estimate finds 0.5 (within 4 standard errors, sqrt((1 - phi^2) / N)); the
    stationary AR(1) fitted to the same record puts phi at its edge (negative control)."""
    n, phi = 20000, 0.5
    x = IntegratedAR1Noise().simulate(np.array([[1e-5, phi]]), n, rng=4)[0]
    est = IntegratedAR1Noise().start(x)
    assert abs(est[1] - phi) < 4 * np.sqrt((1 - phi**2) / n)
    assert AR1Noise().start(x)[1] > 0.999


def test_the_records_likelihood_takes_it_by_name():
    assert isinstance(resolve_noise("iar1", 3), IntegratedAR1Noise)
    model = LinearModel(Rig(), "free")
    theta = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
    t = np.arange(300) * 0.005
    v = 3.0 * (t < 0.05)
    y = simulate_linear(model, theta, v, 0.005)
    noise = IntegratedAR1Noise().simulate(np.array([[2e-5] * 3 + [0.3] * 3]), 300, rng=5)[0]
    e = Experiment(t, v, y + noise, name="a")
    lik = RecordsLikelihood(model, (e,), "iar1", layout=RecordLayout({}))
    assert lik.names[-6:] == ("sigma_1", "sigma_2", "sigma_3", "phi_1", "phi_2", "phi_3")
    p = np.array([2e-5] * 3 + [0.3] * 3)
    got = lik(np.r_[theta, p][None])[0]
    want = IntegratedAR1Noise().loglik((e.y_m - y)[:, :, None], p[None])[0]
    assert abs(got - want) <= 300 * 3 * EPS * abs(want)
