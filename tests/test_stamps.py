"""Records on a logger's jittered, millisecond-rounded stamps: simulated exactly on them.

A microcontroller logger's loop runs at about 1.127 ms with jitter and stamps its samples
to whole milliseconds; the input is held between samples, so the linear model is
simulated exactly on the recorded stamps, each step with its own zero-order hold
(``simulate.py``).  Checked against a fine integration of the same held input, against
the uniform simulator on uniform stamps, by recovering a known truth from a logger-like
file with one ``bayesmodal lsq`` command line (and doing measurably worse when the same
file is forced onto a uniform grid), and by refusing stamps that go backwards or stall.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import scipy.io
from scipy.integrate import solve_ivp

from bayesmodal.cli import main
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, load_experiment
from bayesmodal.model.simulate import LinearSimulator, simulate_linear, step_groups
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import ReadOptions

MODEL = LinearModel(Rig(), "proportional")
TRUTH = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])  # g_v, m1..m3, ca, cb
LOOP_MS = 1.127  # the logger's mean loop period, ms
UNITS_PER_V = 4096 / 5  # a 12-bit converter over 5 V


def logger_stamps(n: int, rng) -> np.ndarray:
    """Stamps of a loop paced at ``LOOP_MS`` with up to 0.12 ms of latency, rounded to
    whole ms (strictly increasing: the steps stay above 1 ms), s."""
    k = np.arange(n)
    return np.round(k * LOOP_MS + rng.uniform(0.0, 0.12, n)) / 1000.0


def drive(t: np.ndarray) -> np.ndarray:
    """Pulses and steps in whole converter units, units."""
    return np.round(UNITS_PER_V * (0.6 * ((t % 4.0) > 0.5) * ((t % 4.0) < 2.0)
                                   - 0.4 * ((t % 4.0) > 3.0)))


def state_space(theta):
    M, C, K, b = MODEL.matrices(np.atleast_2d(theta))
    n = M.shape[1]
    Mi = np.linalg.inv(M[0])
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Mi @ K[0]
    A[n:, n:] = -Mi @ C[0]
    return A, np.r_[np.zeros(n), Mi @ b[0]]


def test_jittered_stamps_match_a_fine_integration_of_the_held_input():
    rng = np.random.default_rng(20)
    t = logger_stamps(600, rng)
    v = drive(t) / UNITS_PER_V
    assert step_groups(np.diff(t))[0].size >= 2  # several distinct steps
    y = simulate_linear(MODEL, TRUTH, v, np.diff(t))
    A, B = state_space(TRUTH)
    rtol, atol = 1e-11, 1e-15
    x = np.zeros(A.shape[0])
    ref = np.zeros_like(y)
    for k in range(t.size):
        ref[k] = x[: y.shape[1]]
        if k + 1 < t.size:  # the input held over [t_k, t_k+1]
            sol = solve_ivp(lambda _, z, u=v[k]: A @ z + B * u, (t[k], t[k + 1]), x,
                            method="DOP853", rtol=rtol, atol=atol)
            x = sol.y[:, -1]
    # each interval's local error is within rtol |x| + atol; over the record they add up
    # at most linearly
    tol = t.size * (rtol * np.abs(ref).max() + atol)
    assert np.abs(y - ref).max() <= tol
    assert np.abs(ref).max() > 1e3 * tol  # the comparison is not vacuous


def test_uniform_steps_are_the_uniform_simulator_bit_for_bit():
    n, dt = 800, 0.005
    v = drive(np.arange(n) * dt) / UNITS_PER_V
    M, C, K, b = MODEL.matrices(np.vstack([TRUTH, TRUTH * 1.01]))
    masses = np.diagonal(M, axis1=1, axis2=2)
    uniform = LinearSimulator(v, dt, 3).run_second_order(masses, C, K, b).copy()
    steps = LinearSimulator(v, np.full(n - 1, dt), 3).run_second_order(masses, C, K, b)
    assert np.array_equal(uniform, steps)
    # a uniform record marked as recorded stamps takes the uniform path
    t = np.arange(n) * dt
    e = Experiment(t, v, uniform[0], recorded_stamps=True)
    assert e.is_uniform and e.sim_dt == e.dt


def test_direct_recursion_on_steps_matches_the_modal_one():
    rng = np.random.default_rng(21)
    t = logger_stamps(400, rng)
    v = drive(t) / UNITS_PER_V
    A, B = state_space(TRUTH)
    sim = LinearSimulator(v, np.diff(t), 3)
    modal = sim.run(A[None], B[None]).copy()
    # an odd state size has no modal form: the full-state recursion with expm per step
    A7 = np.zeros((7, 7))
    A7[:6, :6] = A
    A7[6, 6] = -1.0
    direct = sim.run(A7[None], np.r_[B, 0.0][None])
    eps = np.finfo(float).eps
    assert np.abs(direct - modal).max() <= 1e3 * t.size * eps * np.abs(modal).max()


def write_logger_file(path, rng, n: int = 8000) -> np.ndarray:
    """A logger's ``.mat``: ``time`` in ms, ``enc1..3`` in counts, ``target_v`` in converter
    units, simulated on the stamps from ``TRUTH``; returns the stamps, s."""
    t = logger_stamps(n, rng)
    units = drive(t)
    y = simulate_linear(MODEL, TRUTH, units / UNITS_PER_V, np.diff(t))
    counts = np.round(y / ECP_M_PER_COUNT + rng.normal(0.0, 0.5, y.shape))
    scipy.io.savemat(path, {"time": 1000 * t, "target_v": units, "enc1": counts[:, 0],
                            "enc2": counts[:, 1], "enc3": counts[:, 2],
                            "run": {"operator": "lab"}})
    return t


LOGGER_ARGS = ["--columns", "t=time,v=target_v,x1=enc1,x2=enc2,x3=enc3",
               "--input-scale", "5/4096", "--time-scale", "1/1000",
               "--damping", "proportional", "--json"]


def run_cli(argv):
    """``bayesmodal ARGV`` with its warnings shown as lines on stderr."""
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        return main(argv)


def lsq_json(argv, capsys):
    import json

    code = run_cli(["lsq", *argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out), err


def test_logger_file_is_fitted_on_its_stamps_and_worse_on_a_forced_grid(tmp_path, capsys):
    rng = np.random.default_rng(38)
    path = tmp_path / "logger.mat"
    write_logger_file(path, rng)
    with pytest.warns(UserWarning, match="kept as recorded"):
        e = load_experiment(path, options=ReadOptions(
            columns={"t": "time", "v": "target_v", "x1": "enc1", "x2": "enc2",
                     "x3": "enc3"}, input_scale=5 / 4096, time_scale=1e-3))
    assert e.recorded_stamps and not e.is_uniform
    res, err = lsq_json([str(path), *LOGGER_ARGS], capsys)
    assert "kept as recorded" in err and res["identified"]
    est = np.array([res["parameters"][k] for k in MODEL.names])
    se = np.array([res["stderr"][k] for k in MODEL.names])
    assert np.all(np.abs(est - TRUTH) <= 4 * se), (est - TRUTH) / se
    # negative control: the same file on its least-squares uniform grid
    grid, err = lsq_json([str(path), *LOGGER_ARGS, "--time-base", "grid"], capsys)
    assert "kept as recorded" not in err and "uniform grid" in err
    est_g = np.array([grid["parameters"][k] for k in MODEL.names])
    se_g = np.array([grid["stderr"][k] for k in MODEL.names])
    # residuals well above the stamps' fit, and the truth far outside its errors
    assert min(grid["sigma_m"]) > 3 * max(res["sigma_m"])
    assert np.max(np.abs(est_g - TRUTH) / se_g) > 10


def csv_record(path, t):
    v = 0.5 * (np.arange(t.size) > t.size // 4)
    rows = ["t,v,x1,x2,x3"] + [f"{float(a)!r},{float(b)!r}" + f",{1e-4 * float(b)!r}" * 3
                                for a, b in zip(t, v, strict=True)]
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("case, message", [
    ("backwards", "time is not strictly increasing at sample 301 .*; sort the rows by "
                  "time and drop repeated samples"),
    ("gap", r"time jumps by 0.03\d* s after t = 0.3\d* s, \d+ times the median step of "
            r"0.001 s: samples are missing; cut the record at the gap"),
])
def test_backwards_stamps_and_gaps_are_refused_with_one_line(tmp_path, capsys, case, message):
    rng = np.random.default_rng(5)
    t = logger_stamps(600, rng)
    if case == "backwards":
        t[301] = t[299]
    else:
        t[300:] += 0.03
    path = tmp_path / f"{case}.csv"
    csv_record(path, t)
    code = run_cli(["lsq", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert re.search(message, err), err


@pytest.mark.parametrize("command", ["ema", pytest.param("diagnose", marks=pytest.mark.slow),
                                     pytest.param("sample", marks=pytest.mark.slow)])
def test_analyses_that_need_a_grid_refuse_stamps_with_the_fix(tmp_path, capsys, command):
    rng = np.random.default_rng(6)
    t = logger_stamps(3000, rng)
    path = tmp_path / "stamps.csv"
    csv_record(path, t)
    code = run_cli([command, str(path)])
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ": error: " in ln]
    assert code == 2 and len(lines) == 1
    assert "time steps are not equally spaced" in lines[0]
    assert "--time-base grid" in lines[0]
