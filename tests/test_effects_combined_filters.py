"""A motor lag or an input delay in front of a nonlinear plant (``Combined`` with
``held_average``): closed forms for the held input, the order of the error against the
exact linear recursion, and backlash with a lag against an independent reference
(``reference_sim.simulate_backlash_ref`` with its lag state, solve_ivp with events)."""

import numpy as np
import pytest
from conftest import TABLE3
from reference_sim import simulate_backlash_ref

from bayesmodal import ModelError
from bayesmodal.data import ECP_M_PER_COUNT as COUNT
from bayesmodal.inference.propagate import propagate_modes
from bayesmodal.model.effects import EXTENSIONS, Combined, get_extension
from bayesmodal.model.effects._input import held_average
from bayesmodal.model.system import LinearModel, Rig

RIG = Rig()
DT = 0.005
EPS = np.finfo(float).eps


def _pulses(dt=DT, T=1.5):
    t = np.arange(int(round(T / dt))) * dt
    return 3.0 * ((t > 0.004) & (t < 0.05)) + 0.4 * ((t >= 0.5) & (t < 0.9)) - 2.0 * (
        (t >= 1.1) & (t < 1.14))


def test_held_average_of_a_lagged_step_is_the_interval_mean():
    """Step at t = 0 through tau f' = w - f: f = 1 - exp(-t / tau), whose mean over
    [k dt, (k + 1) dt) is 1 - tau / dt exp(-k dt / tau) (1 - exp(-dt / tau))."""
    tau, N = np.array([0.003, 0.02]), 50
    w = held_average(np.ones(N), DT, 2, tau=tau)
    k = np.arange(N)
    exact = 1.0 - tau[:, None] / DT * np.exp(-k * DT / tau[:, None]) * (
        1.0 - np.exp(-DT / tau[:, None]))
    np.testing.assert_allclose(w, exact, atol=10 * N * EPS)
    # no lag: the input itself; a lag of zero in one lane leaves that lane alone
    np.testing.assert_array_equal(held_average(np.arange(5.0), DT, 2, tau=np.array([0.0, 0.0])),
                                  np.tile(np.arange(5.0), (2, 1)))


def test_held_average_of_a_delay_mixes_neighbouring_samples():
    """D = (m + phi) dt: mean phi v[k-m-1] + (1 - phi) v[k-m], zero before the record."""
    v = np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    w = held_average(v, DT, 2, delay_s=np.array([0.25 * DT, 1.5 * DT]))
    np.testing.assert_allclose(w[0], [0.75, 1.75, 3.5, 7.0, 14.0], rtol=4 * EPS)
    np.testing.assert_allclose(w[1], [0.0, 0.5, 1.5, 3.0, 6.0], rtol=4 * EPS)


def _error_counts(n_hold, name, param, plant="backlash"):
    """Largest difference (counts) between the plant effect at its null (linear) with a
    lag or delay held per fine interval, and the exact linear recursion of that effect."""
    u = _pulses()
    plant_null = {"backlash": [0.0, 0.2], "coulomb_friction": [0.0] * 6}[plant]
    combo = Combined((EXTENSIONS[plant], EXTENSIONS[name]), n_hold=n_hold)
    y = combo.simulate(RIG, np.r_[TABLE3, plant_null, param], u, DT)
    exact = EXTENSIONS[name].simulate(RIG, np.r_[TABLE3, param], u, DT)
    return np.abs(y - exact).max() / COUNT


def _next_term(n):
    """Relative size of the next term of the error expansion at fine step dt / n: the
    fine step over the period of the fastest mode, omega_3 h."""
    omega = propagate_modes(LinearModel(RIG, "free"), TABLE3[None],
                            methods=("eig",)).omega_rad_s[0]
    return float(np.max(omega)) * DT / n


@pytest.mark.parametrize("param,plant", [(0.002, "backlash"), (0.01, "coulomb_friction")])
def test_held_lag_error_is_second_order(param, plant):
    """Halving the fine step divides the error by 4: each halving's observed order is 2
    within the next term of the expansion (omega_3 h, relative)."""
    ns = (1, 2, 4, 8)
    e = np.array([_error_counts(n, "motor_lag", param, plant) for n in ns])
    p = np.log2(e[:-1] / e[1:])
    tol = np.array([_next_term(n) for n in ns[:-1]])
    assert np.all(np.abs(p - 2.0) <= tol), (p, tol)


def test_held_delay_error_follows_its_leading_term():
    """A delay D = (m + phi) h held per fine step h errs by C phi (1 - phi) h^2 (the mean
    replaces a jump at phi h inside the step): the ratio of the error to phi (1 - phi) h^2
    is one constant C for every h, to the next term (omega_3 h, relative).  phi takes the
    values 0.26, 0.52, 0.04, 0.08 for n = 1, 2, 4, 8 here."""
    d, ns = 0.0113, (1, 2, 4, 8)
    phi = np.array([(d / (DT / n)) % 1.0 for n in ns])
    e = np.array([_error_counts(n, "input_delay", d) for n in ns])
    c = e / (phi * (1.0 - phi) / np.array(ns, float) ** 2)
    assert np.all(np.abs(c / c[-1] - 1.0) <= _next_term(1)), c
    # the jump at phi = 0 is on the grid: exact up to rounding
    assert _error_counts(2, "input_delay", 0.0125) < 1e-6


def test_backlash_with_lag_matches_the_reference():
    """Backlash (0.2 mm) with a 2 ms motor lag against the event-driven reference: the
    error is at most the sum of the two approximations' own errors, each measured alone on
    the same input (the held lag against the exact linear lag, backlash without a lag
    against the reference without one)."""
    u = _pulses()
    theta = np.r_[TABLE3, 2e-4, 0.2, 0.002]
    springs = RIG.springs_n_m
    combo = get_extension(["backlash", "motor_lag"])
    assert not combo.exact
    y = combo.simulate(RIG, theta, u, DT)
    ref = simulate_backlash_ref(springs, theta[:11], u, DT, tau=0.002)
    held = _error_counts(combo.n_hold, "motor_lag", 0.002)
    alone = np.abs(EXTENSIONS["backlash"].simulate(RIG, theta[:11], u, DT)
                   - simulate_backlash_ref(springs, theta[:11], u, DT)).max() / COUNT
    err = np.abs(y - ref).max() / COUNT
    assert err <= held + alone, (err, held, alone)
    # negative control: the reference without the lag is far from the lagged model
    far = np.abs(y - simulate_backlash_ref(springs, theta[:11], u, DT)).max() / COUNT
    assert far > 10 * (held + alone)


@pytest.mark.parametrize("bad", [0, -1, 2.5, True])
def test_n_hold_is_validated(bad):
    with pytest.raises(ModelError, match="n_hold"):
        Combined((EXTENSIONS["backlash"], EXTENSIONS["motor_lag"]), n_hold=bad)
