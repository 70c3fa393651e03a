"""Numerical edge cases of the rig model: near-zero damping, nearly repeated frequencies,
very stiff and very soft springs, masses 1000x apart, one cart and ten carts.

The simulator is compared with ``scipy.signal.lsim`` (ZOH) and a matrix-exponential
recursion; the three modal methods with ``scipy.linalg.eigh``; where a method cannot be
accurate (matrix iteration on nearly repeated frequencies) it must say so.  The sampler's
log-posterior and the likelihood must return ``-inf`` (never raise, never NaN) for any
walker position, however impossible.  (Generic pencils with prescribed spectra are in
``test_modal.py``; these are the physical chain rigs.)
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal as ss
from conftest import zoh_rtol

from bayesmodal.data import Experiment
from bayesmodal.inference import Likelihood, LogPosterior, LogUniform, default_priors
from bayesmodal.modal import ConvergenceError, matrix_iteration, rayleigh_modes, undamped_modes
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

# (id, springs N/m, masses kg, free damping: absolute c_i then relative c_i,i+1 in N s/m)
EDGES = {
    "near_zero_damping": ((774.0, 770.0, 396.0), (1.5, 1.4, 1.1), (1e-9,) * 3 + (1e-9,) * 2),
    "zero_damping": ((774.0, 770.0, 396.0), (1.5, 1.4, 1.1), (0.0,) * 5),
    "nearly_repeated": ((0.005, 500.0), (1e-5, 1.0), (1e-4, 1e-3, 0.0)),
    "very_stiff_spring": ((1e7, 770.0, 396.0), (1.5, 1.4, 1.1), (2.9, 1.8, 2.0, 0.0, 0.0)),
    "very_soft_spring": ((774.0, 1e-3, 396.0), (1.5, 1.4, 1.1), (2.9, 1.8, 2.0, 0.0, 0.0)),
    "stiff_and_soft": ((1e6, 1e-2, 1e4), (1.5, 1.4, 1.1), (0.5, 0.5, 0.5, 0.1, 0.1)),
    "masses_1000x": ((774.0, 770.0, 396.0), (0.01, 10.0, 1.0), (0.1, 1.8, 2.0, 0.0, 0.0)),
    "one_cart": ((500.0,), (1.2,), (0.7,)),
    "one_cart_undamped": ((500.0,), (1.2,), (0.0,)),
    "ten_carts": (tuple(np.linspace(300.0, 900.0, 10)), tuple(np.linspace(0.5, 2.0, 10)),
                  tuple(np.full(10, 0.8)) + tuple(np.full(9, 0.2))),
}


def _model(key):
    springs, masses, damping = EDGES[key]
    model = LinearModel(Rig(springs), "free")
    return model, np.array([5.0, *masses, *damping])


def _lsim(model, theta, u, dt, x0=None):
    A, B = model.state_space(theta)
    n = model.n_carts
    t = np.arange(u.size) * dt
    _, y, _ = ss.lsim((A, B[:, None], np.eye(2 * n)[:n], np.zeros((n, 1))), u, t, X0=x0,
                      interp=False)
    return y.reshape(u.size, n)


def _expm_recursion(model, theta, u, dt, x0):
    A, B = model.state_space(theta)
    s = A.shape[0]
    big = np.zeros((s + 1, s + 1))
    big[:s, :s] = A * dt
    big[:s, s] = B * dt
    E = scipy.linalg.expm(big)
    Ad, Bd = E[:s, :s], E[:s, s]
    x = np.array(x0, float)
    out = np.empty((u.size, model.n_carts))
    for k in range(u.size):
        out[k] = x[: model.n_carts]
        x = Ad @ x + Bd * u[k]
    return out


@pytest.mark.parametrize("key", sorted(EDGES))
def test_simulator_matches_lsim_and_expm(key):
    model, theta = _model(key)
    rng = np.random.default_rng(sorted(EDGES).index(key))
    n_samples, dt = 3000, 0.005
    u = rng.normal(size=n_samples)
    x0 = np.r_[rng.normal(size=model.n_carts) * 1e-3, np.zeros(model.n_carts)]
    y = simulate_linear(model, theta, u, dt, x0=x0)
    assert np.all(np.isfinite(y))
    ref = _lsim(model, theta, u, dt, x0)
    scale = np.abs(ref).max()
    # each within the ZOH bound of the exact answer (conditioning of the eigenbasis, memory
    # of the recursion up to the record length, phase drift of the eigenvalue error)
    A, _ = model.state_space(theta)
    assert np.max(np.abs(y - ref)) / scale < 2 * zoh_rtol(A, dt, n_steps=n_samples)
    # an independent exact recursion, on a shorter stretch (it is a Python loop)
    short = _expm_recursion(model, theta, u[:500], dt, x0)
    assert (np.max(np.abs(y[:500] - short)) / np.abs(short).max()
            < 2 * zoh_rtol(A, dt, n_steps=500))


def test_undamped_response_keeps_its_amplitude():
    # zero damping: the free response of each mode neither decays nor grows over 10^4
    # samples (a lossy or unstable discretisation would show here)
    model, theta = _model("zero_damping")
    M, _, K, _ = model.matrices(theta)
    w2, U = scipy.linalg.eigh(K, M)
    x0 = np.r_[U[:, 0] * 1e-3, np.zeros(3)]
    y = simulate_linear(model, theta, np.zeros(20000), 0.005, x0=x0)
    # the amplitude of a sampled sinusoid x_k = a cos(w k dt), exactly, without the
    # sampling error of a peak: a^2 = x_k^2 + ((x_k+1 - x_k-1) / (2 sin(w dt)))^2
    s = np.sin(np.sqrt(w2[0]) * 0.005)
    x = y[:, 0]
    amp = np.hypot(x[1:-1], (x[2:] - x[:-2]) / (2 * s))
    first, last = amp[:4000].mean(), amp[-4000:].mean()
    # the ZOH bound on x, amplified 1 / s by the difference quotient
    A, _ = model.state_space(theta)
    rtol = 2 * zoh_rtol(A, 0.005, n_steps=20000) * (1 + 1 / s)
    assert last == pytest.approx(first, rel=rtol)
    assert first == pytest.approx(abs(x0[0]), rel=rtol)


METHODS = {"eigen": undamped_modes, "rayleigh": rayleigh_modes, "iteration": matrix_iteration}


def _mac_min(a, b):
    num = np.abs(np.einsum("im,im->m", a, b)) ** 2
    return float(np.min(num / (np.einsum("im,im->m", a, a) * np.einsum("im,im->m", b, b))))


def eigh_reference(M, K):
    """omega^2 and shapes from ``scipy.linalg.eigh``, each mode from the better conditioned
    of ``eigh(K, M)`` (absolute error about eps * omega^2_max) and ``eigh(M, K)`` (relative
    error about eps * omega^2_i / omega^2_min): when omega^2 spans many decades the first
    loses digits on the lowest modes (7e-9 relative for ``stiff_and_soft``)."""
    w2, V = scipy.linalg.eigh(K, M)
    mu, W = scipy.linalg.eigh(M, K)
    mu, W = mu[::-1], W[:, ::-1]
    inverse = w2 / w2[0] < w2[-1] / w2
    return np.where(inverse, 1.0 / mu, w2), np.where(inverse[None], W, V)


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("key", sorted(EDGES))
def test_modal_methods_match_eigh_or_fail_clearly(key, method):
    model, theta = _model(key)
    M, _, K, _ = model.matrices(theta)
    w2, V = eigh_reference(M, K)
    gaps = np.diff(w2) / w2[1:] if w2.size > 1 else np.array([1.0])
    try:
        modes = METHODS[method](M, K)
    except ConvergenceError as exc:
        # only power iteration may give up, saying why: a slow rate (w_i/w_j)^2 near 1, or
        # rounding in the deflation when omega^2 spans many decades
        assert method == "iteration"
        if gaps.min() < 0.01:
            assert "nearly repeated" in str(exc)
        else:
            assert w2[-1] / w2[0] > 1e6, (w2, str(exc))
            assert "spans a factor" in str(exc) and "very stiff or very soft" in str(exc)
        return
    np.testing.assert_allclose(modes.omega_rad_s, np.sqrt(w2), rtol=1e-10)
    # shapes: MAC against eigh, to the conditioning of the pair (eps / relative gap)
    assert _mac_min(modes.shapes, V) > 1 - max(1e-10, 1e-12 / gaps.min())


def test_lowest_mode_of_a_wide_spectrum_beats_plain_eigh():
    # omega^2 spans 4e8: eigh(K, M) is off by ~7e-9 on the lowest mode, the package's
    # methods are within rounding of the reference above
    model, theta = _model("stiff_and_soft")
    M, _, K, _ = model.matrices(theta)
    w2, _ = eigh_reference(M, K)
    plain = scipy.linalg.eigh(K, M, eigvals_only=True)
    assert abs(np.sqrt(plain[0] / w2[0]) - 1) > 1e-10  # the reference matters here
    for method in ("eigen", "rayleigh"):
        om = METHODS[method](M, K).omega_rad_s
        assert abs(om[0] / np.sqrt(w2[0]) - 1) < 1e-13


def test_nearly_repeated_case_is_nearly_repeated():
    # the edge case is what it claims: two frequencies within 0.5 %
    model, theta = _model("nearly_repeated")
    M, _, K, _ = model.matrices(theta)
    w = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    assert w[1] / w[0] - 1 < 5e-3
    with pytest.raises(ConvergenceError, match="nearly repeated"):
        matrix_iteration(M, K, max_iter=2000)


def test_ten_carts_matrix_iteration_counts_are_reported():
    model, theta = _model("ten_carts")
    M, _, K, _ = model.matrices(theta)
    modes = matrix_iteration(M, K)
    assert modes.n_iterations.shape == (10,) and np.all(modes.error_bound < 1e-8)


# ---------------------------------------------------------------- the sampler never crashes
def _record():
    model = LinearModel(Rig(), "free")
    theta = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])
    t = np.arange(300) * 0.005
    v = np.where(t < 0.05, 3.0, 0.0)
    y = simulate_linear(model, theta, v, 0.005)
    y = y + np.random.default_rng(0).normal(size=y.shape) * 1e-5
    return model, theta, Experiment(t, v, y, name="rec")


@pytest.mark.parametrize("noise", ["ar1", "white"])
def test_log_posterior_is_minus_inf_in_impossible_regions(noise):
    model, theta, e = _record()
    lik = Likelihood(model, [e], noise=noise)
    priors = default_priors(model, noise=noise, n_outputs=3)
    # a prior so wide that extreme mechanical values reach the likelihood
    wide = {nm: LogUniform(1e-200, 1e200) for nm in model.names[:4]}
    for pr in (priors, priors.replace(wide)):
        lp = LogPosterior(lik, pr)
        P = pr.n_params
        noise_par = np.r_[np.full(3, 1e-5), np.full(3, 0.5)] if noise == "ar1" else \
            np.full(3, 1e-5)
        z0 = pr.to_sampling(np.r_[theta, noise_par][None])
        rows = [np.full(P, np.nan), np.full(P, np.inf), np.full(P, -np.inf),
                np.full(P, 1e308), np.full(P, -1e308), np.zeros(P)]
        rng = np.random.default_rng(1)
        rows += list(z0 + rng.normal(size=(20, P)) * 50)  # far outside any sensible region
        for i in range(P):  # one coordinate wild at a time
            for bad in (np.nan, np.inf, -np.inf, 1e300, -1e300):
                r = z0[0].copy()
                r[i] = bad
                rows.append(r)
        Z = np.array(rows)
        out = lp(Z)  # a RuntimeWarning would fail too (warnings are errors in the tests)
        assert out.shape == (len(Z), 2)
        assert not np.any(np.isnan(out)), Z[np.isnan(out).any(axis=1)][:3]
        assert not np.any(out[:, 0] == np.inf)
        assert np.all(np.isneginf(out[:6, 0]))
        assert np.isfinite(lp(z0)[0, 0])  # and the sensible point is fine


def test_likelihood_is_minus_inf_for_impossible_physical_parameters():
    model, theta, e = _record()
    lik = Likelihood(model, [e], noise="ar1")
    good = np.r_[theta, np.full(3, 1e-5), np.full(3, 0.5)]
    rows = [good]
    for i, bad in [(1, -1.0), (1, 0.0), (0, 0.0), (4, -0.1), (9, 0.0), (9, -1e-5),
                   (12, 1.0), (12, -1.0), (12, 1.5), (1, 1e-300), (1, 1e300), (4, 1e300),
                   (0, 1e300), (2, np.nan), (3, np.inf)]:
        r = good.copy()
        r[i] = bad
        rows.append(r)
    out = lik(np.array(rows))
    assert np.isfinite(out[0])
    assert not np.any(np.isnan(out)) and not np.any(out == np.inf)
    impossible = [1, 2, 3, 4, 5, 6, 7, 8, 9, 14, 15]  # negative, zero, |phi| >= 1, NaN, inf
    assert np.all(np.isneginf(out[impossible])), out


def test_wide_log_uniform_prior_is_finite_inside():
    # regression: log(hi / lo) overflowed for hi / lo > 1e308 and made the density -inf
    pr = LogUniform(1e-200, 1e200)
    assert pr.logpdf(np.array(1.0)) == pytest.approx(-np.log(400 * np.log(10.0)))
    assert pr.ppf(np.array([0.0, 0.5, 1.0])) == pytest.approx([1e-200, 1.0, 1e200], rel=1e-12)
