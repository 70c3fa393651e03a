"""Rest offsets per sensor: encoders not zeroed with the carts at rest.

A record whose outputs read a constant offset at rest (here +37, -12 and +5 counts) is
not a response from rest at 0, which the model starts from.  ``--rest-offset initial``
(``ReadOptions(rest_offset="initial")``) subtracts each output's mean over the samples
before the first input; the offset is then known to ``sigma / sqrt(n)``, and the fit
recovers the truth within its standard errors combined with that error's, which it does
not without the option (negative control); the command line refuses such a record
without it, naming the fix.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli as _cli

from bayesmodal import ConfigError, DataError
from bayesmodal._release import initial_rest
from bayesmodal.data import Experiment, load_experiment, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import ReadOptions

THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
M_PER_COUNT = 0.0706 / 16000
OFFSET_M = np.array([37.0, -12.0, 5.0]) * M_PER_COUNT
DT = 0.005
N = 1600
NOISE_M = 0.5 * M_PER_COUNT
#: standard errors within which the fit must recover the truth
K_SE = 4.0


def _record(tmp_path, start_s: float = 0.5):
    t = np.arange(N) * DT
    v = 0.5 * (((t - start_s) % 4.0) < 2.0) * (t >= start_s)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, DT)
    y = y + OFFSET_M + NOISE_M * np.random.default_rng(5).standard_normal(y.shape)
    path = tmp_path / "offset.csv"
    save_csv(Experiment(t, v, y), path)
    return path, v, y


def test_the_rest_before_the_input_is_the_offset(tmp_path):
    path, v, y = _record(tmp_path)
    n_rest = int(np.flatnonzero(v)[0])
    got = initial_rest("rec", v, y)
    # the mean of n white samples: standard error sigma / sqrt(n)
    assert np.all(np.abs(got - OFFSET_M) < 4 * NOISE_M / np.sqrt(n_rest))
    e = load_experiment(path, options=ReadOptions(rest_offset="initial"))
    np.testing.assert_allclose(e.y_m, y - got, atol=1e-15)


def _offset_stderr(exp: Experiment, theta: np.ndarray, se_offset_m: float) -> np.ndarray:
    """Standard error of the estimate from the removed offsets' own error (each output's
    offset known to ``se_offset_m``, independently): the change of the fit when one
    output's offset moves by one standard error, added in quadrature over the outputs."""
    model = LinearModel(Rig(), "free")
    total = np.zeros(theta.size)
    for o in range(exp.n_outputs):
        y = exp.y_m.copy()
        y[:, o] -= se_offset_m
        moved = fit_lsq(Experiment(exp.t_s, exp.v_volt, y), model, theta0=theta).theta
        total += (moved - theta) ** 2
    return np.sqrt(total)


def test_lsq_with_the_offset_removed_recovers_the_truth(tmp_path):
    path, v, _ = _record(tmp_path)
    code, out, err = _cli(["lsq", str(path), "--rest-offset", "initial", "--json"])
    assert code == 0 and err == [], err
    js = json.loads(out)
    theta = np.array(list(js["parameters"].values()))
    se = np.array(list(js["stderr"].values()))
    # the fit's standard errors take the removed offsets as exact; each is the mean of
    # the rest before the input, known to sigma / sqrt(n_rest), which adds its own error
    exp = load_experiment(path, options=ReadOptions(rest_offset="initial"))
    se_offset = _offset_stderr(exp, theta, NOISE_M / np.sqrt(np.flatnonzero(v)[0]))
    total = np.hypot(se, se_offset)
    assert np.all(np.abs(theta - THETA) < K_SE * total), (theta - THETA) / total
    # negative control: the offset left in biases the fit far beyond its standard errors
    # (g_v by over 1 000 of them: the fit is still "identified", its fit percent high) ...
    raw = fit_lsq(load_experiment(path), LinearModel(Rig(), "free"))
    assert np.any(np.abs(raw.theta - THETA) > 100 * total)
    # ... so the command line refuses the record with the fix
    code, out, err = _cli(["lsq", str(path)])
    assert code == 2 and out == "" and len(err) == 1, err
    assert err[0] == (f"bayesmodal lsq: error: {path}: before the first input the carts "
                      f"rest with output 1 at {1e3 * OFFSET_M[0]:.3g} mm, not at 0 where "
                      "the model starts; an encoder not zeroed at rest: remove each "
                      "output's rest level with --rest-offset initial")


def test_no_rest_before_the_input_is_refused(tmp_path):
    path, v, y = _record(tmp_path, start_s=0.02)           # the input at sample 5
    with pytest.raises(DataError, match=r"offset.csv: the input starts at sample 5; "
                       r"--rest-offset initial needs at least 10 samples at rest"):
        load_experiment(path, options=ReadOptions(rest_offset="initial"))
    with pytest.raises(DataError, match="the input is all zeros, so there is no rest"):
        initial_rest("rec", 0 * v, y)
    drifting = y + np.linspace(0, 50 * M_PER_COUNT, N)[:, None]
    with pytest.raises(DataError, match=r"rec: output 1 still moves before the first input"):
        initial_rest("rec", np.r_[np.zeros(100), v[100:]], drifting)
    with pytest.raises(ConfigError, match=r"rest_offset must be one of \('none', 'initial', "
                       r"'final'\)"):
        ReadOptions(rest_offset="first")


def test_an_offset_at_rest_is_told_from_carts_that_move():
    from bayesmodal._window import offset_at_rest

    t = np.arange(N) * DT
    v = 0.5 * (t >= 0.5)
    model = LinearModel(Rig(), "free")
    y = simulate_linear(model, THETA, v, DT)
    noise = NOISE_M * np.random.default_rng(9).standard_normal(y.shape)
    assert offset_at_rest(y + noise, v) == ""                       # at rest at 0
    assert offset_at_rest(y + noise + OFFSET_M, v) == "output 1 at 0.163 mm"
    counts = np.round((y + OFFSET_M) / M_PER_COUNT) * M_PER_COUNT   # whole counts
    assert offset_at_rest(counts, v) == "output 1 at 0.163 mm"
    assert offset_at_rest(np.round(y / M_PER_COUNT) * M_PER_COUNT, v) == ""
    # a bias of the drive pushes the carts from 0 before the input: they move, and that
    # is no offset of the sensors (negative control)
    biased = simulate_linear(model, THETA, v + 0.1, DT)
    assert np.max(np.abs(biased[:100, 0])) > 10 * np.abs(OFFSET_M[0])
    assert offset_at_rest(biased + noise, v) == ""
    # an input from the first samples: no rest to judge
    assert offset_at_rest(y + OFFSET_M, np.r_[0.0, np.ones(N - 1)]) == ""
