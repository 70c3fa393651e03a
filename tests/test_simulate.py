"""The exact ZOH simulator against closed forms, lsim, and linear-system identities."""

import numpy as np
import pytest
import scipy.signal as ss
from conftest import EPS, TABLE3, solve_tol, zoh_rtol

from bayesmodal import DataError, ModelError
from bayesmodal.model.simulate import discretize_zoh, simulate_linear, simulate_state_space
from bayesmodal.model.system import LinearModel, Rig


def _sdof(m, c, k, g):
    return LinearModel(Rig((k,)), "free"), np.array([g, m, c])


def test_sdof_step_response_closed_form():
    # m x'' + c x' + k x = g v, unit step: x = (g/k)(1 - e^{-zw t}(cos wd t + zw/wd sin wd t))
    m, c, k, g = 1.3, 0.9, 400.0, 5.0
    model, theta = _sdof(m, c, k, g)
    dt, N = 0.002, 3000
    t = np.arange(N) * dt
    y = simulate_linear(model, theta, np.ones(N), dt)[:, 0]
    wn = np.sqrt(k / m)
    z = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - z**2)
    exact = g / k * (1 - np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t)))
    # the simulator's own bound, and the closed form's: its phase wd t carries the rounding
    # of t, eps wd t, besides a few roundings of its terms (amplitude 2 g / k)
    A, _ = model.state_space(theta)
    ref_err = 4 * EPS * (1 + wn * t[-1]) * 2 * g / k
    np.testing.assert_allclose(y, exact, rtol=0,
                               atol=zoh_rtol(A, dt) * np.max(np.abs(exact)) + ref_err)


def test_sdof_free_response_closed_form():
    m, c, k = 0.8, 0.3, 250.0
    model, theta = _sdof(m, c, k, 1.0)
    dt, N = 0.005, 2000
    t = np.arange(N) * dt
    x0 = np.array([0.01, -0.2])
    y = simulate_linear(model, theta, np.zeros(N), dt, x0=x0)[:, 0]
    wn = np.sqrt(k / m)
    z = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - z**2)
    amplitude = abs(x0[0]) + abs(x0[1] + z * wn * x0[0]) / wd
    exact = np.exp(-z * wn * t) * (
        x0[0] * np.cos(wd * t) + (x0[1] + z * wn * x0[0]) / wd * np.sin(wd * t)
    )
    # as for the step response: the simulator's bound and the closed form's phase rounding
    A, _ = model.state_space(theta)
    ref_err = 4 * EPS * (1 + wn * t[-1]) * amplitude
    np.testing.assert_allclose(y, exact, rtol=0,
                               atol=zoh_rtol(A, dt) * np.max(np.abs(exact)) + ref_err)


def test_static_gain_equals_K_inverse_b(free_model):
    theta = TABLE3
    N, dt = 20000, 0.005
    y = simulate_linear(free_model, theta, 0.5 * np.ones(N), dt)
    M, C, K, b = free_model.matrices(theta)
    # the simulator's bound, the solve's, and what is left of the transient after N steps
    # (the slowest mode decays by rho^N; cond(V) bounds the transfer between coordinates)
    A, _ = free_model.state_space(theta)
    lam, V = np.linalg.eig(A)
    left = np.linalg.cond(V) * np.max(np.abs(np.exp(lam * dt))) ** N
    np.testing.assert_allclose(y[-1], np.linalg.solve(K, b) * 0.5,
                               rtol=zoh_rtol(A, dt) + solve_tol(K) + left)
    # report eq. 13: series connection of springs
    k1, k2, k3 = Rig().springs_n_m
    g = theta[0]
    eq13 = g * np.array([(k1 * k2 + k3 * k2 + k3 * k1) / (k1 * k2 * k3), (k2 + k3) / (k2 * k3),
                         1 / k3])
    # eq. 13 itself: about ten roundings
    np.testing.assert_allclose(np.linalg.solve(K, b), eq13, rtol=solve_tol(K) + 10 * EPS)


@pytest.mark.parametrize("damping", ["free", "proportional"])
def test_agrees_with_lsim(damping):
    rng = np.random.default_rng(1)
    model = LinearModel(Rig(), damping)
    if damping == "free":
        theta = TABLE3 * (1 + 0.1 * rng.random((5, 9)))
    else:
        theta = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 8e-5]) * (1 + 0.1 * rng.random((5, 6)))
    N, dt = 8000, 0.005
    u = rng.normal(size=N)
    y = simulate_linear(model, theta, u, dt)
    t = np.arange(N) * dt
    for i in range(theta.shape[0]):
        A, B = model.state_space(theta[i])
        sys = (A, B[:, None], np.eye(6)[:3], np.zeros((3, 1)))
        _, yl, _ = ss.lsim(sys, u, t, interp=False)
        err = np.max(np.abs(yl - y[i])) / np.max(np.abs(yl))
        assert err < 2 * zoh_rtol(A, dt)  # both within the bound of the exact ZOH answer


