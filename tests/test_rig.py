"""Rig descriptions (issue 17): layouts, TOML, presets, unknown springs, free decays.

The reference simulator here is independent of the package: the equations of motion of
each layout are written out by hand (force on each cart from each spring and damper) and
integrated with ``scipy.integrate.solve_ivp`` over the intervals where the zero-order-hold
input is constant.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json

import numpy as np
import pytest
from conftest import EPS, ode_atol, zoh_rtol
from scipy import signal
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares
from scipy.stats import binom, norm

from bayesmodal._errors import ModelError
from bayesmodal.data import Experiment, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.inference import Likelihood
from bayesmodal.metrics import fit_percent
from bayesmodal.model.rigs import (
    PRESETS,
    load_rig,
    rig_from_dict,
    rig_from_toml,
    rig_to_toml,
    save_rig,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import (
    Cart,
    Damper,
    Drive,
    LinearModel,
    Rig,
    Sensor,
    Spring,
    chain_matrix,
)

DT = 0.005
N = 2000
SIGMA_M = 1e-5  # white measurement noise of the synthetic records, m
Z90 = norm.ppf(0.95)  # half-width of a 90 % interval in standard errors


# ------------------------------------------------------------- hand-written dynamics
# Each function returns the accelerations of the moving carts for positions x, velocities
# xd and input v, written from the free-body diagram of the layout.
def eom_1cart(p, k):
    def f(x, xd, v):
        return [(-k[0] * x[0] - p["c1"] * xd[0] + p["g_v"] * v) / p["m1"]]
    return f


def eom_2cart_chain(p, k):  # cart 1 (motor) - k1 - cart 2 - k2 - frame
    def f(x, xd, v):
        f12 = k[0] * (x[1] - x[0]) + p["c12"] * (xd[1] - xd[0])  # on cart 1, from cart 2
        a1 = (f12 - p["c1"] * xd[0] + p["g_v"] * v) / p["m1"]
        a2 = (-f12 - k[1] * x[1] - p["c2"] * xd[1]) / p["m2"]
        return [a1, a2]
    return f


def eom_2cart_frame_at_drive(p, k):  # frame - k1 - cart 1 (motor) - k2 - cart 2
    def f(x, xd, v):
        f12 = k[1] * (x[1] - x[0]) + p["c12"] * (xd[1] - xd[0])
        a1 = (-k[0] * x[0] + f12 - p["c1"] * xd[0] + p["g_v"] * v) / p["m1"]
        a2 = (-f12 - p["c2"] * xd[1]) / p["m2"]
        return [a1, a2]
    return f


def eom_3cart_chain(p, k):
    def f(x, xd, v):
        f12 = k[0] * (x[1] - x[0]) + p["c12"] * (xd[1] - xd[0])
        f23 = k[1] * (x[2] - x[1]) + p["c23"] * (xd[2] - xd[1])
        a1 = (f12 - p["c1"] * xd[0] + p["g_v"] * v) / p["m1"]
        a2 = (-f12 + f23 - p["c2"] * xd[1]) / p["m2"]
        a3 = (-f23 - k[2] * x[2] - p["c3"] * xd[2]) / p["m3"]
        return [a1, a2, a3]
    return f


def eom_3cart_clamp3(p, k):  # the ECP chain with cart 3 held: k2 now grounds cart 2
    def f(x, xd, v):
        f12 = k[0] * (x[1] - x[0]) + p["c12"] * (xd[1] - xd[0])
        a1 = (f12 - p["c1"] * xd[0] + p["g_v"] * v) / p["m1"]
        a2 = (-f12 - k[1] * x[1] - p["c2"] * xd[1]) / p["m2"]
        return [a1, a2]
    return f


#: Tolerances of the reference integrator (DOP853).
REF_RTOL, REF_ATOL = 1e-11, 1e-14


def reference_simulation(accel, n_dof, v, dt, x0=None, *, steps=None):
    """Positions, shape (N, n_dof): solve_ivp over each interval of constant input.

    ``steps``, a list, receives the number of integrator steps of each interval (DOP853
    spends 12 evaluations per step)."""
    state = np.zeros(2 * n_dof) if x0 is None else np.asarray(x0, float)
    y = np.empty((v.size, n_dof))
    y[0] = state[:n_dof]
    change = np.flatnonzero(np.diff(v)) + 1
    edges = np.r_[0, change, v.size]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        level = v[a]

        def rhs(_t, s, level=level):
            return np.r_[s[n_dof:], accel(s[:n_dof], s[n_dof:], level)]

        # sample k is the state at t_k; the input v[k] holds over [t_k, t_{k+1})
        t_eval = dt * np.arange(a, min(b, v.size - 1) + 1)
        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), state, method="DOP853", t_eval=t_eval,
                        rtol=REF_RTOL, atol=REF_ATOL)
        if steps is not None:
            steps.append(-(-sol.nfev // 12))
        y[a + 1 : a + len(t_eval)] = sol.y[:n_dof, 1:].T
        state = sol.y[:, -1]
    return y


def excitation(rng, n=N):
    """Impulses of 3 V every 2 s plus a random level held for 0.5 s: few switches."""
    t = np.arange(n) * DT
    levels = rng.uniform(-1.0, 1.0, size=int(n * DT / 0.5) + 1)
    v = levels[(t / 0.5).astype(int)]
    return np.where((t % 2.0) < 0.05, 3.0, v)


# name, rig, eom, truth (only the parameters of that layout)
CASES = {
    "ecp210-1cart": (eom_1cart, {"g_v": 6.2, "m1": 1.5, "c1": 2.9}),
    "ecp210-2cart": (eom_2cart_chain,
                     {"g_v": 6.2, "m1": 1.5, "m2": 1.45, "c1": 2.9, "c2": 1.8, "c12": 0.4}),
    "ecp210-2cart-frame-at-drive": (eom_2cart_frame_at_drive,
                                    {"g_v": 6.2, "m1": 1.5, "m2": 1.1, "c1": 2.0, "c2": 1.0,
                                     "c12": 0.5}),
    "ecp210-3cart": (eom_3cart_chain,
                     {"g_v": 6.2, "m1": 1.565, "m2": 1.461, "m3": 1.146, "c1": 2.9,
                      "c2": 1.8, "c3": 2.0, "c12": 0.3, "c23": 0.2}),
}


def clamped_rig():
    base = Rig()
    return Rig(carts=base.carts, springs=base.springs, drive=base.drive, clamped=("3",))


def _record(rig, accel, truth, rng, *, x0=None, v=None):
    model = LinearModel(rig, "free")
    v = excitation(rng) if v is None else v
    y = reference_simulation(accel, model.n_carts, v, DT, x0)
    y = y + SIGMA_M * rng.standard_normal(y.shape)
    return model, Experiment(np.arange(N) * DT, v, y, name="synthetic")


# ------------------------------------------------------------------ default unchanged
def test_default_rig_is_the_report_chain_bitwise():
    """Rig() builds the report's eq. 3 matrices exactly (same operations, same bits)."""
    assert Rig() == load_rig("ecp210-3cart") == Rig(springs_n_m=(774.0, 770.0, 396.0))
    model = LinearModel(Rig(), "free")
    assert model.names == ("g_v", "m1", "m2", "m3", "c1", "c2", "c3", "c12", "c23")
    assert LinearModel(Rig(), "proportional").names == ("g_v", "m1", "m2", "m3", "ca", "cb")
    g, m1, m2, m3, c1, c2, c3, c12, c23 = th = np.array(
        [6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])
    M, C, K, b = model.matrices(th)
    # exact by construction: the stiffnesses are integers in N/m, and each damping entry
    # is the same sum of the same floats as the model's assembly (IEEE addition is
    # correctly rounded on every platform)
    np.testing.assert_array_equal(M, np.diag([m1, m2, m3]))
    np.testing.assert_array_equal(K, [[774.0, -774.0, 0], [-774.0, 774.0 + 770.0, -770.0],
                                      [0, -770.0, 770.0 + 396.0]])
    np.testing.assert_array_equal(C, [[c12 + c1, -c12, 0], [-c12, c12 + c23 + c2, -c23],
                                      [0, -c23, c23 + c3]])
    np.testing.assert_array_equal(b, [g, 0, 0])


