"""Sensor kinds in the rig description: position, velocity and acceleration sensors, their
scales and signs, several per cart, the TOML form, and reading records of them in SI."""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import DataError, ModelError
from bayesmodal.data import load_experiment, options_for_rig
from bayesmodal.model.rigs import load_rig, rig_from_dict, rig_from_toml, rig_to_toml
from bayesmodal.model.system import (
    STANDARD_GRAVITY_M_S2,
    LinearModel,
    Rig,
    Sensor,
)
from bayesmodal.reading import ReadOptions

CARTS = [{"name": "1"}, {"name": "2"}]
SPRINGS = [{"between": ["1", "2"], "stiffness_n_m": 774.0},
           {"between": ["2", "frame"], "stiffness_n_m": 770.0}]


def two_cart(sensors) -> Rig:
    return rig_from_dict({"carts": CARTS, "springs": SPRINGS, "drive": {"carts": ["1"]},
                          "sensors": sensors})


def test_units_set_kind_and_si_scale():
    cases = {"m": ("position", 1.0), "mm": ("position", 1e-3), "m/s": ("velocity", 1.0),
             "m/s^2": ("acceleration", 1.0), "g": ("acceleration", 9.80665)}
    for unit, (kind, scale) in cases.items():
        s = Sensor("1", unit)
        assert (s.kind, s.si_per_unit) == (kind, scale)
    assert STANDARD_GRAVITY_M_S2 == 9.80665  # the CGPM's standard gravity, exactly
    assert Sensor("1", "count", 2e-5).si_per_unit == 2e-5
    assert [Sensor("1", u).order for u in ("mm", "m/s", "g")] == [0, 1, 2]


def test_sign_key_and_negative_scale_are_the_same_sensor():
    assert Sensor("1", "count", -2e-5) == Sensor("1", "count", 2e-5, sign=-1)
    assert Sensor("1", "count", -2e-5).si_per_unit == -2e-5
    assert Sensor("1", "g", sign=-1).si_per_unit == -9.80665
    # a negative scale with sign = -1 flips twice
    assert Sensor("1", "count", -2e-5, sign=-1).si_per_unit == 2e-5


@pytest.mark.parametrize("kwargs, match", [
    ({"unit": "inch"}, "unit 'inch' is not supported; use one of"),
    ({"unit": "g", "m_per_unit": 9.81}, "drop m_per_unit"),
    ({"unit": "m/s", "sign": 2}, "sign must be 1 or -1"),
    ({"unit": "m", "sign": True}, "sign must be 1 or -1"),
    ({"unit": "count"}, "needs m_per_unit"),
    ({"unit": "count", "m_per_unit": 0.0}, "m_per_unit must be finite and > 0"),
])
def test_bad_sensors_give_one_line_errors(kwargs, match):
    with pytest.raises(ModelError, match=match) as info:
        Sensor("1", **kwargs)
    assert "\n" not in str(info.value)


def test_several_sensors_per_cart_when_kinds_differ():
    rig = two_cart([{"cart": "1", "unit": "count", "m_per_unit": 4.4125e-6},
                    {"cart": "1", "unit": "g"}, {"cart": "2", "unit": "m/s"}])
    assert rig.output_kinds == ("position", "acceleration", "velocity")
    assert not rig.positions_only and not rig.is_chain
    model = LinearModel(rig, "free")
    assert model.output_spec.tolist() == [[0, 0], [0, 2], [1, 1]]
    assert model.output_index is not None  # never the chain's fast path
    with pytest.raises(ModelError, match="two acceleration sensors on cart '1'"):
        two_cart([{"cart": "1", "unit": "g"}, {"cart": "1", "unit": "m/s^2"}])


def test_accelerometers_on_every_cart_are_not_the_chain():
    chain = Rig(springs_n_m=(774.0, 770.0))
    acc = Rig(carts=chain.carts, springs=chain.springs, drive=chain.drive,
              sensors=(Sensor("1", "g"), Sensor("2", "g")))
    assert chain.is_chain and not acc.is_chain
    assert LinearModel(acc).names == LinearModel(chain).names
    assert LinearModel(chain).output_spec is None


def test_toml_round_trip_keeps_kinds_and_signs():
    rig = two_cart([{"cart": "1", "unit": "count", "m_per_unit": -4.4125e-6},
                    {"cart": "2", "unit": "g", "sign": -1}, {"cart": "2", "unit": "m/s"}])
    text = rig_to_toml(rig)
    assert 'sign = -1' in text
    back = rig_from_toml(text)
    assert back == rig
    assert [s.si_per_unit for s in back.sensors] == [-4.4125e-6, -9.80665, 1.0]
    # the shipped presets are unchanged: encoders counting +x
    assert all(s.sign == 1 and s.kind == "position" for s in load_rig("ecp210-2cart").sensors)


