"""Rigs where nothing absolute is known (identified per unit of drive gain) and tied
parameters (``ties = [["k1", "k2"]]``), against a known truth.

The truth: two carts, frame spring at the driven cart, g_v = 6 N/V, m = 1.5 and 1.3 kg,
k1 = k2 = 500 N/m.  Per unit of drive gain every mass, damper and spring is divided by
g_v; the natural frequencies do not change.
"""

import json

import numpy as np
import pytest
from conftest import run_cli

from bayesmodal import ModelError
from bayesmodal.data import Experiment, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.modal import modal_summary
from bayesmodal.model.rigs import rig_from_toml, rig_to_toml
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel

DT = 0.005
G_V = 6.0
#: m1, m2, c1, c2, c12 (absolute), k1 = k2
ABSOLUTE = np.array([1.5, 1.3, 2.8, 2.0, 0.3])
K = 500.0
SIGMA = 2e-6  # m, white noise of the synthetic records


def _toml(*, known: bool, ties: bool) -> str:
    tie = 'ties = [["k1", "k2"]]\n' if ties else ""
    k = "true" if known else "false"
    return f'''{tie}
[[carts]]
name = "1"
[[carts]]
name = "2"
[[springs]]
name = "k1"
between = ["1", "frame"]
stiffness_n_m = {K}
known = {k}
[[springs]]
name = "k2"
between = ["1", "2"]
stiffness_n_m = {K}
known = {k}
[drive]
carts = ["1"]
'''


def _record(model: LinearModel, theta: np.ndarray, seed: int = 0) -> Experiment:
    u = np.zeros(2000)
    u[1:10] = 3.0
    u[600:1000] = 0.5
    y = simulate_linear(model, theta, u, DT)
    rng = np.random.default_rng(seed)
    return Experiment(np.arange(u.size) * DT, u, y + SIGMA * rng.standard_normal(y.shape),
                      name="synthetic")


def test_nothing_known_is_identified_per_unit_gain_with_ties():
    rig = rig_from_toml(_toml(known=False, ties=True))
    assert rig.per_unit_gain and rig_from_toml(rig_to_toml(rig)) == rig
    model = LinearModel(rig, "free")
    assert model.names == ("m1", "m2", "c1", "c2", "c12", "k1")  # no g_v, k2 follows k1
    assert model.scale == "per_unit_gain" and model.tied == {"k2": "k1"}
    truth = np.r_[ABSOLUTE, K] / G_V
    res = fit_lsq(_record(model, truth), model)
    # within 4 Gauss-Newton standard errors of the truth (white noise: they are right)
    assert np.all(np.abs(res.theta - truth) < 4 * res.stderr), (res.theta, truth, res.stderr)
    # the modal quantities are those of the absolute rig
    absolute = LinearModel(rig_from_toml(_toml(known=True, ties=False)), "free")
    w_abs = modal_summary(absolute, np.r_[G_V, ABSOLUTE])["omega_rad_s"]
    w_unit = modal_summary(model, truth)["omega_rad_s"]
    np.testing.assert_allclose(w_unit, w_abs, rtol=1e-12)


def test_a_tie_is_one_parameter_in_both_springs():
    rig = rig_from_toml(_toml(known=False, ties=True))
    model = LinearModel(rig, "free")
    _, _, Kmat, b = model.matrices(np.r_[ABSOLUTE, K] / G_V)
    k = K / G_V
    np.testing.assert_array_equal(Kmat, [[2 * k, -k], [-k, k]])  # k1 + k2 at cart 1
    np.testing.assert_array_equal(b, [1.0, 0.0])  # the gain is fixed at 1


def test_negative_controls_keep_the_absolute_model():
    known = LinearModel(rig_from_toml(_toml(known=True, ties=False)), "free")
    assert known.scale == "absolute" and known.names[0] == "g_v" and known.tied == {}


@pytest.mark.parametrize(("ties", "match"), [
    ('ties = [["k1", "k9"]]', "'k9' is not a parameter"),
    ('ties = [["k1", "m1"]]', "different kinds"),
    ('ties = [["k1"]]', "at least two"),
    ('ties = [["m1", "m2"], ["m2", "k1"]]', "in two ties"),
    ('ties = "k1"', "list of name lists"),
])
def test_bad_ties_are_refused_with_the_fix(ties, match):
    text = _toml(known=False, ties=False).replace("\n[[carts]]", ties + "\n[[carts]]", 1)
    with pytest.raises(ModelError, match=match):
        LinearModel(rig_from_toml(text), "free")


def test_a_known_spring_cannot_be_tied():
    text = _toml(known=True, ties=True)
    with pytest.raises(ModelError, match="spring k1 is known"):
        LinearModel(rig_from_toml(text), "free")


def test_lsq_says_per_unit_gain_in_text_and_json(tmp_path):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(_toml(known=False, ties=True))
    model = LinearModel(rig_from_toml(rig_path.read_text()), "free")
    csv = tmp_path / "rec.csv"
    save_csv(_record(model, np.r_[ABSOLUTE, K] / G_V), csv)
    code, out, _ = run_cli(["lsq", str(csv), "--rig", str(rig_path)])
    assert code == 0, out
    assert "per unit of drive gain" in out and "V s^2/m" in out and "k2 = k1 (tied" in out
    code, out, _ = run_cli(["lsq", str(csv), "--rig", str(rig_path), "--json"])
    summary = json.loads(out)
    assert summary["scale"] == "per_unit_gain" and summary["tied"] == {"k2": "k1"}
