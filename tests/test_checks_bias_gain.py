"""The input-bias and drive-gain-against-amplitude checks: they find what they look for,
point to the right effect, and stay silent on clean data (negative controls here and in
test_diagnostics.test_clean_linear_data_trigger_nothing, which runs every registered
check on clean white and AR(1) data).

Data: tests/hidden_pairs.py (independent reference simulators, sensor noise, counts).
"""

import numpy as np
import pytest
from hidden_effects import make
from hidden_pairs import make_case

from bayesmodal.discrepancy.checks import (
    RESIDUAL_DIAGNOSTICS,
    drive_gain_amplitude,
    input_bias,
    input_events,
    linear_residuals,
)
from bayesmodal.fit import fit_lsq
from bayesmodal.model.system import LinearModel, Rig

MODEL = LinearModel(Rig(), "free")


def _residuals(e):
    fit = fit_lsq(e, MODEL)
    return linear_residuals(e, MODEL, fit.theta)


@pytest.fixture(scope="module")
def offset():
    h = make_case("input_offset", 3, 2400)
    return h, _residuals(h.experiment)


@pytest.fixture(scope="module")
def deadband():
    h = make_case("drive_deadband", 3, 2400)
    return h, _residuals(h.experiment)


@pytest.fixture(scope="module")
def clean():
    return _residuals(make(None, 3, 2400).experiment)


def test_registered():
    assert RESIDUAL_DIAGNOSTICS["input_bias"] is input_bias
    assert RESIDUAL_DIAGNOSTICS["drive_gain"] is drive_gain_amplitude


def test_input_bias_finds_the_offset_and_its_sign(offset, clean):
    h, res = offset
    v0 = h.sizes["input_offset"][0]
    d = input_bias(res)
    assert d.detected and d.suggests == ("input_offset",), d.summary
    # the regression estimates the offset from its first-order response; its sign is
    # that of the truth and its size within 3 standard errors plus the part the linear
    # fit's gain absorbs (the fit is free to rescale g_v, which the offset response is
    # not orthogonal to): checked against the truth's sign and order of magnitude
    est = d.detail["offset_v"]
    assert np.sign(est) == np.sign(v0) and 0.2 < est / v0 < 5, (est, v0)
    # negative control: the same record without the offset
    c = input_bias(clean)
    assert not c.detected and c.suggests == (), c.summary


def test_drive_gain_rises_with_amplitude_behind_a_dead_band(deadband, clean):
    h, res = deadband
    # seven events give five degrees of freedom to the slope's t: test at 5 %
    d = drive_gain_amplitude(res, alpha=0.05)
    assert d.detected and d.suggests[0] == "drive_deadband", d.summary
    assert d.detail["slope_per_v"] > 0
    # every event of the record (4 pulses, 3 steps) is long enough to be analysed
    assert len(input_events(res.u, 40)) == 7
    c = drive_gain_amplitude(clean)
    assert not c.detected and c.suggests == (), c.summary


def test_drive_gain_falls_with_amplitude_behind_saturation():
    h = make("input_saturation", 1, 2400)
    d = drive_gain_amplitude(_residuals(h.experiment))
    assert d.detected and d.suggests[0] == "input_saturation", d.summary
    assert d.detail["slope_per_v"] < 0


def test_input_events():
    u = np.r_[np.zeros(5), np.full(3, 2.0), np.zeros(50), np.full(60, -0.5), np.zeros(10)]
    assert input_events(u, 1) == [(5, 58, 2.0), (58, 128, -0.5)]
    assert input_events(u, 60) == [(58, 128, -0.5)]
    assert input_events(np.zeros(10), 1) == []
