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
REFUSED = ("lugre_friction", "backlash")


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
    assert "coulomb_friction" in why
    with pytest.raises(ModelError, match="simulate every sensor kind"):
        ext.simulate(rig, ext.null_theta(rig, THETA), np.zeros(10), DT)
    # with positions only they simulate as before
    assert ext.unsupported(rig_with(POSITIONS)) is None


# ---------------------------------------------------------------- stick-slip friction
#: Friction levels (N, rig order) that stick both carts between the pulses of ``PULSE``:
#: Fc1, Fc2, Fs1, Fs2; Fcp1, Fcp2, Fcn1, Fcn2, Fs1, Fs2 (directional).
FRICTION = {"coulomb_friction": [1.5, 1.2, 2.5, 2.0],
            "coulomb_directional": [1.2, 1.0, 1.5, 1.3, 2.5, 2.0]}
#: Every kind of every cart in SI, positions first (the readings are the carts' states).
SI = tuple(Sensor(c, unit) for unit in ("m", "m/s", "m/s^2") for c in ("1", "2"))


def pulse(n: int = N) -> np.ndarray:
    """0 V, 1 V held over 90 samples, 0 V again: the carts break away at both edges and
    stick between them, the input held while they rest (both of the kernel's shortcuts
    past samples at rest)."""
    k = np.arange(n)
    return np.where((k >= 20) & (k < 110), 1.0, 0.0)


def friction_acceleration(model: LinearModel, theta_lin, levels, y, u, with_friction=True):
    """``M^-1 (b u - C v - K x - f)`` at every sample from the SI readings ``y``
    (positions, velocities, accelerations of the n free carts): ``f`` is ``Fc(d) d`` on a
    sliding cart (``v != 0``, ``d = sign v``), the static balance (acceleration 0) on a
    stuck cart with ``|F| < Fs`` and ``Fc(d) d`` with ``d = sign F`` on one that breaks
    away at the sample.  Returns the accelerations (N, n) and the sum of the sizes of the
    terms of each (for the rounding bound)."""
    M, C, K, b = model.matrices(theta_lin)
    n = b.size
    levels = np.asarray(levels, float)
    fwd, bwd, fs = (levels[:n], levels[:n], levels[n:]) if levels.size == 2 * n else (
        levels[:n], levels[n : 2 * n], levels[2 * n :])
    x, v = y[:, :n], y[:, n : 2 * n]
    F = u[:, None] * b - x @ K.T - v @ C.T
    size = np.abs(u)[:, None] * np.abs(b) + np.abs(x) @ np.abs(K).T + np.abs(v) @ np.abs(C).T
    stuck = v == 0.0
    d = np.where(stuck, np.sign(F), np.sign(v))
    f = np.where(d > 0, fwd, bwd) * d if with_friction else 0.0
    held = stuck & (np.abs(F) < fs)
    m = np.diag(M)
    return np.where(held, 0.0, (F - f) / m), (size + np.where(d > 0, fwd, bwd)) / m


@pytest.mark.parametrize("name", sorted(FRICTION))
def test_friction_rates_are_the_states_and_forces_at_the_sample(name):
    ext = get_extension(name)
    rig = rig_with(SI)
    model = LinearModel(rig, "free")
    u = pulse()
    theta = np.r_[THETA, FRICTION[name]]
    y = ext.simulate(rig, theta, u, DT)
    # the positions are those of the position-only kernel, bit for bit
    np.testing.assert_array_equal(y[:, :2], ext.simulate(rig_with(POSITIONS), theta, u, DT))
    # velocities: the kernel's own state.  Its whole state at a sample is a function of
    # the positions and velocities (stuck <=> v = 0, direction = sign v, a stuck cart
    # where it is), so a run restarted from the readings of a sample continues the record
    # bit for bit, stuck, sliding or just stopped; the velocities differenced from the
    # positions (the negative control) do not
    starts = (25, 60, 100, 115, 150)
    for k in starts:
        again = ext.simulate(rig, theta, u[k:], DT, x0=y[k, :4])
        np.testing.assert_array_equal(again, y[k:])
        v_diff = (y[k + 1, :2] - y[k - 1, :2]) / (2 * DT)
        if np.any(y[k, 2:4] != 0.0):
            off = ext.simulate(rig_with(POSITIONS), theta, u[k:], DT,
                               x0=np.r_[y[k, :2], v_diff])
            assert np.abs(off - y[k:, :2]).max() > 1e6 * EPS * np.abs(y[:, :2]).max()
    # accelerations: M^-1 (b u - C v - K x - f) from the readings, to rounding (the
    # kernel sums the same terms in another order); without the friction force they
    # miss by Fc / m on every sliding sample
    a, size = friction_acceleration(model, THETA, FRICTION[name], y, u)
    tol = 16 * EPS * size
    np.testing.assert_array_less(np.abs(y[:, 4:] - a), tol + 1e-300)
    a_free, _ = friction_acceleration(model, THETA, FRICTION[name], y, u, with_friction=False)
    sliding = y[:, 2:4] != 0.0
    assert sliding.sum() > 100
    miss = np.abs(y[:, 4:] - a_free)[sliding]
    assert miss.min() > 1e6 * tol[sliding].max()
    # stuck stretches (both carts still at this sample and the next) read zero rates
    # exactly, the samples the kernel skips at rest too (the input held), and a cart
    # breaking away at the pulse's edge reads its kinetic acceleration at once
    still = np.all(y[:, 2:4] == 0.0, axis=1)
    both = still & np.r_[still[1:], True]
    assert both[:19].all() and both.sum() > 50 and both[25:110].any()
    np.testing.assert_array_equal(y[both, 4:], 0.0)
    assert y[20, 2] == 0.0 and y[20, 4] > 0.5 * (THETA[0] * 1.0 - 2.0) / THETA[1]