def test_batch_matches_single_and_chunks():
    rng = np.random.default_rng(2)
    model = LinearModel(Rig(), "free")
    theta = TABLE3 * (1 + 0.2 * rng.random((70, 9)))  # more than one 64-wide chunk
    u = rng.normal(size=500)
    yb = simulate_linear(model, theta, u, 0.01)
    assert yb.shape == (70, 500, 3)
    A, _ = model.state_space(theta)
    for i in (0, 31, 63, 64, 69):
        # a lane of a batch and a single run: each within its bound of the exact answer
        tol = 2 * zoh_rtol(A[i], 0.01) * np.max(np.abs(yb[i]))
        np.testing.assert_allclose(yb[i], simulate_linear(model, theta[i], u, 0.01), rtol=0,
                                   atol=tol)


def test_superposition_and_time_invariance():
    rng = np.random.default_rng(3)
    model = LinearModel(Rig(), "free")
    u1, u2 = rng.normal(size=(2, 1000))
    a, b = 1.7, -0.4
    y1 = simulate_linear(model, TABLE3, u1, 0.005)
    y2 = simulate_linear(model, TABLE3, u2, 0.005)
    y12 = simulate_linear(model, TABLE3, a * u1 + b * u2, 0.005)
    # the same discretisation in all runs: only the rounding of the recursions counts
    A, _ = model.state_space(TABLE3)
    rtol = zoh_rtol(A, 0.005, phase=False)
    scale = abs(a) * np.abs(y1).max() + abs(b) * np.abs(y2).max()
    np.testing.assert_allclose(y12, a * y1 + b * y2, rtol=0, atol=2 * rtol * scale)
    shift = 37
    us = np.r_[np.zeros(shift), u1[:-shift]]
    ys = simulate_linear(model, TABLE3, us, 0.005)
    np.testing.assert_allclose(ys[shift:], y1[:-shift], rtol=0,
                               atol=2 * rtol * np.abs(y1).max())
    assert np.all(ys[:shift] == 0)


def test_discretize_scalar_closed_form():
    d = discretize_zoh(np.array([[-2.0]]), np.array([3.0]), 0.1)
    # expm is backward stable: exp(x) moves by eps |x| relative, plus its own rounding and
    # that of the closed form; 1 - exp(-0.2) = 0.18 loses 1 / 0.18 of that relative
    x = 0.2
    rel = 4 * EPS * (1 + x)
    assert d.Ad[0, 0, 0] == pytest.approx(np.exp(-x), rel=rel)
    assert d.Bd[0, 0] == pytest.approx(3.0 * (1 - np.exp(-x)) / 2.0, rel=rel / (1 - np.exp(-x)))


def test_impossible_parameters_raise(free_model):
    bad = TABLE3.copy()
    bad[1] = -1.0
    with pytest.raises(ModelError, match="masses > 0"):
        simulate_linear(free_model, bad, np.ones(10), 0.01)
    with pytest.raises(ModelError, match="length 9"):
        simulate_linear(free_model, TABLE3[:5], np.ones(10), 0.01)
    with pytest.raises(DataError, match="dt"):
        simulate_state_space(np.zeros((1, 2, 2)), np.zeros((1, 2)), np.ones(5), 0.0, 1)


def test_ten_carts_and_one_cart_run():
    rig = Rig(tuple(np.linspace(300, 900, 10)))
    model = LinearModel(rig, "proportional")
    theta = np.r_[5.0, np.ones(10), 0.5, 1e-4]
    y = simulate_linear(model, theta, np.ones(3000), 0.005)
    M, C, K, b = model.matrices(theta)
    assert y.shape == (3000, 10)
    assert np.all(np.isfinite(y))
    one = LinearModel(Rig((500.0,)), "free")
    assert one.names == ("g_v", "m1", "c1")


def test_overdamped_lanes_use_exact_fallback():
    # Heavy damping makes some eigenvalues real: the modal kernel does not apply and the
    # full-state recursion must give the same exact ZOH answer as lsim.
    model = LinearModel(Rig(), "free")
    theta = np.array([[6.0, 1.5, 1.4, 1.1, 200.0, 150.0, 180.0, 0.0, 0.0], TABLE3])
    rng = np.random.default_rng(4)
    N, dt = 3000, 0.005
    u = rng.normal(size=N)
    y = simulate_linear(model, theta, u, dt)
    t = np.arange(N) * dt
    for i in range(2):
        A, B = model.state_space(theta[i])
        _, yl, _ = ss.lsim((A, B[:, None], np.eye(6)[:3], np.zeros((3, 1))), u, t, interp=False)
        assert np.max(np.abs(yl - y[i])) / np.max(np.abs(yl)) < 1e-9