def test_general_path_agrees_with_the_chain_path():
    """The same chain through the general assembly (sensors reversed makes it non-chain)."""
    chain = Rig()
    rev = Rig(carts=chain.carts, springs=chain.springs, drive=chain.drive,
              sensors=tuple(reversed(chain.sensors)))
    assert chain.is_chain and not rev.is_chain
    rng = np.random.default_rng(3)
    for damping in ("free", "proportional"):
        a, b_ = LinearModel(chain, damping), LinearModel(rev, damping)
        assert a.names == b_.names
        th = rng.uniform(0.5, 2.0, (4, a.n_params))
        th[:, -1] *= 1e-4
        for x, y in zip(a.matrices(th), b_.matrices(th), strict=True):
            # only the order of the additions differs: a few ulps of the largest entry
            np.testing.assert_allclose(x, y, rtol=0, atol=8 * np.finfo(float).eps
                                       * np.abs(x).max())
        v = excitation(rng, 400)
        ya = simulate_linear(a, th[0], v, DT)
        yb = simulate_linear(b_, th[0], v, DT)
        # matrices a few ulps apart: each simulation within its bound of the exact answer
        A, _ = a.state_space(th[0])
        np.testing.assert_allclose(yb, ya[:, ::-1], rtol=0,
                                   atol=2 * zoh_rtol(A, DT) * np.abs(ya).max())


