"""Priors: densities, quantile functions, transforms and their Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from bayesmodal._errors import ConfigError
from bayesmodal.inference.priors import (
    LogUniform,
    Normal,
    PriorSet,
    Uniform,
    default_priors,
    noise_names,
)

CASES = [
    (Uniform(0.2, 5.0), "log"),
    (Uniform(0.0, 20.0), "identity"),
    (Uniform(0.0, 20.0), "log"),
    (LogUniform(1e-7, 0.1), "log"),
    (Uniform(-1.0, 1.0), "tanh"),
    (Normal(6.0, 0.5, lo=0.0), "log"),
]


@pytest.mark.parametrize(("prior", "transform"), CASES)
def test_density_of_sampling_coordinate_integrates_to_one(prior, transform):
    """p_z(z) = p(f(z)) |f'(z)| is a density in z: it integrates to 1 (closed form)."""
    ps = PriorSet(("x",), (prior,), (transform,))
    lo, hi = prior.support
    zlo, zhi = ps.to_sampling(np.array([[lo], [hi]]))[:, 0]
    zlo = max(zlo, -60.0)  # log(0) = -inf: the tail below is exp(z)-small
    zhi = min(zhi, 60.0)

    def pz(z):
        return float(np.exp(ps.log_prior_z(np.array([[z]]))[0]))

    total, _ = integrate.quad(pz, zlo, zhi, limit=400, points=[0.0] if zlo < 0 < zhi else None)
    assert total == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(("prior", "transform"), CASES)
def test_ppf_draws_follow_the_density(prior, transform):
    """Draws through the quantile function pass a KS test against the integrated density."""
    ps = PriorSet(("x",), (prior,), (transform,))
    x = ps.sample(4000, rng=np.random.default_rng(3))[:, 0]
    lo, hi = prior.support

    def cdf(v):
        a = max(lo, -1e3)
        return integrate.quad(lambda s: float(np.exp(prior.logpdf(s))), a, v, limit=200)[0]

    grid = np.quantile(x, [0.1, 0.3, 0.5, 0.7, 0.9])
    emp = np.array([np.mean(x <= g) for g in grid])
    ref = np.array([cdf(g) for g in grid])
    # binomial standard error of an empirical CDF value, n = 4000: <= 0.008
    assert np.max(np.abs(emp - ref)) < 4 * 0.008


def test_transform_round_trip_and_jacobian_by_finite_differences():
    ps = default_priors(_model("free"), noise="ar1")
    theta = np.r_[6.2, 1.5, 1.4, 1.1, 2.9, 1.8, 2.0, 0.3, 0.0, 6e-5, 6e-5, 6e-5, 0.999, 0.5,
                  -0.3]
    z = ps.to_sampling(theta)
    assert np.allclose(ps.to_physical(z), theta, rtol=1e-12, atol=1e-15)
    # log|det J| of the diagonal map by central differences, parameter by parameter
    h = 1e-6
    num = 0.0
    for i in range(theta.size):
        zp, zm = z.copy(), z.copy()
        zp[i] += h
        zm[i] -= h
        num += np.log((ps.to_physical(zp)[i] - ps.to_physical(zm)[i]) / (2 * h))
    assert ps.log_jacobian(z) == pytest.approx(num, abs=1e-6)


def test_default_priors_match_model_and_documented_bounds():
    ps = default_priors(_model("free"), noise="ar1")
    assert ps.names == _model("free").names + noise_names(3, "ar1")
    d = dict(zip(ps.names, ps.priors, strict=True))
    assert d["g_v"].support == (1.0, 15.0)
    assert d["m2"].support == (0.2, 5.0)
    assert d["c12"].support == (0.0, 20.0)
    assert isinstance(d["sigma_1"], LogUniform)
    assert d["phi_3"].support == (-1.0, 1.0)
    tr = dict(zip(ps.names, ps.transforms, strict=True))
    assert tr["g_v"] == "log" and tr["c12"] == "identity" and tr["phi_1"] == "tanh"
    pp = default_priors(_model("proportional"), noise="white")
    assert pp.names[-5:] == ("ca", "cb", "sigma_1", "sigma_2", "sigma_3")


def test_outside_support_is_minus_inf_not_error():
    ps = default_priors(_model("proportional"), noise="ar1")
    bad = np.array([
        [6.2, -1.5, 1.4, 1.1, 1.6, 1e-4, 1e-5, 1e-5, 1e-5, 0.5, 0.5, 0.5],  # negative mass
        [6.2, 1.5, 1.4, 1.1, 1.6, -1e-4, 1e-5, 1e-5, 1e-5, 0.5, 0.5, 0.5],  # negative cb
        [6.2, 1.5, 1.4, 1.1, 1.6, 1e-4, 1e-5, 1e-5, 1e-5, 1.5, 0.5, 0.5],  # |phi| > 1
        [np.nan, 1.5, 1.4, 1.1, 1.6, 1e-4, 1e-5, 1e-5, 1e-5, 0.5, 0.5, 0.5],
    ])
    assert np.all(ps.log_prior(bad) == -np.inf)


def test_overrides_and_json_round_trip():
    ps = default_priors(_model("proportional"), noise="ar1",
                        overrides={"g_v": Normal(6.2, 0.3, lo=0.0)})
    assert isinstance(ps.priors[0], Normal)
    back = PriorSet.from_json(ps.to_json())
    x = ps.sample(5, rng=1)
    assert np.allclose(back.log_prior(x), ps.log_prior(x))
    with pytest.raises(ConfigError, match="unknown parameter 'k1'"):
        ps.replace({"k1": Uniform(0, 1)})
    with pytest.raises(ConfigError):
        Uniform(3.0, 1.0)
    with pytest.raises(ConfigError, match="log transform"):
        PriorSet(("x",), (Uniform(-1, 1),), ("log",))


def test_normal_truncation_is_normalised():
    p = Normal(0.0, 1.0, lo=0.0)
    x = np.linspace(0, 1, 5)
    assert np.allclose(np.exp(p.logpdf(x)), 2 * stats.norm.pdf(x))


def _model(damping):
    from bayesmodal.model.system import LinearModel, Rig

    return LinearModel(Rig(), damping)


def test_batched_log_prior_is_the_sum_of_the_priors_bit_for_bit():
    # PriorSet evaluates each kind of prior in one call; the result must be the per-prior
    # sum in parameter order, exactly, inside, outside and on the edges of the supports.
    priors = (Uniform(0.5, 2.0), LogUniform(1e-3, 10.0), Normal(1.0, 0.3),
              Normal(0.0, 1.0, lo=-0.5, hi=2.0), Uniform(-1.0, 1.0), LogUniform(0.1, 1e4))
    ps = PriorSet(tuple("abcdef"), priors, ("identity",) * 6)
    rng = np.random.default_rng(7)
    theta = rng.uniform(-1.5, 3.0, size=(200, 6))
    theta[:6] = [p.support[0] for p in priors]       # on the lower edges
    theta[6:12] = [p.support[1] if np.isfinite(p.support[1]) else 5.0 for p in priors]
    reference = np.zeros(theta.shape[0])
    for i, p in enumerate(priors):
        reference = reference + p.logpdf(theta[:, i])
    reference = np.where(np.isnan(reference), -np.inf, reference)
    got = ps.log_prior(theta)
    assert np.array_equal(got, reference)
    assert np.isfinite(got).any() and np.isinf(got).any()   # both branches exercised
    assert ps.log_prior(theta[3]) == reference[3]           # a single vector too
