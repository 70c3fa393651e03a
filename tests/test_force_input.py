"""A measured force as the input: ``[drive] input = "force"`` (N, gain fixed at 1)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from bayesmodal._errors import DataError, ModelError
from bayesmodal.data import Experiment, load_experiment, options_for_rig, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.inference import Likelihood, default_priors
from bayesmodal.inference.priors import SIGMA_PRIOR_BOUNDS
from bayesmodal.model.rigs import rig_from_dict, rig_from_toml, rig_to_toml
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import Cart, LinearModel, Rig, Spring
from bayesmodal.reading import ReadOptions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import force_noise_bias as fnb  # noqa: E402

CARTS = [{"name": "1"}, {"name": "2"}]
SPRINGS = [{"name": "k1", "between": ["1", "2"], "stiffness_n_m": 774.0, "known": False},
           {"name": "k2", "between": ["2", "frame"], "stiffness_n_m": 770.0, "known": False}]


def force_rig(**drive) -> Rig:
    return rig_from_dict({"carts": CARTS, "springs": SPRINGS,
                          "drive": {"carts": ["1"], "input": "force", **drive},
                          "sensors": [{"cart": "1", "unit": "g"}, {"cart": "2", "unit": "g"}]})


def test_force_input_has_no_gain_parameter():
    rig = force_rig()
    assert rig.input == "force" and rig.gain_n_v == 1.0 and not rig.per_unit_gain
    model = LinearModel(rig, "free")
    # every mass and spring unknown, yet absolute: the input is in newtons
    assert model.names == ("m1", "m2", "c1", "c2", "c12", "k1", "k2")
    M, C, K, b = model.matrices(fnb.TRUTH)
    np.testing.assert_array_equal(b, [1.0, 0.0])  # 1 N per N on cart 1
    assert rig_from_toml(rig_to_toml(rig)) == rig
    assert 'input = "force"' in rig_to_toml(rig) and "gain_n_v" not in rig_to_toml(rig)
    # a voltage rig with the same layout cannot separate masses, springs and gain
    voltage = rig_from_dict({"carts": CARTS, "springs": SPRINGS, "drive": {"carts": ["1"]}})
    assert voltage.per_unit_gain


@pytest.mark.parametrize("drive, match", [
    ({"gain_n_v": 6.2}, "a force input has gain 1 .* drop gain_n_v"),
    ({"input": "current"}, "input must be one of \\('voltage', 'force'\\)"),
])
def test_bad_force_inputs_give_one_line_errors(drive, match):
    with pytest.raises(ModelError, match=match) as info:
        force_rig(**drive)
    assert "\n" not in str(info.value)


def test_force_input_needs_a_driven_cart():
    with pytest.raises(ModelError, match="list them in \\[drive\\] carts"):
        Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", 500.0),), input="force")


def test_force_record_is_read_in_newtons(tmp_path):
    rig = force_rig()
    t = np.arange(500) * 0.002
    f = np.where(t < 0.01, 150.0, 0.0)
    e = Experiment(t, f, np.zeros((500, 2)) + 0.01 * np.sin(t)[:, None])
    save_csv(e, tmp_path / "hammer.csv")
    opts = options_for_rig(ReadOptions(), rig, tmp_path / "hammer.csv")
    assert opts.input_kind == "force"
    np.testing.assert_array_equal(load_experiment(tmp_path / "hammer.csv", options=opts).v_volt,
                                  f)
    # negative control: read as a voltage, 150 is far beyond the motor's command
    with pytest.raises(DataError, match="beyond the rig's"):
        load_experiment(tmp_path / "hammer.csv")


def test_noise_priors_follow_the_sensor_kind():
    rig = rig_from_dict({"carts": CARTS, "springs": SPRINGS,
                         "drive": {"carts": ["1"], "input": "force"},
                         "sensors": [{"cart": "1", "unit": "count", "m_per_unit": 1e-5},
                                     {"cart": "2", "unit": "g"}, {"cart": "2", "unit": "m/s"}]})
    ps = default_priors(LinearModel(rig, "free"), noise="ar1")
    pri = dict(zip(ps.names, ps.priors, strict=True))
    assert (pri["sigma_1"].lo, pri["sigma_1"].hi) == SIGMA_PRIOR_BOUNDS["position"]
    assert (pri["sigma_2"].lo, pri["sigma_2"].hi) == SIGMA_PRIOR_BOUNDS["acceleration"]
    assert (pri["sigma_3"].lo, pri["sigma_3"].hi) == SIGMA_PRIOR_BOUNDS["velocity"]
    assert "g_v" not in ps.names and ps.names[:7] == LinearModel(rig, "free").names


def test_lsq_recovers_a_hammer_test_within_its_standard_errors():
    """White accelerometer noise, exact force: each estimate within 4 standard errors of
    the truth (eleven checks at 4 sigma: a false alarm has probability ~1e-3)."""
    rng = np.random.default_rng(2026)
    model = LinearModel(fnb.RIG, "free")
    n = 3000  # two impacts
    f = fnb.hammer(n)
    t = np.arange(n) * fnb.DT
    y = simulate_linear(model, fnb.TRUTH, f, fnb.DT) + rng.normal(0, fnb.SIGMA_ACC, (n, 2))
    # started 10 % off the truth (the default start costs seconds more)
    res = fit_lsq(Experiment(t, f, y), model, theta0=fnb.TRUTH * 1.1)
    z = (res.theta - fnb.TRUTH) / res.stderr
    assert np.all(np.abs(z) < 4), dict(zip(model.names, z, strict=True))
    # negative control: a wrong mass is far outside
    assert abs(res.theta[0] * 1.02 - fnb.TRUTH[0]) > 4 * res.stderr[0]
    # the likelihood takes the same record and parameter names
    lik = Likelihood(model, [Experiment(t, f, y)], noise="white")
    assert lik.names[:7] == model.names
    at_truth = lik(np.r_[fnb.TRUTH, fnb.SIGMA_ACC, fnb.SIGMA_ACC][None])[0]
    off = lik(np.r_[fnb.TRUTH * np.r_[1.05, np.ones(6)], fnb.SIGMA_ACC, fnb.SIGMA_ACC][None])[0]
    assert np.isfinite(at_truth) and at_truth > off


@pytest.mark.slow
def test_force_noise_bias_reduced_study():
    """The force sensor's noise is ignored: at 1 % of the hammer's peak the masses come out
    heavy (attenuation: the model explains the force noise's response with a stiffer,
    heavier rig).  Without force noise the bias is zero within its standard error.
    Reduced from benchmarks/force_noise_bias.py (8 replicates instead of 100)."""
    table = fnb.study(8, levels=(0.0, 1.0), seed0=100)
    for nm in ("m1", "m2", "k1", "k2", "omega1", "omega2"):
        clean = table[0.0][nm]
        assert abs(clean["bias"]) < 4 * clean["se"] + 1e-12, (nm, clean)
    for nm in ("m1", "m2", "k1", "k2"):
        noisy = table[1.0][nm]
        assert noisy["bias"] > 4 * noisy["se"] and 0.03 < noisy["bias"] < 0.3, (nm, noisy)