# ----------------------------------------------------------- reference simulator
@pytest.mark.parametrize("name", [*CASES, "clamped"])
def test_simulation_matches_hand_written_equations(name):
    rng = np.random.default_rng(11)
    if name == "clamped":
        rig, (accel, truth) = clamped_rig(), (eom_3cart_clamp3, CASES["ecp210-2cart"][1])
    else:
        rig, (accel, truth) = load_rig(name), CASES[name]
    model = LinearModel(rig, "free")
    th = model.as_vector(truth)
    v = excitation(rng, 600)
    x0 = rng.normal(0, 0.005, 2 * model.n_carts)
    steps = []
    ref = reference_simulation(accel(truth, rig.springs_n_m), model.n_carts, v, DT, x0,
                               steps=steps)
    y = simulate_linear(model, th, v, DT, x0)
    # the reference's global error (its local tolerance summed over its steps) and the ZOH
    # simulator's own bound
    A, _ = model.state_space(th)
    scale = np.abs(ref).max()
    tol = ode_atol(sum(steps), REF_RTOL, REF_ATOL, scale, np.linalg.cond(np.linalg.eig(A)[1]))
    np.testing.assert_allclose(y, ref, rtol=0, atol=tol + zoh_rtol(A, DT) * scale)


# ----------------------------------------------------------------- recovery
def _interval_checks(res, truth_vec):
    z = (res.theta - truth_vec) / res.stderr
    return np.abs(z)


def test_presets_and_clamped_recover_truth_within_intervals():
    """LSQ on reference-simulated records: the truth inside the 90 % intervals.

    Over all parameters of all layouts the number of misses is binomial(n, 0.1): the test
    asks it to stay below the 99.9 % quantile, and every truth within 4.5 standard errors.
    """
    rng = np.random.default_rng(2026)
    z_all = []
    cases = [(load_rig(n), *CASES[n]) for n in CASES]
    cases.append((clamped_rig(), eom_3cart_clamp3, CASES["ecp210-2cart"][1]))
    for rig, eom, truth in cases:
        model, e = _record(rig, eom(truth, rig.springs_n_m), truth, rng)
        # started 10 % off the truth (a shorter path to the same minimum)
        res = fit_lsq(e, model, theta0=1.1 * model.as_vector(truth))
        z_all.append(_interval_checks(res, model.as_vector(truth)))
    z = np.concatenate(z_all)
    assert np.all(z < 4.5), z
    assert np.sum(z > Z90) <= binom.ppf(0.999, z.size, 0.1), z


#: Seeds (noise draws) of the unknown-spring coverage check, and its false-alarm rate.
N_SEEDS, ALPHA = 40, 1e-3


