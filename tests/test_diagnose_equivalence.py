"""Friction on a driven cart with a drive offset reads as directional friction.

``diagnosis.equivalence``: while the cart slides, equal levels ``Fc`` with the offset
``v0`` push it exactly as directional levels ``Fcp = Fc - s g_v v0``, ``Fcn = Fc + s g_v
v0`` without one; they differ in the breakaway thresholds only (``-Fs - s g_v v0``,
``Fs - s g_v v0`` against the directional model's symmetric ones), which a step or pulse
input crosses within one sample under either reading.  Checked on the package's
simulators (one cart, pulses that stop and restart the cart); negative controls: a slow
sine, whose force reaches the thresholds gradually, and the pulses through a dead band.
"""

import numpy as np
import pytest

from bayesmodal.discrepancy.diagnosis.equivalence import equivalent_readings
from bayesmodal.model.effects import get_extension
from bayesmodal.model.rigs import load_rig

RIG = load_rig("ecp210-1cart")
LIN = np.array([6.3, 1.5, 3.0])  # g_v V->N, m1 kg, c1 N s/m
FC, FS, V0 = 0.8, 1.0, -0.05
DT = 0.005
EPS = np.finfo(float).eps


def _pair(u, extra=()):
    ext = get_extension(["coulomb_friction", "input_offset", *extra])
    names = ext.extension_names(RIG)
    theta = dict(Fc1=FC, Fs1=FS, v_offset=V0, v_dead=0.1)
    return ext.simulate(RIG, np.r_[LIN, [theta[n] for n in names]], u, DT)


def _directional(u, extra=()):
    ext = get_extension(["coulomb_directional", *extra])
    s = LIN[0] * RIG.input_vector()[0]
    theta = dict(Fcp1=FC - s * V0, Fcn1=FC + s * V0, Fs1=FS + abs(s * V0), v_dead=0.1)
    names = ext.extension_names(RIG)
    return ext.simulate(RIG, np.r_[LIN, [theta[n] for n in names]], u, DT)


def _sine():
    t = np.arange(4000) * DT
    return 2.5 * np.sin(2 * np.pi * 0.4 * t) * (t > 0.5)


def _pulses():
    t = np.arange(4000) * DT
    return 1.1 * np.sign(np.sin(2 * np.pi * 0.25 * t)) * (t > 0.5)


def _stuck(y):
    return int(np.sum(np.diff(y[:, 0]) == 0.0))


def test_under_steps_and_pulses_the_two_readings_are_one_motion():
    u = _pulses()
    a, b = _pair(u), _directional(u)
    assert _stuck(a) > 100  # the cart is held between pulses: breakaway is exercised
    # the two kernels integrate the same force: they differ by rounding, a few hundred
    # operations per sample over the record's samples
    assert np.max(np.abs(a - b)) <= 1e3 * EPS * np.max(np.abs(a)) * len(u) ** 0.5


def test_a_slow_sine_and_a_dead_band_tell_them_apart():
    """Negative controls: a sine reaches the breakaway force gradually, so the shifted
    thresholds move the breakaway; a dead band shapes ``v + v0``, not ``v``."""
    u, p = _sine(), _pulses()
    scale = np.max(np.abs(_pair(p)))
    for diff in (_pair(u) - _directional(u),
                 _pair(p, ["drive_deadband"]) - _directional(p, ["drive_deadband"])):
        assert np.max(np.abs(diff)) > 1e6 * EPS * scale * len(u) ** 0.5


@pytest.mark.parametrize("effects", [["coulomb_directional"],
                                     ["coulomb_friction", "input_offset"]])
def test_the_note_gives_the_other_reading(effects):
    s = LIN[0]
    p = dict(g_v=LIN[0], Fc1=FC, Fs1=FS, v_offset=V0, Fcp1=FC - s * V0, Fcn1=FC + s * V0)
    (note,) = equivalent_readings(effects, p, RIG)
    other = (f"drive offset of {V0:+.4f} V" if effects == ["coulomb_directional"]
             else f"Fcp {FC - s * V0:.3f} N, Fcn {FC + s * V0:.3f} N")
    assert other in note
    assert equivalent_readings(effects + ["drive_deadband"], p, RIG) == []
    assert equivalent_readings(["coulomb_friction"], p, RIG) == []


def test_the_note_says_whether_the_records_could_tell_them_apart():
    """With pulses only, the note tells how to tell the readings apart; where a record
    drives slowly (a sine), it says the records chose; a record of steps, pulses and a
    slow triangle drives slowly, one of steps and pulses alone does not."""
    from hidden_effects import rig_input
    from hidden_layouts import slow_triangle

    from bayesmodal.discrepancy.diagnosis.equivalence import has_slow_drive

    s = LIN[0]
    p = dict(g_v=LIN[0], Fc1=FC, Fs1=FS, Fcp1=FC - s * V0, Fcn1=FC + s * V0)
    (pulsed,) = equivalent_readings(["coulomb_directional"], p, RIG, [_pulses()])
    (slow,) = equivalent_readings(["coulomb_directional"], p, RIG, [_pulses(), _sine()])
    assert "add a slow ramp" in pulsed and "add a slow ramp" not in slow
    assert "records chose" in slow and "records chose" not in pulsed
    u = rig_input(2400)
    assert not has_slow_drive(u)
    assert has_slow_drive(np.concatenate([u, slow_triangle(1200)]))
