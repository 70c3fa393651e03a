"""A time window of a record (``ReadOptions(t_start, t_end)``, ``--t-start``, ``--t-end``).

The kept samples keep their recorded times; a window that does not start at rest is
refused by a fit from rest and fitted with its initial state estimated.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from bayesmodal import ConfigError, DataError
from bayesmodal._window import motion_at_start
from bayesmodal.cli import main
from bayesmodal.data import Experiment, load_experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import ReadOptions

THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
DT = 0.01
N = 1200
SIGMA_M = 2e-5
K_SE = 4.0


def _record(tmp_path, seed=7):
    t = np.arange(N) * DT
    v = 0.5 * (((t - 1.0) % 4.0) < 2.0) * (t >= 1.0)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, DT)
    y = y + SIGMA_M * np.random.default_rng(seed).standard_normal(y.shape)
    path = tmp_path / "rec.csv"
    save_csv(Experiment(t, v, y, name="rec"), path)
    return path, t, v, y


def _cli(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def test_the_window_keeps_its_samples_with_their_times(tmp_path):
    path, t, v, y = _record(tmp_path)
    e = load_experiment(path, options=ReadOptions(t_start=2.5, t_end=7.0))
    keep = (t >= 2.5 - 1e-9) & (t <= 7.0 + 1e-9)
    assert e.n_samples == keep.sum() == 451
    np.testing.assert_allclose(e.t_s, t[keep], rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.y_m, y[keep], rtol=1e-15, atol=0)
    assert e.name == "rec"
    # one bound only
    assert load_experiment(path, options=ReadOptions(t_end=0.5)).n_samples == 51


@pytest.mark.parametrize(("window", "message"), [
    ({"t_start": 30.0}, r"rec.csv: t_start = 30 s is outside the record; the record spans "
                        r"0 to 11.99 s \(step 0.01 s\)$"),
    ({"t_start": -1.0, "t_end": 2.0}, r"t_start = -1 s is outside the record"),
    ({"t_start": 5.001, "t_end": 5.019}, r"the window 5.001 to 5.019 s holds 1 sample\(s\), "
                                         r"fewer than 3; the record spans 0 to 11.99 s"),
    ({"t_start": 11.994}, r"the window 11.994 to 11.99 s is empty"),
])
def test_a_window_outside_or_empty_names_the_span(tmp_path, window, message):
    path, *_ = _record(tmp_path)
    with pytest.raises(DataError, match=message):
        load_experiment(path, options=ReadOptions(**window))


def test_t_end_before_t_start_is_refused():
    with pytest.raises(ConfigError, match=r"t_end \(1 s\) must be after t_start \(2 s\)"):
        ReadOptions(t_start=2, t_end=1)
    with pytest.raises(ConfigError, match="t_start must be a finite time in s"):
        ReadOptions(t_start=float("nan"))


def test_rest_is_told_from_motion():
    t = np.arange(500) * DT
    rng = np.random.default_rng(3)
    y = 5e-3 * np.sin(8 * t)[:, None] * [1, 0.5] + SIGMA_M * rng.standard_normal((500, 2))
    v = np.zeros(500)
    assert motion_at_start(np.where(t[:, None] < 1, SIGMA_M * rng.standard_normal((500, 2)),
                                    y), v, DT) == ""
    assert motion_at_start(y[100:], v[100:], DT).startswith("output 1 at ")
    assert motion_at_start(y * 0, v + 0.5, DT) == "the input at 0.5 V"


def test_lsq_of_a_window_in_motion_estimates_its_initial_state(tmp_path):
    path, *_ = _record(tmp_path)
    # at 4 s the input has just dropped and the carts swing: not at rest
    code, out, err = _cli("lsq", str(path), "--t-start", "4.5", "--json")
    assert code == 2 and out == ""
    assert err.strip().endswith("rec.csv: the window starts at t = 4.5 s with output 1 at "
                                + err.split("output 1 at ")[1].split(",")[0]
                                + ", not at rest; fit it with --initial-state estimate, or "
                                "start the window where the carts rest at 0 with no input")
    code, out, err = _cli("lsq", str(path), "--t-start", "4.5", "--t-end", "11.5",
                          "--initial-state", "estimate", "--json")
    assert code == 0, err
    js = json.loads(out)
    assert js["identified"] is True
    theta = np.array(list(js["parameters"].values()))
    se = np.array(list(js["stderr"].values()))
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se


def test_a_window_that_starts_at_rest_is_fitted_from_rest(tmp_path):
    path, *_ = _record(tmp_path)
    code, out, err = _cli("lsq", str(path), "--t-start", "0.5", "--t-end", "9", "--json")
    assert code == 0, err
    js = json.loads(out)
    theta = np.array(list(js["parameters"].values()))
    se = np.array(list(js["stderr"].values()))
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se


def test_the_run_config_reads_the_window(tmp_path):
    from bayesmodal.runs.config import load_config

    path, *_ = _record(tmp_path)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(f'[data]\nfiles = ["{path}"]\nt_start = 0.5\nt_end = 9\n')
    opts = load_config(cfg).data.read_options()
    assert (opts.t_start, opts.t_end) == (0.5, 9.0)
    cfg.write_text(f'[data]\nfiles = ["{path}"]\nt_start = 9\nt_end = 0.5\n')
    with pytest.raises(ConfigError, match=r"data.t_start.*t_end \(0.5 s\) must be after "
                       r"t_start \(9 s\)"):
        load_config(cfg)
