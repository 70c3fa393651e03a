"""Velocity and acceleration sensors read through the LuGre friction and backlash kernels.

The null parameters (no friction level, no gap) are checked with every other effect in
``test_effect_sensor_kinds.py``; here, on the same two-cart rig:

- a batch of six sets (one 16-lane kernel) reads as each set alone (the one-lane kernel);
- LuGre friction is smooth: the rates are the derivatives of the positions of a run 32
  times finer, within that record's own truncation error
  (``test_rates_are_derivatives_of_the_positions_of_a_finer_run``), and, as a negative
  control, the acceleration of the linear rig at the same states, the bristle force left
  out, misses those derivatives by far more than that tolerance;
- backlash has impacts when the gap closes, where no difference of positions is a
  derivative: each acceleration is instead compared with the forces evaluated here from
  the simulated positions and velocities (every state is a sensor's reading), cart 1's
  as ``(F1 + g_v u) / m1`` with the gap closed or ``F1 / (m1 - m_p)`` with it open, to
  the rounding of those sums; the two modes must both occur and differ by far more than
  the tolerance (the negative control), and away from the switches the rates are again
  the derivatives of a finer run's positions.
"""

from __future__ import annotations

import numpy as np
import pytest
import test_effect_sensor_kinds as base
from conftest import EPS
from test_effect_sensor_kinds import (
    DT,
    SENSORS,
    THETA,
    LinearModel,
    N,
    Sensor,
    derivatives,
    raised_cosine,
    rig_with,
)

from bayesmodal.model.effects import get_extension

#: Active parameters: LuGre levels of a few tenths of a newton against a 3 V (18.6 N) drive,
#: bristles at their typical stiffness; a half-millimetre gap with a 0.3 kg motor.
ACTIVE = {"lugre_friction": [0.3, 0.2, 0.45, 0.3, 2e4, 100.0, 0.005],
          "backlash": [5e-4, 0.3]}
#: positions and velocities of both carts and both accelerations (the forces at every
#: sample can be evaluated from the readings)
STATES = (Sensor("1", "m"), Sensor("2", "m"), Sensor("1", "m/s"), Sensor("2", "m/s"),
          Sensor("1", "m/s^2"), Sensor("2", "m/s^2"))


@pytest.mark.parametrize("name", sorted(ACTIVE))
def test_a_batch_reads_as_its_sets_one_at_a_time(name):
    ext = get_extension(name)
    rig = rig_with(SENSORS)
    th = np.r_[THETA, ACTIVE[name]]
    other = np.r_[THETA * 1.1, ACTIVE[name]]
    u = raised_cosine(N)
    six = ext.simulate(rig, np.stack([th, other] * 3), u, DT)
    np.testing.assert_array_equal(six[0], ext.simulate(rig, th, u, DT))
    np.testing.assert_array_equal(six[1], ext.simulate(rig, other, u, DT))


@pytest.mark.parametrize("sensors", ["every kind", "accelerometers"])
def test_lugre_rates_are_derivatives_of_a_finer_run(sensors, monkeypatch):
    monkeypatch.setitem(base.ACTIVE, "lugre_friction", ACTIVE["lugre_friction"])
    base.test_rates_are_derivatives_of_the_positions_of_a_finer_run("lugre_friction",
                                                                      sensors)


def _tolerance(ext, theta, u, r=32):
    """The finite differences' truncation error plus the record's own error (as in
    ``test_rates_are_derivatives_of_the_positions_of_a_finer_run``), cart by cart, for
    the accelerations of STATES; and the one-sided derivative of the finer run."""
    y = ext.simulate(rig_with(STATES), theta, u, DT)
    x_fine = ext.simulate(rig_with(base.POSITIONS), theta, np.repeat(u, r), DT / r)
    y_fine = ext.simulate(rig_with(STATES), theta, np.repeat(u, r), DT / r)[::r]
    d1, d2 = derivatives(x_fine, r, 2, 1), derivatives(x_fine, r, 2, 2)
    return y, d1, np.abs(d1 - d2), np.abs(y[: N - 1, 4:] - y_fine[: N - 1, 4:])


def test_lugre_acceleration_carries_the_bristle_force():
    # negative control: the linear rig's acceleration at the same states (no friction)
    ext = get_extension("lugre_friction")
    theta = np.r_[THETA, ACTIVE["lugre_friction"]]
    u = raised_cosine(N)
    y, d1, trunc, own = _tolerance(ext, theta, u)
    tol = 3.0 * (trunc.max(axis=0) + own.max(axis=0))
    assert np.all(np.abs(y[: N - 1, 4:] - d1).max(axis=0) <= tol)
    A, B = LinearModel(rig_with(base.POSITIONS), "free").state_space(THETA)
    linear = y[:, :4] @ A[2:].T + np.outer(u, B[2:])
    miss = np.abs(linear[: N - 1] - d1).max(axis=0)
    assert np.all(miss > 10 * tol), (miss, tol)