@pytest.mark.slow
def test_unknown_spring_estimated_with_masses():
    """frame - k1 (known) - cart 1 (motor) - k2 (unknown) - cart 2 (known mass).

    Coverage of the 90 % least-squares intervals over ``N_SEEDS`` noise draws on one
    reference-simulated record: for each parameter the number of intervals that miss the
    truth is binomial(N_SEEDS, 0.1) and must stay below its 1 - ALPHA / P quantile
    (Bonferroni over the P parameters); the standard errors are calibrated too (the sum
    of squared z-scores of each parameter is chi-square with N_SEEDS degrees of freedom,
    two-sided).  Negative control: intervals of half the width (nominal coverage 59 %)
    fail the same check.
    """
    from scipy.stats import chi2

    rig = Rig(carts=(Cart("1"), Cart("2", "known", 1.1)),
              springs=(Spring("1", "frame", 770.0), Spring("1", "2", 350.0, known=False,
                                                          prior_sd_n_m=60.0)),
              drive=(Drive("1"),))
    model = LinearModel(rig, "free")
    assert model.names == ("g_v", "m1", "c1", "c2", "c12", "k2")
    truth = {"g_v": 6.2, "m1": 1.5, "m2": 1.1, "c1": 2.0, "c2": 1.0, "c12": 0.5}
    k = (770.0, 396.0)
    want = np.array([6.2, 1.5, 2.0, 1.0, 0.5, 396.0])
    rng = np.random.default_rng(5)
    v = excitation(rng)
    y0 = reference_simulation(eom_2cart_frame_at_drive(truth, k), 2, v, DT)
    t = np.arange(N) * DT
    z = []
    for seed in range(N_SEEDS):
        noise = SIGMA_M * np.random.default_rng([5, seed]).standard_normal(y0.shape)
        e = Experiment(t, v, y0 + noise, name=f"seed{seed}")
        res = fit_lsq(e, model)
        z.append((res.theta - want) / res.stderr)
    z = np.abs(np.array(z))                                   # (N_SEEDS, P)
    n_par = z.shape[1]
    top = binom.ppf(1 - ALPHA / n_par, N_SEEDS, 0.1)
    misses = np.sum(z > Z90, axis=0)
    assert np.all(misses <= top), (misses, top)
    ss = np.sum(z**2, axis=0)
    lo, hi = chi2.ppf([ALPHA / (2 * n_par), 1 - ALPHA / (2 * n_par)], N_SEEDS)
    assert np.all((lo <= ss) & (ss <= hi)), (ss, lo, hi)
    # negative control: half-width intervals miss far more often than the bound allows
    assert np.any(np.sum(z > Z90 / 2, axis=0) > top)
    # and the spring held at its (wrong) nominal value misfits the record
    fixed = LinearModel(Rig(carts=rig.carts, springs=(rig.springs[0],
                                                       Spring("1", "2", 350.0)),
                            drive=rig.drive), "free")
    assert fit_lsq(e, fixed).cost > 10 * res.cost


def test_free_decay_with_estimated_initial_state():
    """No input, an initial displacement: parameters and initial state recovered."""
    rig = Rig(carts=(Cart("1"), Cart("2")),
              springs=(Spring("1", "frame", 770.0), Spring("1", "2", 396.0, known=False)),
              drive=(Drive("1"),), gain_n_v=6.2)
    model = LinearModel(rig, "free")
    truth = {"g_v": 6.2, "m1": 1.5, "m2": 1.1, "c1": 2.0, "c2": 1.0, "c12": 0.5}
    x0 = np.array([0.01, -0.004, 0.0, 0.02])
    rng = np.random.default_rng(8)
    _, e = _record(rig, eom_2cart_frame_at_drive(truth, (770.0, 396.0)), truth, rng, x0=x0,
                   v=np.zeros(N))
    res = fit_lsq(e, model, initial_state="estimate")
    want = model.as_vector({**{k: v for k, v in truth.items() if k != "g_v"}, "k2": 396.0})
    z = np.abs(res.theta - want) / res.stderr
    assert np.all(z < 4.5), z
    # the initial state: within the noise-level (1e-5 m) scale of the first samples
    assert np.allclose(res.x0[0, :2], x0[:2], atol=5 * SIGMA_M)
    # from rest the same record cannot be fitted at all
    with pytest.raises(ValueError, match="input is all zeros"):
        fit_lsq(e, model)
    # the likelihood used by sampling: the true initial state beats rest by far
    lik = Likelihood(model, [e], noise="white", initial_state="estimate")
    assert lik.names[model.n_params : model.n_params + 4] == ("x1_0", "x2_0", "v1_0", "v2_0")
    best = np.r_[want, x0, SIGMA_M, SIGMA_M]
    rest = np.r_[want, np.zeros(4), SIGMA_M, SIGMA_M]
    ll = lik(np.array([best, rest]))
    r = e.y_m - simulate_linear(model, want, e.v_volt, DT, x0)
    expected = np.sum(norm.logpdf(r, scale=SIGMA_M))
    # the same simulator inside the likelihood (its bound on the residuals, propagated
    # through sum r dr / sigma^2) and the rounding of a sum of r.size terms
    A, _ = model.state_space(want)
    dr = zoh_rtol(A, DT) * np.abs(e.y_m - r).max()
    terms = norm.logpdf(r, scale=SIGMA_M)
    tol = np.sum(np.abs(r)) * dr / SIGMA_M**2 + r.size * EPS * np.sum(np.abs(terms))
    assert ll[0] == pytest.approx(expected, abs=tol)
    assert ll[1] < ll[0] - 1e3


def test_free_decays_need_something_absolute():
    rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", 500.0),), drive=(Drive("1"),))
    model = LinearModel(rig, "free")
    t = np.arange(200) * DT
    e = Experiment(t, np.zeros(200), np.cos(20 * t)[:, None] * 1e-2)
    with pytest.raises(ModelError, match="gain_n_v"):
        fit_lsq(e, model, initial_state="estimate")


