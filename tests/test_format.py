"""Number formatting of text outputs: units, significant digits, values on their bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayesmodal._format import estimate, param_unit, percent, sig, values

EPS = np.finfo(float).eps


def test_value_on_its_bound_reads_at_bound():
    assert estimate(1.25999e-43, 0.44, unit="N s/m", lower=0.0) == "0 (at bound) +- 0.44 N s/m"
    # the threshold is sqrt(eps) of the standard error: just above it is a number again
    se = 0.44
    above = 2 * math.sqrt(EPS) * se
    assert "at bound" not in estimate(above, se, lower=0.0)
    assert "at bound" in estimate(0.5 * math.sqrt(EPS) * se, se, lower=0.0)


def test_negative_control_no_bound_given_prints_the_number():
    assert "at bound" not in estimate(1.25999e-43, 0.44)


@pytest.mark.parametrize("value,se", [(6.22345, 0.01234), (1.5648, 0.0022), (2.92, 0.12),
                                      (123.456, 7.8), (0.01384, 0.0067)])
def test_rounded_to_the_second_digit_of_the_error(value, se):
    text = estimate(value, se, unit="kg")
    assert text.endswith(" kg")
    v_txt, se_txt = text[:-3].split(" +- ")
    # the error keeps two significant digits, the value the same decimal places
    assert float(se_txt) == pytest.approx(se, rel=0.05)
    dec = len(se_txt.split(".")[1]) if "." in se_txt else 0
    assert (len(v_txt.split(".")[1]) if "." in v_txt else 0) == dec
    assert abs(float(v_txt) - value) <= 0.5 * 10.0**-dec * (1 + 1e-9)


def test_tiny_values_share_a_power_of_ten():
    text = estimate(8.583e-05, 1.02e-06, unit="s")
    assert text == "(8.58 +- 0.10)e-05 s"


def test_units_and_lists():
    assert [param_unit(n) for n in ("g_v", "m3", "c23", "ca", "cb", "k2")] == \
        ["N/V", "kg", "N s/m", "1/s", "s", "N/m"]
    assert param_unit("friction_fc1") == ""
    assert values([8.28081, 27.4038], unit="rad/s") == "8.281, 27.4 rad/s"
    assert percent([93.45359705083726, 81.0]) == "93.5 %, 81.0 %"
    assert sig(float("nan")) == "nan" and sig(0.0) == "0"