def test_backlash_acceleration_is_the_force_of_its_mode_over_the_mass():
    ext = get_extension("backlash")
    gap, m_p = ACTIVE["backlash"]
    theta = np.r_[THETA, ACTIVE["backlash"]]
    u = raised_cosine(N) * np.cos(2 * np.pi * np.arange(N) / 40)  # reversals open the gap
    y = ext.simulate(rig_with(STATES), theta, u, DT)
    M, C, K, b = LinearModel(rig_with(base.POSITIONS), "free").matrices(THETA)
    z = y[:, :4]  # (x1, x2, v1, v2)
    force = -z[:, :2] @ K.T - z[:, 2:] @ C.T  # springs and dampers on each cart, N
    closed = (force[:, 0] + b[0] * u) / M[0, 0]
    open_ = force[:, 0] / (M[0, 0] - m_p)
    # rounding of the sums: a few terms, each within a few eps of the largest
    scale = (np.abs(z[:, :2]) @ np.abs(K).T + np.abs(z[:, 2:]) @ np.abs(C).T
             + np.abs(b) * np.abs(u)[:, None]) / np.diag(M)
    tol = 16 * EPS * scale.max()
    a1, a2 = y[:, 4], y[:, 5]
    np.testing.assert_array_less(np.abs(a2 - force[:, 1] / M[1, 1]), tol)
    is_closed = np.abs(a1 - closed) <= tol
    is_open = np.abs(a1 - open_) <= tol
    assert np.all(is_closed | is_open)
    # both modes occur, and where the gap is open the engaged formula misses by far more
    assert 0.05 < is_open.mean() < 0.95, is_open.mean()
    only_open = is_open & ~is_closed
    assert np.median(np.abs(a1 - closed)[only_open]) > 100 * tol


def test_backlash_rates_away_from_the_switches_are_derivatives_of_a_finer_run():
    # the raised cosine pushes cart 1 one way, so the gap closes once near the start and
    # the drive stays engaged; samples whose stencil sees the first impact are left out
    ext = get_extension("backlash")
    theta = np.r_[THETA, ACTIVE["backlash"]]
    u = raised_cosine(N)
    y, d1, trunc, own = _tolerance(ext, theta, u)
    M, C, K, b = LinearModel(rig_with(base.POSITIONS), "free").matrices(THETA)
    z = y[:, :4]
    closed = (-(z[:, :2] @ K[0]) - z[:, 2:] @ C[0] + b[0] * u) / M[0, 0]
    engaged = np.abs(y[:, 4] - closed) <= 1e-9 * np.abs(closed).max()
    # samples engaged over this one and the next (the stencil's span, 2 x 7 of 32 steps)
    ok = engaged[: N - 1] & engaged[1:]
    ok[:10] = False  # the first closure: the gap is taken up over the first samples
    assert ok.mean() > 0.8
    tol = 3.0 * (trunc[ok].max(axis=0) + own[ok].max(axis=0))
    err = np.abs(y[: N - 1, 4:][ok] - d1[ok]).max(axis=0)
    assert np.all(err <= tol), (err, tol)
    assert np.all(tol < 0.02 * np.abs(y[:, 4:]).max(axis=0))


#: Combinations through the kernels' other layouts: the end stop and the input stages
#: applied in the LuGre kernel (shared input), a per-lane input held over a finer grid
#: behind the motor lag (backlash).
COMBINED = {"end_stop+lugre_friction+input_offset":
                [0.03, 3000.0, *ACTIVE["lugre_friction"], 0.1],
            "backlash+input_offset+motor_lag": [*ACTIVE["backlash"], 0.1, 0.01]}


@pytest.mark.parametrize("name", sorted(COMBINED))
def test_combinations_at_null_parameters_read_as_the_linear_model(name):
    base.test_null_parameters_read_as_the_linear_model(name, "1", "every kind")


def test_lugre_with_stop_and_stages_reads_the_stop_force():
    # in the stop the cart reverses, and the bristles' break-away there is fast for the
    # 8-point stencil at one sample: the tolerance is each sample's own truncation error
    # (plus the record's own error), not the largest over the record
    name = "end_stop+lugre_friction+input_offset"
    ext = get_extension(name)
    theta = np.r_[THETA, COMBINED[name]]
    u = raised_cosine(N)
    y, d1, trunc, own = _tolerance(ext, theta, u)
    x_fine = ext.simulate(rig_with(base.POSITIONS), theta, np.repeat(u, 32), DT / 32)
    ok = base.smooth_after(name, theta, x_fine, 32)
    tol = 3.0 * (trunc + own.max(axis=0))[ok]
    assert np.all(np.abs(y[: N - 1, 4:][ok] - d1[ok]) <= tol)
    assert np.all(np.median(tol, axis=0) < 0.01 * np.abs(d1).max(axis=0))
    # negative control: without the stop's force (k_stop (x1 - x_stop) / m1 in contact)
    # cart 1's acceleration misses by far more than the tolerance where the cart is in it
    x_stop, k_stop = COMBINED[name][:2]
    depth = np.maximum(0.0, y[: N - 1, 0] - x_stop)[ok]
    without = y[: N - 1, 4][ok] + k_stop * depth / THETA[1]
    deep = depth > 0.2 * depth.max()
    assert deep.sum() > 10
    assert np.all(np.abs(without - d1[ok, 0])[deep] > 10 * tol[deep, 0])


def test_backlash_behind_a_lag_reads_its_batch_as_its_sets():
    name = "backlash+input_offset+motor_lag"
    ext = get_extension(name)
    rig = rig_with(SENSORS)
    th = np.r_[THETA, COMBINED[name]]
    other = np.r_[THETA * 1.1, COMBINED[name]]
    u = raised_cosine(N)
    six = ext.simulate(rig, np.stack([th, other] * 3), u, DT)
    np.testing.assert_array_equal(six[1], ext.simulate(rig, other, u, DT))