# -------------------------------------------------- the 'done when' two-cart record
#: ftol of the reference fit, and of fit_lsq (bayesmodal/fit/linear.py).
REF_FTOL, LSQ_FTOL = 1e-14, 1e-12


def _hand_written_fit(e, k1, k2, start, *, fit=True):
    """Reference LSQ: hand-written state space, scipy.signal.lsim (ZOH), least_squares.

    With ``fit=False``, only the hand-written simulation at ``start``."""
    def simulate(p):
        g, m1, m2, c1, c2, c12 = p
        A = np.array([[0, 0, 1, 0], [0, 0, 0, 1],
                      [-(k1 + k2) / m1, k2 / m1, -(c1 + c12) / m1, c12 / m1],
                      [k2 / m2, -k2 / m2, c12 / m2, -(c2 + c12) / m2]])
        B = np.array([[0], [0], [g / m1], [0]])
        sys = signal.StateSpace(A, B, np.eye(4)[:2], np.zeros((2, 1)))
        _, y, _ = signal.lsim(sys, e.v_volt, e.t_s, interp=False)
        return y

    if not fit:
        return simulate(np.asarray(start, float))

    def res(z):
        return (e.y_m - simulate(np.exp(z))).ravel()

    sol = least_squares(res, np.log(start), xtol=1e-14, ftol=REF_FTOL, gtol=1e-12)
    p = np.exp(sol.x)
    return p, simulate(p)


def _omega(M, K):
    return np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))


@pytest.mark.slow
def test_two_cart_frame_at_drive_matches_hand_written_fit():
    """The 'done when' record: fitted with the right layout, next to a reference fit.

    The two fits' fit percent and frequencies are printed side by side (``pytest -rP``).
    """
    name = "ecp210-2cart-frame-at-drive"
    rig = load_rig(name)
    eom, truth = CASES[name]
    rng = np.random.default_rng(17)
    model, e = _record(rig, eom(truth, rig.springs_n_m), truth, rng)
    start = 1.1 * model.as_vector(truth)  # both fits from the same start, 10 % off
    res = fit_lsq(e, model, theta0=start)
    p_ref, y_ref = _hand_written_fit(e, *rig.springs_n_m, start)
    M, _, K, _ = model.matrices(res.theta)
    omega = _omega(M, K)
    omega_ref = _omega(np.diag(p_ref[1:3]), np.array(
        [[rig.springs_n_m[0] + rig.springs_n_m[1], -rig.springs_n_m[1]],
         [-rig.springs_n_m[1], rig.springs_n_m[1]]]))
    fp_ref = fit_percent(e.y_m, y_ref)
    print(f"fit percent   bayesmodal {np.round(res.fit_percent[0], 4)}   hand-written "
          f"{np.round(fp_ref, 4)}")
    print(f"omega (rad/s) bayesmodal {np.round(omega, 5)}   hand-written "
          f"{np.round(omega_ref, 5)}")
    # Not two optimiser paths but one cost function: the two simulations agree at fixed
    # parameter sets (the start, the truth and both estimates) within the ZOH bound ...
    k1, k2 = rig.springs_n_m
    A0, _ = model.state_space(model.as_vector(truth))
    sim_tol = 2 * zoh_rtol(A0, DT) * np.abs(e.y_m).max()
    for p in (start, model.as_vector(truth), res.theta, p_ref):
        hand = _hand_written_fit(e, k1, k2, p, fit=False)
        np.testing.assert_allclose(simulate_linear(model, p, e.v_volt, DT), hand, rtol=0,
                                   atol=sim_tol)
    # ... and each optimiser stopped within its ftol of the minimum: a cost gap ftol * F is
    # a distance sqrt(ftol (n - p)) standard errors (F = 0.5 sum r^2, s^2 = 2 F / (n - p));
    # the simulation error moves the minimum by about sim_tol sqrt(n) / s of them.
    n_res = e.y_m.size
    s = np.sqrt(np.sum((e.y_m - y_ref) ** 2) / (n_res - model.n_params))
    dist = (np.sqrt(LSQ_FTOL * n_res) + np.sqrt(REF_FTOL * n_res)
            + sim_tol * np.sqrt(n_res) / s)
    delta = res.theta - p_ref
    assert np.sqrt(delta @ np.linalg.solve(res.cov, delta)) < dist
    # frequency standard errors by the delta method from the LSQ covariance
    h_rel = 1e-6
    h = h_rel * res.theta
    grads = []
    for i in range(model.n_params):
        th = res.theta.copy()
        th[i] += h[i]
        Mi, _, Ki, _ = model.matrices(th)
        grads.append((_omega(Mi, Ki) - omega) / h[i])
    G = np.array(grads).T
    se_omega = np.sqrt(np.einsum("ij,jk,ik->i", G, res.cov, G))
    # |g^T delta| <= sqrt(g^T cov g) sqrt(delta^T cov^-1 delta) (Cauchy-Schwarz), plus the
    # finite-difference error of G (second order, h relative)
    # relative error h_rel of the forward-difference gradient G
    assert np.all(np.abs(omega - omega_ref) < se_omega * dist * (1 + h_rel))
    # fit percent 100 (1 - ||y - yh|| / ||y - mean||) of each output moves by at most
    # 100 ||yh_a - yh_b|| / ||y - mean||, and ||J delta|| = s sqrt(delta^T cov^-1 delta)
    spread = np.linalg.norm(e.y_m - e.y_m.mean(axis=0), axis=0)
    moved = s * dist + sim_tol * np.sqrt(n_res)
    assert np.all(np.abs(res.fit_percent[0] - fp_ref) <= 100 * moved / spread)
    # negative control: the same record read with the chain layout of the default presets
    wrong = fit_lsq(e, LinearModel(load_rig("ecp210-2cart"), "free"))
    assert np.all(wrong.fit_percent[0] < res.fit_percent[0] - 1.0)


