"""AR(p) noise: exact density against the dense Toeplitz normal, order choice by BIC."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.linalg import solve_toeplitz, toeplitz
from scipy.signal import lfilter

from bayesmodal._errors import ConfigError, DataError
from bayesmodal.inference.likelihood import ar1_terms
from bayesmodal.inference.noise import ARpNoise, burg, choose_order, levinson_table, pacf_to_ar

EPS = np.finfo(float).eps


def _autocov(a, sigma, n_lags):
    """Autocovariance gamma_0..gamma_{n_lags-1} from the MA(inf) weights (brute force).

    psi = impulse response of 1 / (1 - sum a_i z^i), truncated where it is below eps.
    """
    n_psi = 200
    while True:
        imp = np.zeros(n_psi)
        imp[0] = 1.0
        psi = lfilter([1.0], np.r_[1.0, -np.asarray(a)], imp)
        if np.abs(psi[-50:]).max() < 1e-17 * np.abs(psi).max():
            break
        n_psi *= 2
    return sigma**2 * np.array([psi[: n_psi - k] @ psi[k:] for k in range(n_lags)])


def _kappas(rng, p):
    return rng.uniform(-0.9, 0.9, p)


@pytest.mark.parametrize("p", [1, 2, 3, 4])
def test_pacf_map_gives_stationary_ar_whose_pacf_is_kappa(p):
    """kappa -> a (Durbin-Levinson) -> gamma (brute force) -> PACF (Toeplitz solve) = kappa."""
    rng = np.random.default_rng(p)
    for _ in range(5):
        kappa = _kappas(rng, p)
        a = pacf_to_ar(kappa)
        roots = np.roots(np.r_[-a[::-1], 1.0])  # 1 - a_1 z - ... - a_p z^p
        assert np.all(np.abs(roots) > 1)
        g = _autocov(a, 1.0, p + 1)
        pacf = [solve_toeplitz(g[:m], g[1 : m + 1])[-1] for m in range(1, p + 1)]
        cond = np.linalg.cond(toeplitz(g[:p]))
        assert np.allclose(pacf, kappa, atol=100 * cond * EPS)
        # the stationary variance is sigma^2 c_0
        _, c = levinson_table(kappa)
        assert g[0] == pytest.approx(c[0], rel=100 * cond * EPS)


@pytest.mark.parametrize("p", [1, 2, 3, 4])
@pytest.mark.parametrize("n", [9, 40])
def test_exact_loglik_equals_dense_toeplitz_normal(p, n):
    rng = np.random.default_rng(10 * p + n)
    orders = (p, max(p - 1, 1), 1)
    model = ARpNoise(orders)
    nb = 3
    sig = rng.uniform(0.2, 2.0, (nb, 3))
    kap = np.stack([np.stack([np.r_[_kappas(rng, q), np.zeros(p - q)] for q in orders])
                    for _ in range(nb)])
    params = model.join(sig, kap)
    r = rng.normal(size=(nb, n, 3))
    got = model.loglik(np.moveaxis(r, 0, -1), params)
    pw = model.pointwise(r, params)
    for b in range(nb):
        ref, tol = 0.0, 0.0
        for j, q in enumerate(orders):
            a = pacf_to_ar(kap[b, j, :q])
            cov = toeplitz(_autocov(a, sig[b, j], n))
            ref += stats.multivariate_normal(np.zeros(n), cov).logpdf(r[b, :, j])
            tol += 100 * n * np.linalg.cond(cov) * EPS
        assert abs(got[b] - ref) <= tol * max(1.0, abs(ref))
        assert abs(pw[b].sum() - ref) <= tol * max(1.0, abs(ref))


def test_ar1_case_equals_ar1_terms_and_padding_with_zero_pacf_changes_nothing():
    rng = np.random.default_rng(3)
    nb, n = 4, 300
    sig, phi = rng.uniform(0.5, 2, (nb, 2)), rng.uniform(-0.99, 0.99, (nb, 2))
    r = rng.normal(size=(nb, n, 2))
    ref = ar1_terms(r, sig, phi)
    got = ARpNoise((1, 1)).pointwise(r, np.c_[sig, phi])
    assert np.allclose(got, ref, rtol=8 * EPS, atol=8 * EPS * np.abs(ref).max())
    padded = ARpNoise((3, 2))
    kap = np.zeros((nb, 2, 3))
    kap[:, :, 0] = phi
    got3 = padded.pointwise(r, padded.join(sig, kap))
    assert np.allclose(got3, ref, rtol=64 * EPS, atol=64 * EPS * np.abs(ref).max())


@pytest.mark.parametrize("orders", [(1, 1, 1), (2, 3, 4), (6, 1, 2)])
def test_fast_loglik_equals_sum_of_pointwise_within_the_cancellation_bound(orders):
    """Bound: N eps sum |a_i a_l| S_il / sigma^2, from forming a' S a out of lag sums."""
    rng = np.random.default_rng(sum(orders))
    model = ARpNoise(orders)
    nb, n = 8, 3000
    sig = rng.uniform(1e-5, 1e-4, (nb, 3))
    P = max(orders)
    kap = np.zeros((nb, 3, P))
    for j, q in enumerate(orders):
        kap[:, j, :q] = rng.uniform(-0.95, 0.99, (nb, q))
    params = model.join(sig, kap)
    r = model.simulate(params, n, rng=2)
    got = model.loglik(np.moveaxis(r, 0, -1), params)
    pw = model.pointwise(r, params)
    a = np.concatenate([np.ones((nb, 3, 1)), -pacf_to_ar(kap)], axis=2)
    absr = np.abs(r)
    bound = np.zeros(nb)
    for i in range(P + 1):
        for m in range(P + 1):
            s_abs = np.einsum("bkj,bkj->bj", absr[:, P - i : n - i], absr[:, P - m : n - m])
            bound += np.sum(np.abs(a[:, :, i] * a[:, :, m]) * s_abs / sig**2, axis=1)
    bound = n * EPS * bound + 2 * n * EPS * np.abs(pw).sum(axis=(1, 2))
    assert np.all(np.abs(got - pw.sum(axis=(1, 2))) <= bound)