def test_nonzero_initial_state_matches_lsim():
    model = LinearModel(Rig(), "free")
    x0 = np.array([0.01, -0.005, 0.002, 0.0, 0.1, -0.05])
    N, dt = 2000, 0.005
    u = np.sin(np.arange(N) * dt * 7.0)
    y = simulate_linear(model, TABLE3, u, dt, x0=x0)
    A, B = model.state_space(TABLE3)
    _, yl, _ = ss.lsim((A, B[:, None], np.eye(6)[:3], np.zeros((3, 1))), u, np.arange(N) * dt,
                       X0=x0, interp=False)
    assert np.max(np.abs(yl - y)) / np.max(np.abs(yl)) < 1e-9


def test_simulator_buffer_is_reused_and_results_stable():
    from bayesmodal.model.simulate import LinearSimulator

    model = LinearModel(Rig(), "free")
    u = np.random.default_rng(5).normal(size=400)
    sim = LinearSimulator(u, 0.005, 3)
    A, B = model.state_space(np.stack([TABLE3, TABLE3 * 1.1]))
    first = np.array(sim.run(A, B))
    again = sim.run(A, B)
    np.testing.assert_array_equal(first, again)
    with pytest.raises(DataError, match="non-finite"):
        LinearSimulator(np.array([0.0, np.nan]), 0.005, 3)


def test_bench_reports_speedup_against_lsim_in_same_run():
    # The speed target itself lives in `bayesmodal bench`; here only its contract.
    from bayesmodal.bench import bench_linear

    out = bench_linear(n_samples=2000, batch=16, quick=True)
    for key in ("n_samples", "batch", "us_per_eval", "lsim_us_per_eval", "speedup"):
        assert key in out
    assert out["speedup"] == pytest.approx(out["lsim_us_per_eval"] / out["us_per_eval"])
    assert out["max_rel_diff_vs_lsim"] < 1e-9


@pytest.mark.parametrize("n_carts", [1, 2, 3, 6])
def test_second_order_path_matches_general_path(n_carts):
    # run_second_order (compiled QEP modal form) against run (LAPACK eig / expm) on random
    # systems, with initial conditions, a mix of light and heavy damping in one batch.
    from bayesmodal.model.simulate import LinearSimulator

    rng = np.random.default_rng(10 + n_carts)
    rig = Rig(tuple(rng.uniform(200, 900, n_carts)))
    model = LinearModel(rig, "free")
    nb = 12
    theta = np.empty((nb, model.n_params))
    theta[:, 0] = rng.uniform(3, 8, nb)
    theta[:, 1 : 1 + n_carts] = rng.uniform(0.5, 2.5, (nb, n_carts))
    theta[:, 1 + n_carts :] = rng.uniform(0, 3, (nb, model.n_params - 1 - n_carts))
    theta[-2:, 1 + n_carts : 1 + 2 * n_carts] = 300.0  # overdamped lanes
    x0 = rng.normal(size=(nb, 2 * n_carts)) * 1e-3
    u = rng.normal(size=1500)
    M, C, K, b = model.matrices(theta)
    sim = LinearSimulator(u, 0.005, n_carts)
    y_fast = np.array(sim.run_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b, x0))
    A, B = model.state_space(theta)
    y_ref = np.array(LinearSimulator(u, 0.005, n_carts).run(A, B, x0))
    scale = np.abs(y_ref).max(axis=(1, 2), keepdims=True)
    assert np.max(np.abs(y_fast - y_ref) / scale) < 1e-9


def test_very_soft_coupling_spring_stays_exact():
    # Cart 1 hangs on a very soft spring: one mode near zero frequency, strongly damped.
    rig = Rig((1e-3, 500.0))
    model = LinearModel(rig, "free")
    theta = np.array([5.0, 1.0, 1.0, 0.5, 0.5, 0.0])
    N, dt = 2000, 0.005
    u = np.random.default_rng(6).normal(size=N)
    y = simulate_linear(model, theta, u, dt)
    A, B = model.state_space(theta)
    _, yl, _ = ss.lsim((A, B[:, None], np.eye(4)[:2], np.zeros((2, 1))), u, np.arange(N) * dt,
                       interp=False)
    assert np.max(np.abs(yl - y)) / np.max(np.abs(yl)) < 1e-9