# ------------------------------------------------------------------ TOML
def _rich_rig():
    return Rig(
        carts=(Cart("left", "nominal", 1.4), Cart("mid"), Cart("right", "known", 1.2),
               Cart("held")),
        springs=(Spring("left", "frame", 770.0), Spring("left", "mid", 400.0, known=False,
                                                        prior_sd_n_m=50.0, name="k_mid"),
                 Spring("mid", "right", 396.0), Spring("right", "held", 300.0)),
        dampers=(Damper("left"), Damper("mid", "frame"), Damper("left", "mid")),
        drive=(Drive("left", 1.0), Drive("mid", -0.5)),
        sensors=(Sensor("mid", "mm"), Sensor("left", "count", 2e-5)),
        clamped=("held",), gain_n_v=6.0, name="rich")


@pytest.mark.parametrize("name", [*PRESETS, "rich"])
def test_toml_round_trip(name, tmp_path):
    rig = _rich_rig() if name == "rich" else load_rig(name)
    assert rig_from_toml(rig_to_toml(rig)) == rig
    save_rig(rig, tmp_path / "r.toml")
    assert load_rig(tmp_path / "r.toml") == rig
    model = LinearModel(rig)
    assert LinearModel(load_rig(tmp_path / "r.toml")).names == model.names


def test_rich_rig_layout():
    model = LinearModel(_rich_rig(), "free")
    # gain known, mass 3 known, cart 4 clamped; ground dampers first, then the pair
    assert model.names == ("m1", "m2", "c1", "c2", "c12", "k_mid")
    assert model.n_carts == 3 and model.n_outputs == 2
    th = model.as_vector({"m1": 1.4, "m2": 1.0, "c1": 1.0, "c2": 2.0, "c12": 0.5,
                          "k_mid": 410.0})
    M, C, K, b = model.matrices(th)
    # exact by construction: integer stiffnesses, dampers and gains that are sums of
    # binary fractions (0.5, 1.0, 2.0), masses passed through
    np.testing.assert_array_equal(np.diag(M), [1.4, 1.0, 1.2])
    np.testing.assert_array_equal(K, [[770.0 + 410.0, -410.0, 0], [-410.0, 410.0 + 396.0,
                                                                   -396.0],
                                      [0, -396.0, 396.0 + 300.0]])
    np.testing.assert_array_equal(C, [[1.5, -0.5, 0], [-0.5, 2.5, 0], [0, 0, 0]])
    np.testing.assert_array_equal(b, [6.0, -3.0, 0])
    np.testing.assert_array_equal(_rich_rig().output_matrix(), [[0, 1, 0], [1, 0, 0]])