def test_friction_batch_reads_as_its_sets_one_at_a_time():
    # six sets in a 16-lane kernel, lanes stuck and sliding side by side; groups of lanes
    # all at rest are skipped and must write their zero rates
    ext = get_extension("coulomb_friction")
    rig = rig_with(SENSORS)
    u = pulse()
    sets = np.array([np.r_[THETA * s, np.array(FRICTION["coulomb_friction"]) * f]
                     for s, f in ((1.0, 1.0), (1.1, 0.5), (0.9, 2.0), (1.0, 0.7),
                                  (1.2, 1.3), (1.0, 1.0))])
    six = ext.simulate(rig, sets, u, DT)
    for theta, y in zip(sets, six, strict=True):
        np.testing.assert_array_equal(y, ext.simulate(rig, theta, u, DT))


def _chain_reversed() -> Rig:
    return Rig(drive=(Drive("1", -1.0),),
               sensors=tuple(Sensor(c, unit) for unit in ("m", "m/s", "m/s^2")
                             for c in ("1", "2", "3")))


def _four_clamped() -> Rig:
    carts = tuple(Cart(str(i)) for i in range(1, 5))
    springs = (Spring("1", "frame", 800.0), Spring("1", "2", 450.0), Spring("2", "3", 400.0),
               Spring("3", "4", 350.0), Spring("4", "frame", 600.0))
    return Rig(carts=carts, springs=springs, drive=(Drive("2"),), clamped=("3",),
               sensors=tuple(Sensor(c, unit) for unit in ("m", "m/s", "m/s^2")
                             for c in ("1", "2", "4")))


@pytest.mark.parametrize("make", [_chain_reversed, _four_clamped])
def test_friction_rates_on_other_layouts(make):
    # three free carts in both (one compiled kernel): the chain driven backwards, and four
    # carts driven at cart 2 with cart 3 clamped (the kernel's order: driven cart first)
    ext = get_extension("coulomb_friction")
    rig = make()
    model = LinearModel(rig, "free")
    lin = model.as_vector(dict(zip(model.names, [1.0] * model.n_params, strict=True)))
    lin[0], lin[1:4] = 6.2, (1.5, 1.4, 1.2)
    u = np.r_[np.random.default_rng(4).normal(size=300), pulse(300)]
    # null friction reads as the linear model, to the rounding of an exact hold
    y = ext.simulate(rig, ext.null_theta(rig, lin), u, DT)
    y_lin = simulate_linear(model, lin, u, DT)
    A, B = model.state_space(lin)
    tol = (2 * zoh_rtol(A, DT, n_steps=u.size) * np.abs(y_lin).max(axis=0)
           + 4 * EPS * np.abs(B).max() * np.abs(u).max())
    np.testing.assert_array_less(np.abs(y - y_lin).max(axis=0), tol)
    # active friction: the accelerations are M^-1 (b u - C v - K x - f) of the readings
    levels = [0.8, 0.6, 0.7, 1.4, 1.0, 1.2]
    y = ext.simulate(rig, np.r_[lin, levels], u, DT)
    a, size = friction_acceleration(model, lin, levels, y, u)
    np.testing.assert_array_less(np.abs(y[:, 6:] - a), 16 * EPS * size + 1e-300)
    assert (y[:, 3:6] == 0.0).sum() > 50 and (y[:, 3:6] != 0.0).sum() > 50
