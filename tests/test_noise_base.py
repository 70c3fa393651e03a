"""Noise-model protocol: white and AR(1) in NoiseModel form give the likelihood's numbers."""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.data import Experiment
from bayesmodal.inference.likelihood import Likelihood, ar1_terms, white_terms
from bayesmodal.inference.noise import AR1Noise, ARpNoise, NoiseModel, WhiteNoise
from bayesmodal.inference.priors import default_priors, noise_names
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

EPS = np.finfo(float).eps
THETA_P = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])


def _sum_bound(terms):
    """Worst-case rounding bound of two different summation orders (Higham gamma_N)."""
    t = np.abs(terms).reshape(terms.shape[0], -1)
    return 2 * t.shape[1] * EPS * t.sum(axis=1)


def _params(rng, nb, n_out, kind):
    sig = rng.uniform(0.5, 2.0, (nb, n_out)) * 1e-4
    if kind == "white":
        return sig
    return np.c_[sig, rng.uniform(-0.95, 0.99, (nb, n_out))]


@pytest.mark.parametrize("model,terms", [(WhiteNoise(), "white"), (AR1Noise(), "ar1")])
def test_pointwise_equals_the_likelihood_terms_and_sums_to_loglik(model, terms):
    rng = np.random.default_rng(0)
    nb, n, n_out = 6, 500, 3
    p = _params(rng, nb, n_out, terms)
    r = model.simulate(p, n, rng=1)
    pw = model.pointwise(r, p)
    ref = (white_terms(r, p) if terms == "white"
           else ar1_terms(r, p[:, :n_out], p[:, n_out:]))
    assert np.array_equal(pw, ref)
    total = model.loglik(np.moveaxis(r, 0, -1), p)
    assert np.all(np.abs(total - pw.sum(axis=(1, 2))) <= _sum_bound(pw) * 10)


@pytest.mark.parametrize("noise,cls", [("white", WhiteNoise), ("ar1", AR1Noise)])
def test_loglik_equals_likelihood_call_on_the_same_residuals(noise, cls):
    model = LinearModel(Rig(), "proportional")
    t = np.arange(700) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(model, THETA_P, v, 0.005)
    y = y + 1e-5 * np.random.default_rng(4).standard_normal(y.shape)
    lik = Likelihood(model, [Experiment(t, v, y)], noise)
    rng = np.random.default_rng(5)
    mech = THETA_P * (1 + 1e-3 * rng.standard_normal((4, 6)))
    p = _params(rng, 4, 3, noise)
    yh = simulate_linear(model, mech, v, 0.005)
    R = y[:, :, None] - np.moveaxis(yh, 0, -1)
    got = cls().loglik(R, p)
    ref = lik(np.c_[mech, p])
    pw = cls().pointwise(np.moveaxis(R, -1, 0), p)
    assert np.all(np.abs(got - ref) <= _sum_bound(pw) * 10)


@pytest.mark.parametrize("model", [WhiteNoise(), AR1Noise(), ARpNoise((2, 1, 3))])
def test_invalid_rows_get_minus_inf_without_raising(model):
    n_out = 3
    k = model.n_params(n_out)
    p = np.full((4, k), 0.5)
    p[1, 0] = -1.0          # sigma < 0
    p[2, 0] = np.nan
    if k > n_out:
        p[3, -1] = 1.0      # |coefficient| = 1: not stationary
    r = np.random.default_rng(0).normal(size=(4, 20, n_out))
    ll = model.loglik(np.moveaxis(r, 0, -1), p)
    pw = model.pointwise(r, p)
    bad = [1, 2, 3] if k > n_out else [1, 2]
    assert np.all(ll[bad] == -np.inf) and np.all(pw[bad] == -np.inf)
    assert np.isfinite(ll[0]) and np.all(np.isfinite(pw[0]))
    assert list(np.flatnonzero(~model.valid(p))) == bad


@pytest.mark.parametrize("noise,model", [("white", WhiteNoise()), ("ar1", AR1Noise())])
def test_names_and_priors_match_the_default_priors(noise, model):
    assert model.names(3) == noise_names(3, noise)
    lin = LinearModel(Rig(), "proportional")
    ps = default_priors(lin, noise=noise)
    mine = model.priors(3)
    k = len(mine.names)
    assert ps.names[-k:] == mine.names
    assert ps.priors[-k:] == mine.priors and ps.transforms[-k:] == mine.transforms


def test_arp_priors_use_the_shared_classes_and_transforms():
    ps = ARpNoise((2, 1, 3)).priors(3)
    assert ps.names[:3] == ("sigma_1", "sigma_2", "sigma_3") and len(ps.names) == 9
    assert set(ps.transforms[3:]) == {"tanh"} and set(ps.transforms[:3]) == {"log"}
    lin = default_priors(LinearModel(Rig(), "proportional"), noise="ar1")
    assert ps.priors[0] == lin.priors[lin.index("sigma_1")]
    assert ps.priors[3] == lin.priors[lin.index("phi_1")]


def test_ar1_start_recovers_phi_and_sigma_within_standard_errors():
    rng = np.random.default_rng(7)
    n = 20000
    sig, phi = np.array([2e-5, 1e-4]), np.array([0.9, -0.3])
    r = AR1Noise().simulate(np.r_[sig, phi][None], n, rng)[0]
    est = AR1Noise().start(r)
    se_phi = np.sqrt((1 - phi**2) / n)
    se_sig = sig / np.sqrt(2 * n)
    assert np.all(np.abs(est[2:] - phi) < 4 * se_phi)
    assert np.all(np.abs(est[:2] - sig) < 4 * se_sig)
    assert np.all(np.abs(WhiteNoise().start(r) - sig / np.sqrt(1 - phi**2))
                  < 4 * sig / np.sqrt(1 - phi**2) * np.sqrt((1 + phi**2) / (1 - phi**2) / (2 * n)))


def test_bad_inputs_raise_one_line_errors():
    with pytest.raises(DataError, match="parameter rows of length 6"):
        AR1Noise().loglik(np.zeros((10, 3, 2)), np.ones((2, 5)))
    with pytest.raises(DataError, match="non-finite"):
        WhiteNoise().start(np.array([[0.0], [np.nan]]))
    assert isinstance(ARpNoise((1,)), NoiseModel)


@pytest.mark.parametrize("model", [WhiteNoise(), AR1Noise(), ARpNoise((2,))])
def test_a_model_without_a_covariate_is_the_same_for_every_record(model):
    """``NoiseModel.for_record`` returns the model itself unless it reads its record."""
    t = np.arange(50) * 0.01
    e = Experiment(t, np.zeros_like(t), np.zeros((50, 1)), name="r")
    assert model.for_record(e) is model