# ------------------------------------------------------------------ bad descriptions
CART2 = [{"name": "1"}, {"name": "2"}]
BAD = {
    "no path to the frame": (
        {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0}]},
        "no spring path to the frame"),
    "spring to an unknown cart": (
        {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0},
                                     {"between": ["2", "7"], "stiffness_n_m": 500.0}]},
        "unknown cart '7'"),
    "duplicate spring": (
        {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0},
                                     {"between": ["1", "2"], "stiffness_n_m": 500.0},
                                     {"between": ["2", "1"], "stiffness_n_m": 300.0}]},
        "duplicate spring"),
    "duplicate cart": (
        {"carts": [{"name": "1"}, {"name": "1"}],
         "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0}]},
        "duplicate cart"),
    "unsupported unit": (
        {"carts": CART2[:1], "springs": [{"between": ["1", "frame"], "stiffness_n_m": 5e2}],
         "sensors": [{"cart": "1", "unit": "inch"}]},
        "unit 'inch' is not supported"),
    "unknown key": (
        {"carts": CART2[:1], "springs": [{"between": ["1", "frame"], "stiffness": 5e2}]},
        "unknown key 'stiffness'"),
    "negative stiffness": (
        {"carts": CART2[:1], "springs": [{"between": ["1", "frame"], "stiffness_n_m": -5.0}]},
        "stiffness_n_m"),
    "spring named like a mass": (
        {"carts": CART2[:1], "springs": [{"between": ["1", "frame"], "stiffness_n_m": 5e2,
                                          "name": "m1", "known": False}]},
        "clashes with a parameter name"),
    "duplicate damper": (
        {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0},
                                     {"between": ["1", "2"], "stiffness_n_m": 500.0}],
         "dampers": {"ground": ["1"], "pairs": [["1", "2"], ["2", "1"]]}},
        "duplicate damper"),
    "sensor on a clamped cart": (
        {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0},
                                     {"between": ["1", "2"], "stiffness_n_m": 500.0}],
         "clamped": ["2"], "sensors": [{"cart": "2"}]},
        "clamped cart '2'"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_descriptions_give_one_line_errors(case):
    d, match = BAD[case]
    with pytest.raises(ModelError, match=match) as info:
        rig_from_dict(d, where="my_rig.toml")
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith("my_rig.toml: ")


def test_good_description_is_accepted():  # control for the table above
    d = {"carts": CART2, "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0},
                                     {"between": ["1", "2"], "stiffness_n_m": 500.0}]}
    assert rig_from_dict(d).n_carts == 2


def test_inseparable_scale_names_what_to_add():
    # free decays only (no drive) and nothing known: no scale at all, refused with the fix
    rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", 500.0, known=False),),
              drive=())
    with pytest.raises(ModelError) as info:
        LinearModel(rig)
    msg = str(info.value)
    assert "known mass" in msg and "known spring" in msg and "static-gain" in msg
    # each of the three fixes makes the model absolute
    driven = dataclasses.replace(rig, drive=(Drive("1"),))
    for fixed in (Rig(carts=(Cart("1", "known", 1.0),), springs=rig.springs, drive=rig.drive),
                  Rig(carts=rig.carts, springs=(Spring("1", "frame", 500.0),),
                      drive=driven.drive),
                  dataclasses.replace(driven, gain_n_v=6.0)):
        assert LinearModel(fixed).scale == "absolute"
    # with a drive and nothing known: per unit of drive gain (tests/test_rig_scale_ties.py)
    assert LinearModel(driven).scale == "per_unit_gain"


# ---------------------------------------------------------- extensions on other layouts
def test_extensions_take_other_layouts():
    from bayesmodal.model.effects import EXTENSIONS

    other = load_rig("ecp210-2cart-frame-at-drive")
    t = np.arange(50) * DT
    e = Experiment(t, np.ones(50), np.zeros((50, 2)) + t[:, None])
    for name, ext in EXTENSIONS.items():
        assert ext.unsupported(other) is None, name
        lik = Likelihood(LinearModel(other, "free"), [e], extension=name)
        assert lik.extension is ext
    assert EXTENSIONS["coulomb_friction"].extension_names(other) == ("Fc1", "Fc2", "Fs1",
                                                                     "Fs2")
    assert EXTENSIONS["cubic_stiffness"].extension_names(other) == ("k3_1", "k3_2")


# ------------------------------------------------------------------ CLI and config
def test_cli_lsq_with_rig_file(tmp_path):
    from bayesmodal.cli import main

    name = "ecp210-2cart-frame-at-drive"
    rig = load_rig(name)
    eom, truth = CASES[name]
    _, e = _record(rig, eom(truth, rig.springs_n_m), truth, np.random.default_rng(4))
    save_csv(e, tmp_path / "two.csv")
    save_rig(rig, tmp_path / "rig.toml")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["lsq", str(tmp_path / "two.csv"), "--rig", str(tmp_path / "rig.toml"),
                     "--json"]) == 0
    out = json.loads(buf.getvalue())
    res = fit_lsq(e, LinearModel(rig))
    assert out["parameters"] == pytest.approx(res.params, rel=1e-12)
    # without --rig the record does not match the default three-cart rig
    assert main(["lsq", str(tmp_path / "two.csv")]) != 0
    assert main(["lsq", str(tmp_path / "two.csv"), "--rig", str(tmp_path / "none.toml")]) != 0


