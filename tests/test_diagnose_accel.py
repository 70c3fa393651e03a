"""``diagnose`` on accelerometer records: known truths from the independent references.

The records (``hidden_accel``) come from ``solve_ivp`` on the two-cart rig assembled by
hand, read by an accelerometer on each cart with noise and 16-bit quantisation; the
diagnosis must name the hidden effect and where it acts, and nothing on the linear rig.
The rates over many seeds live in ``benchmarks/detection_accel.py``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hidden_accel import accel_rig, make_accel_case
from hidden_pairs import judge

from bayesmodal import ModelError
from bayesmodal.data import Experiment
from bayesmodal.discrepancy.checks import NEEDS_POSITIONS, diagnostics_for, linear_residuals
from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES, diagnose
from bayesmodal.model.effects import EXTENSIONS
from bayesmodal.model.elements import Sensor
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel

SEED = 5


def _candidates(rig):
    return tuple(c for c in (*DEFAULT_CANDIDATES, "end_stop")
                 if not EXTENSIONS[c].unsupported(rig))


def _diagnose(h, rig=None):
    rig = accel_rig() if rig is None else rig
    return diagnose(h.experiment, rig=rig, posterior=False, n_null=19, rng=SEED,
                    candidates=_candidates(rig))


def test_residuals_are_in_the_accelerometers_units():
    """The prediction is the model's own acceleration output: on a noise-free record of
    the reference the residual is the reference-vs-package integration error, far below
    the accelerometer's noise, and the position checks are left out."""
    h = make_accel_case("none", SEED)
    model = LinearModel(accel_rig(), "free")
    res = linear_residuals(h.experiment, model, h.theta_lin)
    y = simulate_linear(model, h.theta_lin, h.experiment.v_volt, h.experiment.dt)
    np.testing.assert_array_equal(res.y_pred, y)
    # the record's noise: its residual's spread, at least the converter's step / sqrt(12)
    sd = np.std(res.residual, axis=0)
    assert np.all(sd < 0.03 * 1.2) and np.all(sd > 0.01 * 0.8)
    assert np.all(np.isnan(res.v_meas))  # no measured velocity from an accelerometer
    names = diagnostics_for(model)
    assert names and not set(names) & NEEDS_POSITIONS


def test_names_nothing_on_the_linear_rig():
    h = make_accel_case("none", SEED)
    d = _diagnose(h)
    assert judge(h, d)[0], (d.cause, d.notes)
    assert any("skipped on acceleration records" in n for n in d.notes)


@pytest.mark.slow  # about 5 min each on a shared core (the forward selection's refits)
@pytest.mark.parametrize("case", ["end_stop", "cubic_stiffness", "coulomb_friction"])
def test_names_the_hidden_effect_on_accelerometer_records(case):
    h = make_accel_case(case, SEED)
    d = _diagnose(h)
    ok, found = judge(h, d)
    assert ok, (case, found, d.cause, d.notes)


def test_position_records_out_of_cart_order_are_refused_in_one_line():
    rig = accel_rig()
    swapped = dataclasses.replace(
        rig, sensors=tuple(Sensor(s.cart, "m") for s in reversed(rig.sensors)))
    e = Experiment(np.arange(400) * 0.005, np.r_[1.0, np.zeros(399)], np.zeros((400, 2)))
    with pytest.raises(ModelError, match="in cart order") as info:
        diagnose(e, rig=swapped, posterior=False, rng=1)
    assert "\n" not in str(info.value)
