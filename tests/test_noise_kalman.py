"""Process-noise likelihood: Van Loan, DARE, dense joint Gaussian, time-varying filter."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import quad_vec
from scipy.linalg import expm, solve_discrete_are
from scipy.signal import cont2discrete

from bayesmodal._errors import ConfigError, DataError
from bayesmodal.inference.likelihood import white_terms
from bayesmodal.inference.noise.kalman import (
    ProcessNoise,
    kalman_loglik,
    kalman_pointwise,
    simulate_process_noise,
)
from bayesmodal.inference.noise.steady_filter import (
    discretize_process_noise,
    solve_filter_dare,
    steady_state_filter,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

EPS = np.finfo(float).eps
DT = 0.005
THETA = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])
MODEL = LinearModel(Rig(), "proportional")
C = np.eye(3, 6)


def _batch(nb, seed=0):
    rng = np.random.default_rng(seed)
    th = THETA * (1 + 0.05 * rng.random((nb, 6)))
    q = 10 ** rng.uniform(-7, -4, (nb, 3))
    sig = 10 ** rng.uniform(-5.5, -4.5, (nb, 3))
    return th, q, sig


def _input(n):
    t = np.arange(n) * DT
    return np.where((t >= 0.02) & (t < 0.07), 3.0, 0.0)


def test_van_loan_qd_equals_the_integral_and_ad_bd_equal_cont2discrete():
    th, q, _ = _batch(2)
    sysd = discretize_process_noise(MODEL, th, q, DT)
    for b in range(2):
        A, B = MODEL.state_space(th[b])
        GQG = np.zeros((6, 6))
        GQG[3:, 3:] = np.diag(q[b] / th[b, 1:4] ** 2)
        ref, err = quad_vec(lambda s, A=A, GQG=GQG: expm(A * s) @ GQG @ expm(A * s).T, 0, DT,
                            epsabs=0, epsrel=1e-13)
        assert np.all(np.abs(sysd.Qd[b] - ref) <= 10 * err + 100 * EPS * np.abs(ref).max())
        Ad, Bd, *_ = cont2discrete((A, B[:, None], C, np.zeros((3, 1))), DT, "zoh")
        assert np.allclose(sysd.Ad[b], Ad, rtol=0, atol=100 * EPS)
        assert np.allclose(sysd.Bd[b], Bd[:, 0], rtol=0, atol=100 * EPS * np.abs(Bd).max())


def _dare_residual(Ad, Qd, R, P):
    S = C @ P @ C.T + R
    return Ad @ P @ Ad.T - Ad @ P @ C.T @ np.linalg.solve(S, C @ P @ Ad.T) + Qd - P


def test_doubling_dare_solves_the_riccati_equation_and_stabilises():
    th, q, sig = _batch(6, seed=1)
    q[2] = 0.0          # no process noise: P = 0
    q[3, 1:] = 0.0      # force on one cart only
    sysd = discretize_process_noise(MODEL, th, q, DT)
    P = solve_filter_dare(sysd.Ad, sysd.Qd, sig**2)
    assert np.all(P[2] == 0)
    for b in range(6):
        R = np.diag(sig[b] ** 2)
        res = np.abs(_dare_residual(sysd.Ad[b], sysd.Qd[b], R, P[b])).max()
        assert res <= 100 * EPS * max(np.abs(P[b]).max(), np.abs(sysd.Qd[b]).max())
        assert np.all(np.linalg.eigvalsh(P[b]) >= -100 * EPS * np.abs(P[b]).max())
        K = P[b] @ C.T @ np.linalg.inv(C @ P[b] @ C.T + R)
        rho = np.abs(np.linalg.eigvals(sysd.Ad[b] - sysd.Ad[b] @ K @ C)).max()
        assert rho < 1
        if q[b].any():
            # scipy's solver (scaled); its own residual over (1 - rho^2) bounds the gap
            sc = sig[b].max() ** 2
            Pr = sc * solve_discrete_are(sysd.Ad[b].T, C.T, sysd.Qd[b] / sc, R / sc)
            res_r = np.abs(_dare_residual(sysd.Ad[b], sysd.Qd[b], R, Pr)).max()
            gap = np.abs(P[b] - Pr).max()
            assert gap <= 100 * (res_r + res) / (1 - rho**2) + 100 * EPS * np.abs(P[b]).max()


def _dense_loglik(sysd, b, sigma, v, y, P0):
    """log N(y; mean, Sigma) of the whole record, from the state covariances (brute force)."""
    n = v.size
    Ad, Bd, Qd = sysd.Ad[b], sysd.Bd[b], sysd.Qd[b]
    x = np.zeros(6)
    mean = np.empty((n, 3))
    covs = [P0]
    for k in range(n):
        mean[k] = x[:3]
        x = Ad @ x + Bd * v[k]
        covs.append(Ad @ covs[-1] @ Ad.T + Qd)
    big = np.zeros((3 * n, 3 * n))
    for ll in range(n):
        M = covs[ll]
        for k in range(ll, n):
            blk = C @ M @ C.T
            big[3 * k : 3 * k + 3, 3 * ll : 3 * ll + 3] = blk
            big[3 * ll : 3 * ll + 3, 3 * k : 3 * k + 3] = blk.T
            M = Ad @ M
    big += np.kron(np.eye(n), np.diag(sigma**2))
    lp = stats.multivariate_normal(mean.ravel(), big).logpdf(y.ravel())
    return lp, np.linalg.cond(big)


def _tv_filter(sysd, b, sigma, v, y, P0):
    """Time-varying Kalman filter written independently of the library (covariance form)."""
    Ad, Bd, Qd = sysd.Ad[b], sysd.Bd[b], sysd.Qd[b]
    R = np.diag(sigma**2)
    x, P, ll = np.zeros(6), P0.copy(), 0.0
    for k in range(v.size):
        S = C @ P @ C.T + R
        e = y[k] - C @ x
        ll += stats.multivariate_normal(np.zeros(3), S).logpdf(e)
        K = P @ C.T @ np.linalg.inv(S)
        x = x + K @ e
        P = (np.eye(6) - K @ C) @ P
        P = 0.5 * (P + P.T)
        x = Ad @ x + Bd * v[k]
        P = Ad @ P @ Ad.T + Qd
    return ll


def test_steady_state_filter_is_the_dense_gaussian_with_x0_from_p_and_tv_filter_agrees():
    n = 40
    th, q, sig = _batch(3, seed=2)
    v = _input(n)
    sysd = discretize_process_noise(MODEL, th, q, DT)
    filt = steady_state_filter(sysd, sig)
    y = simulate_process_noise(MODEL, th[:1], q[:1], sig[:1], v, DT, rng=3)[0]
    got = kalman_loglik(MODEL, th, q, sig, v, y, DT)
    for b in range(3):
        ref, cond = _dense_loglik(sysd, b, sig[b], v, y, filt.P[b])
        tol = 100 * cond * EPS * max(1.0, abs(ref))
        assert abs(got[b] - ref) <= tol
        # the test's own time-varying filter: from P and from rest
        assert abs(_tv_filter(sysd, b, sig[b], v, y, filt.P[b]) - ref) <= tol
        ref0, cond0 = _dense_loglik(sysd, b, sig[b], v, y, np.zeros((6, 6)))
        tv0 = _tv_filter(sysd, b, sig[b], v, y, np.zeros((6, 6)))
        assert abs(tv0 - ref0) <= 100 * cond0 * EPS * max(1.0, abs(ref0))


@pytest.mark.parametrize("n", [40, 1600])
def test_initial_rest_is_the_exact_filter_from_p0_zero(n):
    """The Woodbury correction equals the time-varying filter from rest (and, for small N,
    the dense Gaussian with x_0 = 0); long records exercise the truncated adjoint sum."""
    th, q, sig = _batch(3, seed=12)
    q[2] = 0.0  # P = 0: nothing to correct
    v = _input(n)
    sysd = discretize_process_noise(MODEL, th, q, DT)
    y = simulate_process_noise(MODEL, th[:1], q[:1], sig[:1], v, DT, rng=13)[0]
    got = kalman_loglik(MODEL, th, q, sig, v, y, DT, initial="rest")
    steady = kalman_loglik(MODEL, th, q, sig, v, y, DT)
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT)
    for b in range(3):
        tv = _tv_filter(sysd, b, sig[b], v, y, np.zeros((6, 6)))
        assert abs(got[b] - tv) <= 8 * n * EPS * np.abs(pw[b]).sum()
        if n <= 40:
            ref, cond = _dense_loglik(sysd, b, sig[b], v, y, np.zeros((6, 6)))
            assert abs(got[b] - ref) <= 100 * cond * EPS * max(1.0, abs(ref))
    assert got[2] == steady[2]


def test_free_damping_model_matches_the_dense_gaussian_too():
    model = LinearModel(Rig(), "free")
    th = np.array([[6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001]])
    q, sig = np.array([[3e-6, 1e-6, 5e-7]]), np.array([[1e-5, 2e-5, 1.5e-5]])
    n = 30
    v = _input(n)
    y = simulate_process_noise(model, th, q, sig, v, DT, rng=16)[0]
    sysd = discretize_process_noise(model, th, q, DT)
    P = steady_state_filter(sysd, sig).P
    for initial, P0 in (("steady", P[0]), ("rest", np.zeros((6, 6)))):
        ref, cond = _dense_loglik(sysd, 0, sig[0], v, y, P0)
        got = kalman_loglik(model, th, q, sig, v, y, DT, initial=initial)[0]
        assert abs(got - ref) <= 100 * cond * EPS * max(1.0, abs(ref))


def test_start_from_rest_differs_by_a_constant_that_does_not_grow_with_n():
    """Exact (P0 = 0) minus steady-state likelihood settles once the filter converges."""
    th, q, sig = _batch(1, seed=4)
    n_long = 1600
    v = _input(n_long)
    y = simulate_process_noise(MODEL, th, q, sig, v, DT, rng=5)[0]
    sysd = discretize_process_noise(MODEL, th, q, DT)
    diffs = []
    for n in (800, n_long):
        ss = kalman_loglik(MODEL, th, q, sig, v[:n], y[:n], DT)[0]
        diffs.append(_tv_filter(sysd, 0, sig[0], v[:n], y[:n], np.zeros((6, 6))) - ss)
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT)
    round_off = 4 * n_long * EPS * np.abs(pw).sum()
    assert abs(diffs[1] - diffs[0]) <= round_off
    # and the difference is a handful of nats against a total of order 1e4
    assert abs(diffs[1]) < 1e-3 * abs(pw.sum())


def test_zero_process_noise_is_the_white_output_error_likelihood_and_the_limit_is_smooth():
    th, _, sig = _batch(2, seed=6)
    n = 600
    v = _input(n)
    y = simulate_linear(MODEL, THETA, v, DT) + 2e-5 * np.random.default_rng(7).normal(size=(n, 3))
    ll0 = kalman_loglik(MODEL, th, np.zeros((2, 3)), sig, v, y, DT)
    yhat = simulate_linear(MODEL, th, v, DT)
    r = y[None] - yhat
    w = white_terms(r, sig)
    # the filter's open-loop prediction and the simulator are two implementations of the
    # ZOH recursion: their outputs may differ by the forward error of N steps,
    # delta <= N eps max|yhat|, which moves the log-likelihood by sum |r| delta / sigma^2
    delta = n * EPS * np.abs(yhat).max()
    tol = (4 * n * EPS * np.abs(w).sum(axis=(1, 2))
           + delta * np.sum(np.abs(r) / sig[:, None, :] ** 2, axis=(1, 2)))
    assert np.all(np.abs(ll0 - w.sum(axis=(1, 2))) <= tol)
    # for small q the change is linear in q: ten times less q, ten times less change
    d = [kalman_loglik(MODEL, th, np.full((2, 3), qq), sig, v, y, DT) - ll0
         for qq in (1e-13, 1e-14)]
    assert np.all(np.abs(d[1] / d[0] - 0.1) < 0.02)


def test_pointwise_sums_to_total_and_lanes_are_independent():
    th, q, sig = _batch(5, seed=8)
    n = 500
    v = _input(n)
    y = simulate_process_noise(MODEL, th[:1], q[:1], sig[:1], v, DT, rng=9)[0]
    tot = kalman_loglik(MODEL, th, q, sig, v, y, DT)
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT)
    bound = 4 * n * EPS * np.abs(pw).sum(axis=(1, 2))
    assert np.all(np.abs(pw.sum(axis=(1, 2)) - tot) <= bound)
    one = np.array([kalman_loglik(MODEL, th[b : b + 1], q[b : b + 1], sig[b : b + 1], v, y,
                                  DT)[0] for b in range(5)])
    assert np.all(np.abs(one - tot) <= bound)
    # a wild walker (a 10 mg cart: |A dt| ~ 1e3) in the batch leaves the others unchanged
    wild = th[:1].copy()
    wild[0, 1] = 1e-5
    mixed = kalman_loglik(MODEL, np.r_[th[:1], wild], q[:2], sig[:2], v, y, DT)
    assert abs(mixed[0] - one[0]) <= bound[0]
    # more lanes than one compiled kernel width (64): chunks give the same numbers
    rep = np.arange(70) % 5
    many = kalman_pointwise(MODEL, th[rep], q[rep], sig[rep], v, y, DT)
    assert np.array_equal(many, pw[rep])


@pytest.mark.parametrize("initial", ["steady", "rest"])
def test_input_offset_per_row_is_the_filter_of_the_shifted_input(initial):
    """``v0`` per row equals filtering ``v + v0`` row by row (and the test's own
    time-varying filter of the shifted input from rest); simulation shifts the same way.
    Negative control: without the offset the numbers differ by many tolerances."""
    th, q, sig = _batch(4, seed=21)
    n = 300
    v = _input(n)
    v0 = np.array([0.0, 0.02, -0.05, 0.3])
    y = simulate_process_noise(MODEL, th[:1], q[:1], sig[:1], v + 0.02, DT, rng=22)[0]
    got = kalman_loglik(MODEL, th, q, sig, v, y, DT, initial=initial, v0=v0)
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT, v0=v0)
    bound = 8 * n * EPS * np.abs(pw).sum(axis=(1, 2))
    sysd = discretize_process_noise(MODEL, th, q, DT)
    for b in range(4):
        one = kalman_loglik(MODEL, th[b : b + 1], q[b : b + 1], sig[b : b + 1], v + v0[b], y,
                            DT, initial=initial)[0]
        assert abs(got[b] - one) <= bound[b]
        pw1 = kalman_pointwise(MODEL, th[b : b + 1], q[b : b + 1], sig[b : b + 1], v + v0[b],
                               y, DT)[0]
        assert np.allclose(pw[b], pw1, rtol=0, atol=bound[b] / n)
        if initial == "rest":
            tv = _tv_filter(sysd, b, sig[b], v + v0[b], y, np.zeros((6, 6)))
            assert abs(got[b] - tv) <= bound[b]
    plain = kalman_loglik(MODEL, th, q, sig, v, y, DT, initial=initial)
    assert plain[0] == got[0]                          # v0 = 0 is no offset
    assert np.all(np.abs(plain[1:] - got[1:]) > 100 * bound[1:])
    # simulation: the same noise draws, the deterministic part shifted by the offset
    a = simulate_process_noise(MODEL, th[1:2], q[1:2], sig[1:2], v, DT, rng=5, v0=0.02)
    b = simulate_process_noise(MODEL, th[1:2], q[1:2], sig[1:2], v + 0.02, DT, rng=5)
    assert np.allclose(a, b, rtol=0, atol=1e3 * EPS * np.abs(b).max())
    with pytest.raises(DataError, match="one per row"):
        kalman_loglik(MODEL, th, q, sig, v, y, DT, v0=np.zeros(3))


def test_invalid_rows_get_minus_inf():
    th, q, sig = _batch(4, seed=10)
    th[1, 1] = -1.0
    q[2, 0] = -1e-6
    sig[3, 2] = 0.0
    v = _input(50)
    y = np.zeros((50, 3))
    ll = kalman_loglik(MODEL, th, q, sig, v, y, DT)
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT)
    assert np.isfinite(ll[0]) and np.all(ll[1:] == -np.inf) and np.all(pw[1:] == -np.inf)
    assert list(ProcessNoise().valid(np.c_[q, sig])) == [True, True, False, False]


def test_simulated_records_give_white_standard_normal_innovations():
    """Posterior-predictive consistency: at the true parameters u_k ~ iid N(0, 1)."""
    th, q, sig = _batch(1, seed=11)
    n = 4000
    v = _input(n)
    y = simulate_process_noise(MODEL, th, q, sig, v, DT, rng=12)[0]
    pw = kalman_pointwise(MODEL, th, q, sig, v, y, DT)[0]
    sysd = discretize_process_noise(MODEL, th, q, DT)
    L = np.linalg.cholesky(steady_state_filter(sysd, sig).S[0])
    u2 = -2 * (pw + 0.5 * np.log(2 * np.pi) + np.log(np.diag(L)))  # u_kj^2
    assert np.all(np.abs(u2.mean(axis=0) - 1) < 4 * np.sqrt(2 / n))
    u = np.sqrt(u2)  # |u|; E|u| = sqrt(2/pi), var 1 - 2/pi
    assert np.all(np.abs(u.mean(axis=0) - np.sqrt(2 / np.pi)) < 4 * np.sqrt((1 - 2 / np.pi) / n))


def test_bad_inputs():
    th, q, sig = _batch(2)
    with pytest.raises(DataError, match="one per cart"):
        kalman_loglik(MODEL, th, q[:, :2], sig, np.zeros(5), np.zeros((5, 3)), DT)
    with pytest.raises(DataError, match="to match v"):
        kalman_loglik(MODEL, th, q, sig, np.zeros(5), np.zeros((4, 3)), DT)
    with pytest.raises(ConfigError, match="initial must be one of"):
        kalman_loglik(MODEL, th, q, sig, np.zeros(5), np.zeros((5, 3)), DT, initial="zero")
    assert ProcessNoise().priors(3).names == ProcessNoise().names(3)


def test_known_q_is_recovered_within_its_standard_error():
    """Profile of log q (common scale of all three carts) on simulated data: the maximum is
    within 4 standard errors (from the curvature of the log-likelihood) of the truth, and
    the white output-error limit (q -> 0) is far below (negative control)."""
    th, q, sig = _batch(1, seed=14)
    n = 4000
    v = _input(n)
    y = simulate_process_noise(MODEL, th, q, sig, v, DT, rng=15)[0]
    log_c = np.linspace(-1.0, 1.0, 41)
    c = np.exp(log_c)[:, None]
    ll = kalman_loglik(MODEL, np.repeat(th, 41, 0), q * c, np.repeat(sig, 41, 0), v, y, DT)
    k = int(np.argmax(ll))
    assert 2 <= k <= 38, "maximum on the grid edge"
    a, b, _ = np.polyfit(log_c[k - 2 : k + 3], ll[k - 2 : k + 3], 2)
    peak, se = -b / (2 * a), 1 / np.sqrt(-2 * a)
    assert abs(peak) < 4 * se
    ll0 = kalman_loglik(MODEL, th, 0 * q, sig, v, y, DT)[0]
    assert ll.max() - ll0 > 100