def test_config_rig_table(tmp_path):
    from bayesmodal.runs.config import parse_config

    base = {"data": {"files": ["x.csv"]}}
    save_rig(load_rig("ecp210-1cart"), tmp_path / "one.toml")
    by_file = parse_config({**base, "rig": {"file": "one.toml"}}, base=tmp_path,
                           check_files=False)
    by_preset = parse_config({**base, "rig": {"file": "ecp210-1cart"}}, base=tmp_path,
                             check_files=False)
    assert by_file.make_rig() == by_preset.make_rig() == load_rig("ecp210-1cart")
    inline = {"carts": [{"name": "1"}],
              "springs": [{"between": ["1", "frame"], "stiffness_n_m": 396.0}],
              "drive": {"carts": ["1"]}}
    cfg = parse_config({**base, "rig": inline}, base=tmp_path, check_files=False)
    assert cfg.make_rig().springs_n_m == (396.0,)
    chain = parse_config({**base, "rig": {"springs_n_m": [774.0, 770.0, 396.0]}},
                         check_files=False)
    assert chain.model.rig is None and chain.make_rig() == Rig()
    with pytest.raises(ValueError, match="give one of springs_n_m, file"):
        parse_config({**base, "rig": {"springs_n_m": [500.0], "file": "one.toml"}},
                     base=tmp_path, check_files=False)
    with pytest.raises(ValueError, match="no spring path"):
        parse_config({**base, "rig": {**inline, "carts": [{"name": "1"}, {"name": "2"}]}},
                     base=tmp_path, check_files=False)


def test_chain_matrix_unchanged_helper():
    # chain_matrix stays importable for callers (assembles a chain of dampers/springs)
    np.testing.assert_array_equal(chain_matrix(np.array([1.0, 2.0]), grounded_last=True),
                                  [[1.0, -1.0], [-1.0, 3.0]])


@pytest.mark.slow
def test_free_decay_is_sampled_with_its_initial_state():
    """emcee on a one-cart free decay: mass, damper and initial state near the truth."""
    from bayesmodal.inference import sample_posterior

    rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", 396.0),),
              drive=(Drive("1"),), gain_n_v=6.2)
    truth = {"g_v": 6.2, "m1": 1.5, "c1": 2.0}
    x0 = np.array([0.01, 0.0])
    rng = np.random.default_rng(21)
    model, e = _record(rig, eom_1cart(truth, (396.0,)), truth, rng, x0=x0, v=np.zeros(N))
    run = sample_posterior(e, model, noise="white", n_walkers=16, n_steps=1500, rng=3,
                           initial_state="estimate", warn=False)
    assert run.names[:4] == ("m1", "c1", "x1_0", "v1_0")
    draws = run.flat_draws
    want = np.r_[1.5, 2.0, x0]
    z = np.abs(np.median(draws[:, :4], axis=0) - want) / draws[:, :4].std(axis=0)
    assert np.all(z < 4), z


def test_replace_keeps_a_description_valid():
    import dataclasses

    rig = load_rig("ecp210-2cart-frame-at-drive")
    known = dataclasses.replace(rig, gain_n_v=6.2)
    assert "g_v" not in LinearModel(known).names and known.springs == rig.springs
    with pytest.raises(ModelError, match="springs_n_m=None"):
        dataclasses.replace(rig, springs=(Spring("1", "frame", 1.0), Spring("1", "2", 2.0)))
    moved = dataclasses.replace(rig, springs=(Spring("1", "frame", 1.0),
                                              Spring("1", "2", 2.0)), springs_n_m=None)
    assert moved.springs_n_m == (1.0, 2.0)


def test_diagnose_refuses_permuted_sensors():
    from bayesmodal.discrepancy.diagnosis import diagnose

    chain = Rig()
    rev = Rig(carts=chain.carts, springs=chain.springs, drive=chain.drive,
              sensors=tuple(reversed(chain.sensors)))
    t = np.arange(50) * DT
    e = Experiment(t, np.ones(50), np.zeros((50, 3)) + t[:, None])
    with pytest.raises(ModelError, match="sensor on every moving cart"):
        diagnose([e], rig=rev)
