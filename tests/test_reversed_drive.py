"""Signed scales and a reversed drive (+V moves the carts to negative counts).

A sign flip of the input or of the encoders is a lab convention, not a bad input: a
negative ``--input-scale`` / ``--m-per-count`` is read, and the reader guesses a reversed
drive from the record's static response (``reading.drive_sign``) and says so with the
fix.  The record is simulated from a known truth with the input negated; read with
``--input-scale -1`` its fit recovers the truth within the fit's own standard errors.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from conftest import run_cli as _cli

from bayesmodal import ConfigError
from bayesmodal.data import Experiment, load_experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import ReadOptions, drive_sign, parse_scale
from bayesmodal.runs.config import parse_config

THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
DT = 0.005
N = 2000
NOISE_M = 0.1 * 0.0706 / 16000
#: standard errors within which the fit must recover the truth
K_SE = 4.0


def _reversed(tmp_path, *, flip_outputs: bool = False):
    """A CSV whose carts were driven by minus its input column (or, ``flip_outputs``, a
    normal drive whose positions are written with the opposite sign)."""
    t = np.arange(N) * DT
    v = 0.5 * ((t % 4.0) < 2.0)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, DT)
    y = y + NOISE_M * np.random.default_rng(7).standard_normal(y.shape)
    path = tmp_path / ("flipped.csv" if flip_outputs else "reversed.csv")
    # reversed drive: the file's input is minus the voltage that moved the carts
    save_csv(Experiment(t, v if flip_outputs else -v, -y if flip_outputs else y), path)
    return path, v, y


def _load(path, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        e = load_experiment(path, **kw)
    return e, [str(w.message) for w in caught]


def test_signed_scales_are_read():
    assert parse_scale("-1", "--input-scale", signed=True) == -1.0
    assert parse_scale("-5/4096", "--input-scale", signed=True) == -5 / 4096
    for bad in ("0", "-0", "1e400"):
        with pytest.raises(ConfigError, match="finite and non-zero"):
            parse_scale(bad, "--input-scale", signed=True)
    with pytest.raises(ConfigError, match="finite and > 0"):  # time still runs forwards
        parse_scale("-1", "--time-scale")
    assert ReadOptions(input_scale=-1, m_per_count=-4.4125e-6).input_scale == -1.0
    with pytest.raises(ConfigError, match="input_scale must be finite and non-zero"):
        ReadOptions(input_scale=0)
    with pytest.raises(ConfigError, match="time_scale must be finite and > 0"):
        ReadOptions(time_scale=-1)
    cfg = parse_config({"data": {"files": ["a.csv"], "input_scale": "-1",
                                 "m_per_count": -4.4125e-6}},
                       source="cfg.toml", check_files=False)
    assert cfg.data.input_scale == -1.0 and cfg.data.m_per_count == -4.4125e-6


def test_a_reversed_drive_is_guessed_from_the_static_response(tmp_path):
    path, v, y = _reversed(tmp_path)
    e, warned = _load(path)
    assert len(warned) == 1, warned
    assert warned[0].startswith(f"{path}: the carts move against the input: below 0.5 Hz")
    assert warned[0].endswith("give --input-scale -1 (ReadOptions(input_scale=-1))")
    np.testing.assert_array_equal(e.v_volt, -v)  # read as it is: a guess, not a change
    # read with the fix: no warning, the input is the voltage that moved the carts
    e, warned = _load(path, options=ReadOptions(input_scale=-1))
    assert warned == []
    np.testing.assert_allclose(e.v_volt, v)
    # the normal record (negative control): the carts follow the input
    sign = drive_sign(v, y, DT)
    assert not sign.reversed and np.all(sign.correlation > 0)
    # no input, or a record too short for the band: no guess
    assert drive_sign(0 * v, y, DT) is None
    assert drive_sign(v[:100], y[:100], DT) is None


@pytest.mark.parametrize("flip_outputs", [False, True], ids=["input-scale", "m-per-count"])
def test_lsq_with_the_sign_flipped_recovers_the_truth(tmp_path, flip_outputs):
    path, _, _ = _reversed(tmp_path, flip_outputs=flip_outputs)
    fix = ["--m-per-count", "-1"] if flip_outputs else ["--input-scale", "-1"]
    code, out, err = _cli(["lsq", str(path), *fix, "--json"])
    assert code == 0 and err == [], err
    js = json.loads(out)
    assert js["identified"] is True
    names = list(js["parameters"])
    theta = np.array([js["parameters"][k] for k in names])
    se = np.array([js["stderr"][k] for k in names])
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se
