"""``bayesmodal inspect``: what the reader sees in a file, and the command that fits it."""

from __future__ import annotations

import json
import shlex
import warnings

import numpy as np
import pytest
import scipy.io

from bayesmodal.cli import main
from bayesmodal.data import ECP_M_PER_COUNT, find_data
from bayesmodal.inspection import input_events, inspect_file
from bayesmodal.reading import ReadOptions

UNITS_PER_V = 4096 / 5


def run_cli(argv):
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        return main(argv)


def logger_file(path, rng, *, reversed_drive=False):
    """A logger's ``.mat``: ms stamps jittered and rounded, counts, converter units."""
    n = 6000
    k = np.arange(n)
    t = np.round(k * 1.127 + rng.uniform(0.0, 0.12, n))  # ms
    volts = 0.5 * ((t > 1000) & (t < 3500))
    # a slow first-order response to the input, in counts, plus a rest offset
    y = np.zeros(n)
    for i in range(1, n):
        y[i] = y[i - 1] + (t[i] - t[i - 1]) / 300 * (2000 * volts[i - 1] - y[i - 1])
    counts = np.round(y * (-1 if reversed_drive else 1) + 40 + rng.normal(0, 0.5, n))
    scipy.io.savemat(path, {"time": t, "target_v": np.round(volts * UNITS_PER_V),
                            "enc1": counts, "enc2": counts / 2, "run": {"rate": 887}})
    return t / 1000


OPTS = ReadOptions(columns={"t": "time", "v": "target_v", "x1": "enc1", "x2": "enc2"},
                   input_scale=5 / 4096, time_scale=1e-3)
ARGS = ["--columns", "t=time,v=target_v,x1=enc1,x2=enc2", "--input-scale", "5/4096",
        "--time-scale", "1/1000"]


def test_input_events_find_steps_beyond_the_noise():
    rng = np.random.default_rng(3)
    t = np.arange(2000) * 0.005
    v = 0.5 * ((t > 2) & (t < 6)) + rng.normal(0, 0.002, t.size)
    ev = input_events(t, v)
    assert [round(e.t_s, 3) for e in ev] == [2.005, 6.0]
    assert ev[0].to_v == pytest.approx(0.5, abs=0.01) and ev[1].to_v == pytest.approx(0, abs=0.01)
    assert input_events(t, np.zeros_like(t)) == ()


def test_inspect_a_logger_file(tmp_path):
    rng = np.random.default_rng(11)
    path = tmp_path / "rec.mat"
    t = logger_file(path, rng)
    r = inspect_file(path, OPTS)
    assert r.format == "mat" and r.n_samples == t.size
    assert dict(r.columns)["x2"] == "enc2"
    assert r.input_v_per_unit == 5 / 4096 and r.output_m_per_unit == ECP_M_PER_COUNT
    assert r.time_base == "stamps"
    assert (r.step_min_s, r.step_median_s, r.step_max_s) == pytest.approx((1e-3, 1e-3, 2e-3))
    assert r.duration_s == pytest.approx(t[-1] - t[0])
    assert [round(e.t_s, 2) for e in r.events] == [1.0, 3.5]
    assert r.drive_correlation is not None and not r.drive_reversed
    # rest: 40 counts before the first step, back near 40 at the end (time constant 0.3 s)
    assert np.allclose(r.rest_before_m, [40 * ECP_M_PER_COUNT, 20 * ECP_M_PER_COUNT],
                       atol=ECP_M_PER_COUNT)
    assert any("kept as recorded" in w for w in r.warnings)
    # the fit command reads the file as inspect did, less the rest level of 40 counts
    # before the input (an offset lsq refuses without --rest-offset initial)
    argv = shlex.split(r.fit_command)
    assert argv[:3] == ["bayesmodal", "lsq", str(path)]
    assert argv[3:] == [*ARGS, "--rest-offset", "initial"]


def test_the_fit_command_removes_an_offset_at_rest_and_runs(tmp_path):
    from conftest import run_cli

    from bayesmodal.data import Experiment, save_csv
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig

    t = np.arange(1200) * 0.005
    v = 0.5 * (((t - 0.5) % 4.0) < 2.0) * (t >= 0.5)
    y = simulate_linear(LinearModel(Rig(), "proportional"), [6.2, 1.5, 1.4, 1.1, 1.5, 1e-4],
                        v, 0.005)
    path = tmp_path / "offset.csv"
    save_csv(Experiment(t, v, y + [2e-4, -1e-4, 5e-5]), path)
    r = inspect_file(path, ReadOptions(t_start=0.0))
    argv = shlex.split(r.fit_command)
    assert argv[3:] == ["--t-start", "0.0", "--rest-offset", "initial"]
    code, _, err = run_cli([*argv[1:], "--damping", "proportional"])
    assert code == 0 and err == [], err
    # negative control: the record at rest at 0 needs no option
    save_csv(Experiment(t, v, y), path)
    assert inspect_file(path).fit_command == f"bayesmodal lsq {shlex.quote(str(path))}"


def test_inspect_names_a_reversed_drive_in_the_fit_command(tmp_path):
    path = tmp_path / "rev.mat"
    logger_file(path, np.random.default_rng(12), reversed_drive=True)
    r = inspect_file(path, OPTS)
    assert r.drive_reversed
    assert "--input-scale -5/4096" in r.fit_command


def test_inspect_cli_text_and_json(tmp_path, capsys):
    path = tmp_path / "rec.mat"
    logger_file(path, np.random.default_rng(13))
    assert run_cli(["inspect", str(path), *ARGS]) == 0
    out, err = capsys.readouterr()
    assert "time base: stamps" in out and "input events: 2" in out
    assert f"fit it with: bayesmodal lsq {path}" in out
    assert "reader warning: " in out and "kept as recorded" in out
    assert err == ""
    assert run_cli(["inspect", str(path), *ARGS, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["time_base"] == "stamps" and len(d["events"]) == 2
    assert set(d["events"][0]) == {"t_s", "from_v", "to_v"}


@pytest.mark.parametrize("text, message", [
    ("t,v,x1\n0,0,0\n0.2,0,0\n0.1,0,0\n", "not strictly increasing"),
    ("t,x1\n0,0\n0.1,0\n0.2,0\n", r"missing column\(s\) \['v'\]"),
])
def test_inspect_bad_files_give_the_readers_one_line(tmp_path, capsys, text, message):
    import re

    path = tmp_path / "bad.csv"
    path.write_text(text)
    assert run_cli(["inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and re.search(message, err)


@pytest.mark.parametrize("name", ["data_steps.mat", "data_impulses.txt"])
def test_inspect_measured_records(name):
    p = find_data(f"ecp210-3dof/{name}")
    if p is None:
        pytest.skip("measured data not available")
    r = inspect_file(p)
    assert r.time_base == "uniform" and r.n_samples > 1000
    assert len(r.events) >= 2 and not r.drive_reversed
    assert r.fit_command == f"bayesmodal lsq {shlex.quote(str(p))}"