def test_unknown_sensor_key_is_refused():
    with pytest.raises(ModelError, match="unknown key 'scale'"):
        two_cart([{"cart": "1", "unit": "g", "scale": 2.0}])


def _write_txt(path, t, cols, v):
    np.savetxt(path, np.column_stack([t, *cols, v]))


def test_reader_scales_each_column_to_si(tmp_path):
    rig = two_cart([{"cart": "1", "unit": "count", "m_per_unit": 4.4125e-6},
                    {"cart": "2", "unit": "g", "sign": -1}])
    rng = np.random.default_rng(3)
    n = 400
    t = np.arange(n) * 0.002
    counts = np.round(200 * np.sin(2 * np.pi * t))
    acc_g = rng.normal(0, 0.5, n)  # up to ~1.5 g: 15 m/s^2, far above a plausible metre
    v = 0.5 * np.sin(2 * np.pi * t)
    path = tmp_path / "hammer.txt"
    _write_txt(path, t, [counts, acc_g], v)
    opts = options_for_rig(ReadOptions(), rig, path)
    e = load_experiment(path, options=opts)
    # scaling by exact constants: equal to the product of the floats
    np.testing.assert_array_equal(e.y_m[:, 0], counts * 4.4125e-6)
    np.testing.assert_array_equal(e.y_m[:, 1], acc_g * -9.80665)
    # negative control: read as positions in metres, the accelerations in g are
    # implausible displacements
    with pytest.raises(DataError, match="implausible"):
        load_experiment(path, options=ReadOptions(m_per_count=1.0))


def test_csv_holds_si_already(tmp_path):
    rig = two_cart([{"cart": "1", "unit": "m"}, {"cart": "2", "unit": "m/s^2"}])
    path = tmp_path / "r.csv"
    t = np.arange(300) * 0.002
    a = 5.0 * np.sin(30 * t)
    np.savetxt(path, np.column_stack([t, np.sin(t), 0.01 * np.sin(t), a]), delimiter=",",
               header="t,v,x1,x2", comments="")
    opts = options_for_rig(ReadOptions(), rig, path)
    assert opts.output_scales is None and opts.output_kinds == ("position", "acceleration")
    e = load_experiment(path, options=opts)
    np.testing.assert_array_equal(e.y_m[:, 1], a)
    # a positions-only rig along +x leaves the options alone
    plain = two_cart([{"cart": "1"}, {"cart": "2"}])
    assert options_for_rig(ReadOptions(), plain, path) == ReadOptions()


def test_reader_options_check_lengths(tmp_path):
    path = tmp_path / "r.txt"
    _write_txt(path, np.arange(50) * 0.01, [np.zeros(50)], np.zeros(50))
    with pytest.raises(DataError, match="1 output columns but output_kinds lists 2"):
        load_experiment(path, options=ReadOptions(output_kinds=("position", "velocity")))


def test_diagnose_takes_accelerometer_records_and_refuses_positions_out_of_order():
    from bayesmodal.discrepancy.diagnosis import require_diagnosable

    require_diagnosable(two_cart([{"cart": "1", "unit": "g"}, {"cart": "2", "unit": "g"}]))
    swapped = two_cart([{"cart": "2"}, {"cart": "1"}])
    with pytest.raises(ModelError, match="diagnose needs a sensor on every moving cart, "
                                         "in cart order") as info:
        require_diagnosable(swapped)
    assert "\n" not in str(info.value)


def test_lsq_on_an_encoder_and_an_accelerometer_under_a_voltage():
    """A voltage-driven rig read by an encoder on cart 1 and an accelerometer on cart 2
    (mixed kinds): white noise on each, every estimate within 4 standard errors."""
    from bayesmodal.data import Experiment
    from bayesmodal.fit import fit_lsq
    from bayesmodal.model.simulate import simulate_linear

    rig = two_cart([{"cart": "1", "unit": "count", "m_per_unit": 4.4125e-6},
                    {"cart": "2", "unit": "g"}])
    model = LinearModel(rig, "free")
    assert model.names == ("g_v", "m1", "m2", "c1", "c2", "c12")
    truth = np.array([6.2, 1.5, 1.4, 2.0, 1.5, 0.5])
    rng = np.random.default_rng(17)
    dt, n = 0.005, 2000
    t = np.arange(n) * dt
    v = np.where((t % 5.0 >= 0.1) & (t % 5.0 < 0.15), 3.0, 0.0)
    y = simulate_linear(model, truth, v, dt)
    y = y + rng.normal(0.0, [2e-5, 0.02], y.shape)
    res = fit_lsq(Experiment(t, v, y), model, theta0=truth * 1.1)
    z = (res.theta - truth) / res.stderr
    assert np.all(np.abs(z) < 4), dict(zip(model.names, z, strict=True))
