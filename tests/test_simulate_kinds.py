"""The linear simulator's velocity and acceleration outputs.

The reference here is independent of the package: the equations of motion of a two-cart
rig written out by hand (force on each cart from each spring and damper), integrated with
``scipy.integrate.solve_ivp`` over each interval of constant (zero-order-hold) input; a
velocity is a state, an acceleration the right-hand side at the sample with the input
held from it.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, ode_atol, zoh_rtol
from scipy.integrate import solve_ivp

from bayesmodal._errors import ModelError
from bayesmodal.model.simulate import LinearSimulator, simulate_linear
from bayesmodal.model.system import Cart, Drive, LinearModel, Rig, Sensor, Spring

REF_RTOL, REF_ATOL = 1e-11, 1e-14
K1, K2 = 774.0, 770.0  # N/m: cart 1 - k1 - cart 2 - k2 - frame


def rig_with(sensors) -> Rig:
    return Rig(carts=(Cart("1"), Cart("2")),
               springs=(Spring("1", "2", K1), Spring("2", "frame", K2)),
               drive=(Drive("1"),), sensors=tuple(sensors))


MIXED = (Sensor("1", "count", 4.4125e-6), Sensor("2", "m/s"), Sensor("1", "g"),
         Sensor("2", "m/s^2"), Sensor("1", "m/s"))
#: (g_v N/V, m1, m2 kg, c1, c2, c12 N s/m) in LinearModel(rig, "free").names order
THETA = np.array([[6.2, 1.5, 1.4, 2.0, 1.5, 0.5],
                  [5.0, 1.2, 1.6, 0.8, 3.0, 0.1]])


def accel(theta, x, xd, v):
    """Cart accelerations of the two-cart rig, written from the free-body diagrams."""
    g, m1, m2, c1, c2, c12 = theta
    f1 = K1 * (x[1] - x[0]) + c12 * (xd[1] - xd[0]) - c1 * xd[0] + g * v
    f2 = K1 * (x[0] - x[1]) - K2 * x[1] + c12 * (xd[0] - xd[1]) - c2 * xd[1]
    return np.array([f1 / m1, f2 / m2])


def reference(theta, v, t, sensors):
    """Each sensor's reading at the sample times ``t`` (N,), SI, and the number of
    integrator steps."""
    state = np.zeros(4)
    states = np.empty((t.size, 4))
    states[0] = state
    n_steps = 0
    for k in range(t.size - 1):
        def rhs(_t, s, level=v[k]):
            return np.r_[s[2:], accel(theta, s[:2], s[2:], level)]
        sol = solve_ivp(rhs, (t[k], t[k + 1]), state, method="DOP853", rtol=REF_RTOL,
                        atol=REF_ATOL)
        n_steps += -(-sol.nfev // 12)
        state = sol.y[:, -1]
        states[k + 1] = state
    out = np.empty((t.size, len(sensors)))
    for j, s in enumerate(sensors):
        i = int(s.cart) - 1
        if s.kind == "position":
            out[:, j] = states[:, i]
        elif s.kind == "velocity":
            out[:, j] = states[:, 2 + i]
        else:  # the right-hand side at t_k with the input held from t_k
            out[:, j] = [accel(theta, x[:2], x[2:], vk)[i] for x, vk in zip(states, v,
                                                                               strict=True)]
    return out, states, n_steps


def tolerance(model, theta, dt, states, n_steps, y_ref):
    """Per-column bound: the simulator's own error (``zoh_rtol``) plus the reference
    integrator's, on the state; an acceleration adds the state error through the rows of
    ``A`` (``|a - a_ref| <= ||A_acc||_inf |x - x_ref|``)."""
    A, _ = model.state_space(theta)
    scale = float(np.max(np.abs(states)))
    err_state = (zoh_rtol(A, dt) * scale
                 + ode_atol(n_steps, REF_RTOL, REF_ATOL, scale))
    tol = np.empty(len(model.rig.sensors))
    a_norm = float(np.max(np.sum(np.abs(A[2:]), axis=1)))
    for j, s in enumerate(model.rig.sensors):
        col = float(np.max(np.abs(y_ref[:, j])))
        tol[j] = (a_norm * err_state if s.kind == "acceleration" else err_state) \
            + 8 * EPS * col
    return tol


def levels(rng, n, dt):
    """A random level held for 0.25 s, plus 3 V pulses: inputs with jumps."""
    t = np.arange(n) * dt
    v = rng.uniform(-1.0, 1.0, size=int(n * dt / 0.25) + 1)[(t / 0.25).astype(int)]
    return np.where((t % 1.0) < 0.02, 3.0, v)


def test_each_kind_matches_the_reference():
    rng = np.random.default_rng(40)
    dt, n = 0.004, 600
    v = levels(rng, n, dt)
    model = LinearModel(rig_with(MIXED), "free")
    y = simulate_linear(model, THETA, v, dt)
    assert y.shape == (2, n, len(MIXED))
    for b in range(2):
        y_ref, states, n_steps = reference(THETA[b], v, np.arange(n) * dt, MIXED)
        tol = tolerance(model, THETA[b], dt, states, n_steps, y_ref)
        err = np.max(np.abs(y[b] - y_ref), axis=0)
        assert np.all(err <= tol), (err, tol)
    # the accelerometer in g reads the same SI acceleration as the one in m/s^2 would
    assert MIXED[2].si_per_unit == 9.80665


def test_acceleration_carries_the_input_feedthrough():
    """From rest, the first sample's acceleration is the force of the held input over the
    mass, ``g_v v_0 / m1``; positions and velocities are still zero."""
    model = LinearModel(rig_with(MIXED), "free")
    v = np.r_[2.0, np.zeros(9)]
    y = simulate_linear(model, THETA[0], v, 0.005)
    g, m1 = THETA[0, :2]
    np.testing.assert_array_equal(y[0, [0, 1, 3, 4]], 0.0)
    assert abs(y[0, 2] - g * 2.0 / m1) <= 4 * EPS * g * 2.0 / m1


def test_full_state_path_matches_the_reference():
    """Overdamped modes have no complex modal form: the full-state recursion and the output
    matrix compute them."""
    theta = np.array([6.2, 1.5, 1.4, 150.0, 120.0, 0.5])  # c1, c2 far above critical
    model = LinearModel(rig_with(MIXED), "free")
    dt, n = 0.004, 400
    v = levels(np.random.default_rng(7), n, dt)
    M, C, K, b = model.matrices(theta[None])
    sim = LinearSimulator(v, dt, len(MIXED), outputs=model.output_spec)
    prepared = sim.prepare_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)
    assert not prepared[3].any()  # no lane takes the modal kernel
    y = sim.run_prepared(prepared)[0]
    y_ref, states, n_steps = reference(theta, v, np.arange(n) * dt, MIXED)
    tol = tolerance(model, theta, dt, states, n_steps, y_ref)
    assert np.all(np.max(np.abs(y - y_ref), axis=0) <= tol)


def test_recorded_steps_match_the_reference():
    rng = np.random.default_rng(11)
    n = 500
    steps = rng.choice([0.004, 0.005], size=n - 1)
    t = np.r_[0.0, np.cumsum(steps)]
    v = levels(rng, n, 0.0045)
    model = LinearModel(rig_with(MIXED), "free")
    y = simulate_linear(model, THETA[0], v, steps)
    y_ref, states, n_steps = reference(THETA[0], v, t, MIXED)
    tol = tolerance(model, THETA[0], 0.004, states, n_steps, y_ref)
    # each distinct step carries its own discretisation: twice the simulator's error
    assert np.all(np.max(np.abs(y - y_ref), axis=0) <= 2 * tol)


def test_one_cart_step_acceleration_closed_form():
    """``m x'' + c x' + k x = g`` from rest: ``x'' = (g/m) e^(-s t) (cos(wd t) -
    (s/wd) sin(wd t))`` with ``s = c / 2m``, ``wd = sqrt(k/m - s^2)``; exact at the samples
    under a step (the input does not change)."""
    k, g, m, c = 500.0, 4.0, 1.3, 1.1
    rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", k),), drive=(Drive("1"),),
              sensors=(Sensor("1", "m/s^2"), Sensor("1", "m/s"), Sensor("1", "m")))
    model = LinearModel(rig, "free")
    dt, n = 0.002, 3000
    t = np.arange(n) * dt
    y = simulate_linear(model, np.array([g, m, c]), np.ones(n), dt)
    s = c / (2 * m)
    wd = np.sqrt(k / m - s**2)
    decay = np.exp(-s * t)
    a = g / m * decay * (np.cos(wd * t) - s / wd * np.sin(wd * t))
    vel = g / m / wd * decay * np.sin(wd * t)
    x = g / k * (1 - decay * (np.cos(wd * t) + s / wd * np.sin(wd * t)))
    # each output is the modal recursion read through its own gains (lambda^order times
    # the position's): it carries the recursion's relative error
    A, _ = model.state_space(np.array([g, m, c]))
    rtol = zoh_rtol(A, dt, n_steps=n)
    for col, exact in zip(y.T, (a, vel, x), strict=True):
        assert np.max(np.abs(col - exact)) <= rtol * np.max(np.abs(exact))
    assert y[0, 0] == pytest.approx(g / m, rel=4 * EPS)


def _smooth_pair(dt, t_end=4.0):
    """Acceleration and position of cart 2 and the input, under a smooth input."""
    t = np.arange(int(round(t_end / dt)) + 1) * dt
    v = np.sin(2 * np.pi * 1.3 * t) * np.exp(-(((t - 2.0) / 0.6) ** 2))
    rig = rig_with((Sensor("2", "m"), Sensor("2", "m/s^2"), Sensor("1", "m"),
                    Sensor("1", "m/s^2")))
    y = simulate_linear(LinearModel(rig, "free"), THETA[0], v, dt)
    return y, v


def _second_difference_error(dt, *, feedthrough=True):
    y, v = _smooth_pair(dt)
    d2 = (y[2:, 2] - 2 * y[1:-1, 2] + y[:-2, 2]) / dt**2
    # over [t_{k-1}, t_{k+1}] the held input is v[k-1], then v[k]: the second difference
    # averages the feedthrough g v / m1 of both, the acceleration at t_k has v[k]'s
    g, m1 = THETA[0, :2]
    a = y[1:-1, 3] - (g / m1 * (v[1:-1] - v[:-2]) / 2 if feedthrough else 0.0)
    return float(np.max(np.abs(d2 - a))), float(np.max(np.abs(y[:, 3])))


def test_acceleration_is_the_second_derivative_of_position():
    """The second difference of the position output converges to the acceleration output
    at second order, the truncation of the difference itself: nothing else separates
    them.  Negative control: without the half-step average of the input's feedthrough the
    difference is first order (the acceleration holds the input from the sample)."""
    e1, peak = _second_difference_error(0.002)
    e2, _ = _second_difference_error(0.001)
    assert e1 < 1e-4 * peak
    assert 3.5 < e1 / e2 < 4.5  # O(dt^2)
    f1, _ = _second_difference_error(0.002, feedthrough=False)
    f2, _ = _second_difference_error(0.001, feedthrough=False)
    assert 1.7 < f1 / f2 < 2.3 and f1 > 10 * e1


def test_position_outputs_are_unchanged():
    """All-position outputs take the plain path bit for bit; positions within a mixed rig
    agree with it to rounding."""
    rng = np.random.default_rng(5)
    v = levels(rng, 300, 0.005)
    model = LinearModel(rig_with((Sensor("1"), Sensor("2"))), "free")
    theta = THETA[0]
    M, C, K, b = model.matrices(theta[None])
    masses = np.diagonal(M, axis1=1, axis2=2)
    plain = LinearSimulator(v, 0.005, 2).run_second_order(masses, C, K, b).copy()
    spec = LinearSimulator(v, 0.005, 2, outputs=[(0, 0), (1, 0)])
    assert spec.outputs is None
    np.testing.assert_array_equal(spec.run_second_order(masses, C, K, b), plain)
    mixed = simulate_linear(LinearModel(rig_with(MIXED), "free"), theta, v, 0.005)
    assert np.max(np.abs(mixed[:, 0] - plain[0, :, 0])) <= 64 * EPS * np.max(np.abs(plain))


def test_simulator_refuses_bad_output_specs():
    with pytest.raises(ModelError, match="one \\(dof, order\\) pair per output"):
        LinearSimulator(np.zeros(5), 0.01, 3, outputs=[(0, 2)])
    with pytest.raises(ModelError, match="order 0, 1 or 2"):
        LinearSimulator(np.zeros(5), 0.01, 1, outputs=[(0, 3)])
    sim = LinearSimulator(np.zeros(5), 0.01, 1, outputs=[(0, 2)])
    with pytest.raises(ModelError, match="use run_second_order"):
        sim.run(np.zeros((1, 2, 2)), np.zeros((1, 2)))
