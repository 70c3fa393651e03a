"""Velocity and acceleration sensors read through the effects' simulators.

Three checks on a two-cart rig read by encoders, velocity sensors and accelerometers
(three per cart, in no cart order, one in g, one mounted backwards):

- at the null parameters every effect reads what the linear model reads (an independent
  path: the linear simulator's modal form), to the rounding of an exact hold;
- with the effect active under a slow raised-cosine voltage, the velocity and
  acceleration outputs are the first and second derivatives of the position output of a
  run sampled 32 times finer, taken by one-sided finite differences over the stencil
  after each sample (where the held input is constant and the motion smooth).  The
  tolerance is the record's own: the finite differences' truncation and rounding error,
  the difference between the stencil at step h and at 2h, plus the simulator's own error,
  the difference between the record's outputs and the finer run's at the same instants;
- a negative control: at a voltage step the derivative of positions across the sample
  (a centred difference) misses the input's feedthrough that the acceleration output
  carries, by far more than that tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import EPS, zoh_rtol

from bayesmodal._errors import ModelError
from bayesmodal.model.effects import EXTENSIONS, get_extension
from bayesmodal.model.effects._input import sensor_coordinates
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import Cart, Drive, LinearModel, Rig, Sensor, Spring

K1, K2 = 774.0, 770.0  # N/m: cart 1 - k1 - cart 2 - k2 - frame
DT, N = 0.005, 200
#: (g_v N/V, m1, m2 kg, c1, c2, c12 N s/m) in LinearModel(rig, "free").names order
THETA = np.array([6.2, 1.5, 1.4, 2.0, 1.5, 0.5])
#: every kind on each cart (one of a kind per cart), out of cart order; an accelerometer
#: in g, one mounted backwards
SENSORS = (Sensor("2", "mm"), Sensor("1", "g"), Sensor("2", "m/s"),
           Sensor("2", "m/s^2", sign=-1), Sensor("1", "m/s"), Sensor("1", "count", 4.4e-6))
#: fewer sensors than states: the linear recursion runs in sensor coordinates
#: (``effects._input.sensor_coordinates``), where the set above takes the output rows
SETS = {"every kind": SENSORS,
        "encoder and accelerometer": (Sensor("1", "count", 4.4e-6), Sensor("2", "g")),
        "accelerometers": (Sensor("2", "m/s^2"), Sensor("1", "m/s^2", sign=-1))}
KIND = np.array([s.order for s in SENSORS])
CART = np.array([int(s.cart) for s in SENSORS])
POSITIONS = (Sensor("1", "m"), Sensor("2", "m"))

#: Effects that read every sensor kind, with active parameters on this rig (the end stop
#: is met by cart 1, the lag and delay are several samples long, the cubic springs harden
#: the 57 mm swing by half).
ACTIVE = {
    "input_offset": [0.2],
    "drive_deadband": [0.3],
    "input_saturation": [2.0],
    "amplitude_gain": [0.03],
    "motor_lag": [0.01],
    "input_delay": [2.75 * DT],
    "sensor_gain": [1.02, 0.97, 1.05, 0.99, 1.01],
    "cubic_stiffness": [1e5, 5e4],
    "end_stop": [0.03, 3000.0],
    "cubic_stiffness+motor_lag": [1e5, 5e4, 0.01],
    "end_stop+input_delay+input_offset": [0.03, 3000.0, 2.75 * DT, 0.1],
    "input_offset+drive_deadband+input_saturation+motor_lag+input_delay":
        [0.1, 0.2, 2.5, 0.01, 1.5 * DT],
}
REFUSED = ("coulomb_friction", "coulomb_directional")


def rig_with(sensors, drive: str = "1") -> Rig:
    return Rig(carts=(Cart("1"), Cart("2")),
               springs=(Spring("1", "2", K1), Spring("2", "frame", K2)),
               drive=(Drive(drive),), sensors=tuple(sensors))


def raised_cosine(n: int) -> np.ndarray:
    """A slow voltage, 0 to 3 V and back over the record, V."""
    return 1.5 * (1.0 - np.cos(2.0 * np.pi * np.arange(n) / n))


def forward_weights(n_points: int, order: int) -> np.ndarray:
    """Weights of the one-sided difference ``f^(order)(0) ~ sum_j w_j f(j) / h^order`` on
    the points ``j = 0..n_points-1``: exact for polynomials of degree below n_points."""
    j = np.arange(float(n_points))
    rhs = np.zeros(n_points)
    rhs[order] = math.factorial(order)
    return np.linalg.solve(np.vander(j, increasing=True).T, rhs)


def derivatives(x_fine, r: int, order: int, step: int, n_points: int = 8):
    """Derivative of order 1 or 2 of the fine positions (n_fine, n_carts) at every coarse
    sample k (but the last), from the stencil ``k r + step * j`` (within the interval)."""
    k = np.arange(x_fine.shape[0] // r - 1)
    idx = k[:, None] * r + step * np.arange(n_points)[None]
    h = step * DT / r
    return np.einsum("j,kjc->kc", forward_weights(n_points, order), x_fine[idx]) / h**order


@pytest.mark.parametrize("sensors", sorted(SETS))
@pytest.mark.parametrize("drive", ["1", "2"])
@pytest.mark.parametrize("name", sorted(set(EXTENSIONS) - set(REFUSED)) + [
    "cubic_stiffness+motor_lag", "end_stop+input_delay+input_offset"])
def test_null_parameters_read_as_the_linear_model(name, drive, sensors):
    ext = get_extension(name)
    rig = rig_with(SETS[sensors], drive)
    if ext.unsupported(rig):  # effects at the driven cart need the motor on one cart
        pytest.skip(ext.unsupported(rig))
    u = np.random.default_rng(4).normal(size=600)
    y = ext.simulate(rig, ext.null_theta(rig, THETA), u, DT)
    model = LinearModel(rig, "free")
    y_lin = simulate_linear(model, THETA, u, DT)
    assert y.shape == y_lin.shape == (600, len(SETS[sensors]))
    # two exact holds of one linear system: each within the hold's rounding bound of the
    # exact answer, relative to each output's own size; an acceleration's feedthrough
    # adds the rounding of D u
    A, B = model.state_space(THETA)
    tol = (2 * zoh_rtol(A, DT, n_steps=u.size) * np.abs(y_lin).max(axis=0)
           + 4 * EPS * np.abs(B).max() * np.abs(u).max())
    np.testing.assert_array_less(np.abs(y - y_lin).max(axis=0), tol)


@pytest.mark.parametrize("name", ["cubic_stiffness", "motor_lag", "input_delay"])
def test_a_batch_reads_as_its_sets_one_at_a_time(name):
    # six sets run in a 16-lane (vectorised) kernel, a single one in the scalar kernel
    ext = get_extension(name)
    rig = rig_with(SENSORS)
    th = np.r_[THETA, ACTIVE[name]]
    other = np.r_[THETA * 1.1, ACTIVE[name]]
    six = ext.simulate(rig, np.stack([th, other] * 3), raised_cosine(N), DT)
    np.testing.assert_array_equal(six[0], ext.simulate(rig, th, raised_cosine(N), DT))
    np.testing.assert_array_equal(six[1], ext.simulate(rig, other, raised_cosine(N), DT))


def smooth_after(name, theta, x_fine, r: int, n_points: int = 8) -> np.ndarray:
    """Coarse samples (but the last) whose stencils see a smooth motion: all of them, but
    for an end stop those whose longer stencil (step 2h) reaches the contact's onset,
    where the stop's force has a kink and a difference of any order is first order."""
    k = np.arange(x_fine.shape[0] // r - 1)
    if "end_stop" not in name:
        return np.ones(k.size, bool)
    x_stop = theta[LinearModel(rig_with(POSITIONS), "free").n_params]
    window = x_fine[k[:, None] * r + np.arange(2 * n_points - 1)[None], 0] > x_stop
    return np.all(window, axis=1) | ~np.any(window, axis=1)


def _active(name, sensors=SENSORS):
    ext = get_extension(name)
    rig = rig_with(sensors)
    n_gains = len(sensors) - 1
    theta = np.r_[THETA, ACTIVE[name][:n_gains] if name == "sensor_gain" else ACTIVE[name]]
    return ext, rig, theta


def test_sensor_coordinates_where_the_readings_are_independent_states():
    from bayesmodal.model.effects._input import input_sensor_map, lagged_system
    from bayesmodal.model.effects._linear import sensor_spec

    for sensors, independent in ((SENSORS, False), (SETS["accelerometers"], True),
                                 (SETS["encoder and accelerometer"], True)):
        rig = rig_with(sensors)
        A, B = lagged_system(rig, THETA[None], np.array([0.01]))
        C, _, _ = input_sensor_map(A, B, sensor_spec(rig), 2)
        T, scale = sensor_coordinates(C, 2)
        assert (T is not None) == independent
        if independent:  # the first states of T z are the readings, scaled
            z = np.random.default_rng(1).normal(size=A.shape[-1])
            np.testing.assert_allclose((T[0] @ z)[: len(sensors)] * scale[0], C[0] @ z,
                                       rtol=8 * EPS * np.linalg.cond(T[0]))


@pytest.mark.parametrize("sensors", sorted(SETS))
@pytest.mark.parametrize("name", sorted(ACTIVE))
def test_rates_are_derivatives_of_the_positions_of_a_finer_run(name, sensors):
    ext, rig, theta = _active(name, SETS[sensors])
    kind = np.array([s.order for s in SETS[sensors]])
    cart = np.array([int(s.cart) for s in SETS[sensors]])
    r = 32
    u = raised_cosine(N)
    y = ext.simulate(rig, theta, u, DT)
    u_fine = np.repeat(u, r)  # the same held input, sampled r times finer
    if name == "sensor_gain":  # sensor j reads s_j times the linear rig's motion
        x_fine = simulate_linear(LinearModel(rig_with(POSITIONS), "free"), THETA, u_fine,
                                 DT / r)
        gain = np.r_[1.0, theta[THETA.size:]]
    else:
        x_fine = ext.simulate(rig_with(POSITIONS), theta, u_fine, DT / r)
        gain = np.ones(kind.size)
    y_fine = ext.simulate(rig, theta, u_fine, DT / r)[::r]
    # the effect must act: its readings differ from the linear model's
    y_lin = simulate_linear(LinearModel(rig, "free"), THETA, u, DT)
    assert np.abs(y - y_lin).max() > 1e-3 * np.abs(y_lin).max()
    ok = smooth_after(name, theta, x_fine, r)
    assert ok.mean() > 0.9
    for order in (1, 2):
        d1 = derivatives(x_fine, r, order, 1)[ok]
        d2 = derivatives(x_fine, r, order, 2)[ok]
        for j in np.flatnonzero(kind == order):
            c = cart[j] - 1
            exact = y[: N - 1, j][ok] / gain[j]
            truncation = np.abs(d1[:, c] - d2[:, c]).max()
            own = np.abs(y[: N - 1, j] - y_fine[: N - 1, j]).max() / gain[j]
            err = np.abs(exact - d1[:, c]).max()
            assert err <= 3.0 * (truncation + own), (name, j, err, truncation, own)
            # the comparison is sharp: far below the derivative's size
            assert 3.0 * (truncation + own) < 0.02 * np.abs(exact).max()


@pytest.mark.parametrize("name", ["input_offset", "motor_lag", "cubic_stiffness",
                                  "end_stop"])
def test_a_step_shows_the_feedthrough_a_difference_of_positions_misses(name):
    # the voltage steps by 2 V at sample k0: the acceleration just after it carries
    # g_v * 2 V / m1 more than just before, which positions differenced across the sample
    # see only half of; the motor lag is the control without feedthrough (its force is a
    # state, continuous across the step)
    ext, rig, theta = _active(name)
    r, k0 = 32, 60
    u = 0.1 * raised_cosine(N) + np.where(np.arange(N) >= k0, 2.0, 0.0)
    y = ext.simulate(rig, theta, u, DT)
    x_fine = ext.simulate(rig_with(POSITIONS), theta, np.repeat(u, r), DT / r)
    y_fine = ext.simulate(rig, theta, np.repeat(u, r), DT / r)[::r]
    a1 = np.flatnonzero((KIND == 2) & (CART == 1))[0]
    # the tolerance of the smooth case: the motion is smooth after each sample
    ok = smooth_after(name, theta, x_fine, r)
    assert ok[k0]
    one_sided = derivatives(x_fine, r, 2, 1)[ok, 0]
    truncation = np.abs(one_sided - derivatives(x_fine, r, 2, 2)[ok, 0]).max()
    own = np.abs(y[: N - 1, a1] - y_fine[: N - 1, a1]).max()
    tol = 3.0 * (truncation + own)
    assert np.abs(y[: N - 1, a1][ok] - one_sided).max() <= tol
    # a centred second difference of the fine positions across the step's sample
    h = DT / r
    k = k0 * r
    centred = (x_fine[k + 1, 0] - 2 * x_fine[k, 0] + x_fine[k - 1, 0]) / h**2
    miss = y[k0, a1] - centred
    feed = THETA[0] * 2.0 / THETA[1]  # the step's feedthrough, m/s^2
    if name == "motor_lag":  # only the jerk jumps: a miss of h / 6 times its jump
        assert abs(miss) < 0.01 * feed
    else:
        assert abs(miss) > 10 * tol
        np.testing.assert_allclose(miss, feed / 2, rtol=0.05)


@pytest.mark.parametrize("name", REFUSED)
def test_friction_and_backlash_refuse_rate_sensors_naming_what_works(name):
    rig = rig_with(SENSORS)
    ext = EXTENSIONS[name]
    why = ext.unsupported(rig)
    assert why is not None and "cubic_stiffness" in why and "input-side" in why
    with pytest.raises(ModelError, match="simulate every sensor kind"):
        ext.simulate(rig, ext.null_theta(rig, THETA), np.zeros(10), DT)
    # with positions only they simulate as before
    assert ext.unsupported(rig_with(POSITIONS)) is None
