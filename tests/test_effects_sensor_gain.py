"""The sensor-gain effect: one module and one registry entry (bayesmodal/model/effects/
sensor_gain.py), against closed forms and a known truth."""

import numpy as np
import pytest
from conftest import TABLE3

from bayesmodal import ModelError
from bayesmodal.data import Experiment
from bayesmodal.fit import fit_extension_lsq
from bayesmodal.model import EXTENSIONS, LinearModel, Rig, load_rig, simulate_linear
from bayesmodal.model.effects import get_extension, suggested_by

DT = 0.005
RIG = Rig()


def _input(n=1200):
    u = np.zeros(n)
    u[1:10] = 3.0
    u[400:700] = 0.5
    return u


def test_registered_from_its_module_alone():
    ext = EXTENSIONS["sensor_gain"]
    assert ext.extension_names(RIG) == ("s_2", "s_3")
    assert suggested_by("sensor_gain") == ("sensor_gain",)
    assert not ext.default_candidate  # the ECP diagnosis keeps its catalogue


def test_scales_the_linear_outputs_exactly():
    ext = EXTENSIONS["sensor_gain"]
    u = _input()
    y_lin = simulate_linear(LinearModel(RIG, "free"), TABLE3, u, DT)
    y = ext.simulate(RIG, np.r_[TABLE3, 1.05, 0.97], u, DT)
    # the same simulation, read through the scales (exact: one multiplication each)
    np.testing.assert_array_equal(y[:, 0], ext.simulate(RIG, np.r_[TABLE3, 1.0, 1.0], u,
                                                         DT)[:, 0])
    np.testing.assert_allclose(y, y_lin * [1.0, 1.05, 0.97], rtol=1e-12,
                               atol=1e-12 * np.abs(y_lin).max())
    # null values: the linear model (negative control of the scaling above)
    np.testing.assert_allclose(ext.simulate(RIG, np.r_[TABLE3, 1.0, 1.0], u, DT), y_lin,
                               rtol=1e-12, atol=1e-12 * np.abs(y_lin).max())


def test_combines_with_a_plant_effect():
    both = get_extension("coulomb_friction+sensor_gain")
    fric = EXTENSIONS["coulomb_friction"]
    u = _input()
    f = fric.typical
    y = both.simulate(RIG, np.r_[TABLE3, f, 1.05, 0.97], u, DT)
    y_f = fric.simulate(RIG, np.r_[TABLE3, f], u, DT)
    np.testing.assert_allclose(y, y_f * [1.0, 1.05, 0.97], rtol=1e-12,
                               atol=1e-12 * np.abs(y_f).max())


def test_a_one_sensor_rig_is_refused_with_the_reason():
    with pytest.raises(ModelError, match="one sensor"):
        EXTENSIONS["sensor_gain"].simulate(load_rig("ecp210-1cart"), [6.0, 1.5, 2.0, ], _input(20),
                                           DT)


def test_least_squares_recovers_a_hidden_scale_error():
    """Sensor 3 reads 4 % high: the fit finds the scales within 4 of their Gauss-Newton
    standard errors (white noise of known size: those errors are right)."""
    ext = EXTENSIONS["sensor_gain"]
    u = _input(2400)
    truth = np.r_[TABLE3, 1.0, 1.04]
    y = ext.simulate(RIG, truth, u, DT)
    sigma = 1e-6
    rng = np.random.default_rng(5)
    e = Experiment(np.arange(u.size) * DT, u, y + sigma * rng.standard_normal(y.shape))
    fit = fit_extension_lsq(e, ext, RIG)
    # Jacobian of the outputs at the estimate (central differences, relative step 1e-6)
    th = fit.theta
    h = 1e-6 * np.maximum(np.abs(th), 1e-3)
    plus = ext.simulate(RIG, th + np.diag(h), u, DT)
    minus = ext.simulate(RIG, th - np.diag(h), u, DT)
    J = ((plus - minus) / (2 * h)[:, None, None]).reshape(th.size, -1).T
    se = sigma * np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    assert np.all(np.abs(th[-2:] - truth[-2:]) < 4 * se[-2:]), (th[-2:], se[-2:])
    assert se[-1] < 0.01  # the check above is not vacuous: 4 se is well below the 4 %