def test_simulate_has_the_stationary_covariance_from_the_first_sample():
    """Sample covariance of the first 6 samples over many draws vs the Toeplitz truth."""
    kappa = np.array([0.8, -0.6, 0.3])
    model = ARpNoise((3,))
    n_draw, n = 20000, 6
    r = model.simulate(model.join(np.array([[0.5]]), kappa[None, None]).repeat(n_draw, 0), n,
                       rng=11)[:, :, 0]
    g = toeplitz(_autocov(pacf_to_ar(kappa), 0.5, n))
    emp = r.T @ r / n_draw
    se = np.sqrt((np.outer(np.diag(g), np.diag(g)) + g**2) / n_draw)
    # 21 distinct entries: 4.5 standard errors keeps the family-wise false alarm < 1e-3
    assert np.all(np.abs(emp - g) < 4.5 * se)


def test_start_recovers_the_pacf_within_standard_errors():
    kappa = np.array([[0.9, -0.5, 0.0], [0.6, 0.3, -0.4]])
    model = ARpNoise((2, 3))
    sig = np.array([[1e-5, 2e-5]])
    n = 20000
    r = model.simulate(model.join(sig, kappa[None]), n, rng=5)[0]
    est_sig, est_kap = model.split(model.start(r)[None])
    # asymptotic sd of a PACF estimate is at most 1/sqrt(N); of sigma, sigma/sqrt(2N)
    assert np.all(np.abs(est_kap[0] - kappa) < 4 / np.sqrt(n))
    assert np.all(np.abs(est_sig - sig) < 4 * sig / np.sqrt(2 * n))


@pytest.mark.parametrize("kappa", [(0.7, -0.4), (0.9, -0.5, 0.35)])
def test_choose_order_finds_the_true_order_in_most_seeds(kappa):
    """BIC is consistent: require the success rate be compatible with >= 85 %."""
    kappa = np.array(kappa)
    p0 = kappa.size
    model = ARpNoise((p0,))
    n_seeds, n = 40, 1500
    params = model.join(np.ones((n_seeds, 1)), np.tile(kappa, (n_seeds, 1, 1)))
    r = model.simulate(params, n, rng=21)
    chosen = np.array([choose_order(r[s], max_p=8).orders[0] for s in range(n_seeds)])
    hits = int(np.sum(chosen == p0))
    assert hits >= stats.binom.ppf(1e-3, n_seeds, 0.85)
    assert np.all(chosen >= p0 - 1)


def test_choose_order_picks_nothing_on_white_noise():
    """Negative control: each spurious lag needs chi2_1 > log N (p ~ 0.002 at N = 1500)."""
    rng = np.random.default_rng(8)
    n_seeds, n = 40, 1500
    chosen = [choose_order(rng.normal(size=(n, 3)), max_p=8).orders for _ in range(n_seeds)]
    too_high = int(np.sum(np.array(chosen) > 0))
    assert too_high <= stats.binom.ppf(1 - 1e-3, 3 * n_seeds, 0.05)


def test_choose_order_warns_when_the_cap_is_chosen():
    model = ARpNoise((3,))
    r = model.simulate(model.join(np.ones((1, 1)), np.array([[[0.9, -0.5, 0.35]]])), 1500,
                       rng=3)[0]
    with pytest.warns(UserWarning, match="largest order max_p = 2"):
        assert choose_order(r, max_p=2).orders == (2,)


def test_burg_reflection_coefficients_bounded_and_power_decreases():
    r = np.cumsum(np.random.default_rng(0).normal(size=(500, 2)), axis=0)  # near unit root
    kappa, power = burg(r, 5)
    assert np.all(np.abs(kappa) <= 1)
    assert np.all(np.diff(power, axis=1) <= 0)


def test_bad_inputs():
    with pytest.raises(ConfigError, match="orders"):
        ARpNoise((0, 1))
    with pytest.raises(DataError, match="one order per output"):
        ARpNoise((1, 2)).names(3)
    with pytest.raises(DataError, match="too short"):
        ARpNoise((4,)).loglik(np.zeros((3, 1, 1)), np.array([[1, 0, 0, 0, 0.0]]))
    with pytest.raises(ConfigError, match="max_p"):
        choose_order(np.zeros((10, 1)) + 1.0, max_p=20)


def test_measured_residuals_are_not_low_order_ar(impulses):
    """docs/noise_models.md: on the rig the order choice runs into the cap, with a warning,
    and AR(p) at the Burg start beats AR(1) at its moment start."""
    from bayesmodal.inference.noise import AR1Noise
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig

    table3 = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])
    r = impulses.y_m - simulate_linear(LinearModel(Rig(), "free"), table3, impulses.v_volt,
                                       impulses.dt)
    with pytest.warns(UserWarning, match="largest order"):
        choice = choose_order(r, max_p=8)
    assert choice.orders == (8, 8, 8)
    ar = choice.model()
    ll_p = ar.loglik(r[:, :, None], ar.start(r)[None])[0]
    ll_1 = AR1Noise().loglik(r[:, :, None], AR1Noise().start(r)[None])[0]
    # the gain pays for the extra parameters by BIC's standard (at the Burg start, not the
    # maximum, so this is a check of start() on real data too)
    n_extra = sum(choice.orders) - 3
    assert ll_p - ll_1 > 0.5 * n_extra * np.log(r.shape[0])
