"""A closed-loop record: a PID controller's control effort as the recorded input.

The record is written by ``tests/closed_loop_writer.py`` (its own simulation of the loop,
independent of the package) as the ECP Executive exports it.  The effort is the voltage
that drove the carts, held over each sample, so the open-loop model simulated on it is
the carts' motion; the controller feeds the encoders' noise back into the effort, but the
response at sample ``k`` depends on the effort up to ``k - 1`` only, which depends on the
noise up to ``k - 1``: white measurement noise stays uncorrelated with the gradient of the
prediction, and the output-error fit is consistent.  So ``bayesmodal lsq FILE`` fits it
with no option and recovers the truth within its own standard errors; read with the
commanded position as its input (the reference, not what drove the carts) it must never
exit 0.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from closed_loop_writer import THETA, closed_loop, write_closed_loop
from conftest import run_cli as _cli

#: standard errors within which the estimates must fall
K_SE = 4.0


def test_the_loop_is_closed():
    # the writer's effort follows the error to the commanded position: a step of the
    # reference moves cart 1 most of the way there within 2 s, and the encoders' noise
    # reaches the effort
    v, y, r = closed_loop(1200, seed=11)
    k = np.arange(1200) * 0.008854
    settled = (k > 1.5) & (k < 2.0)          # the end of the first step
    assert abs(np.mean(y[settled, 0]) - r[settled][0]) < 0.1 * r[settled][0]
    quiet = closed_loop(1200, seed=11, noise_counts=0.0)[0]
    assert np.std(v[:20] - quiet[:20]) > 0   # noise fed back into the effort


def test_lsq_fits_a_closed_loop_export_with_one_command_line(tmp_path):
    path = write_closed_loop(tmp_path / "pid.txt")
    code, out, err = _cli(["lsq", str(path), "--json"])
    assert code == 0, err
    assert len(err) == 1 and "ECP Executive export" in err[0]   # the rounded times only
    js = json.loads(out)
    assert js["identified"] is True
    names = list(js["parameters"])
    theta = np.array([js["parameters"][n] for n in names])
    se = np.array([js["stderr"][n] for n in names])
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se


@pytest.mark.slow  # the optimiser spends its 400 evaluations (3 to 35 s by the load);
# the default suite's guard is the closed_loop_reference case of tests/test_bad_inputs.py
def test_the_commanded_position_as_input_never_exits_0(tmp_path):
    # the reference is not what drove the carts: the fit cannot explain the record with
    # it and must say so (the record gave c1 = 1.9e19 +- nan with exit 0); 400
    # samples: the optimiser spends its 400 evaluations either way
    path = write_closed_loop(tmp_path / "pid.txt", 400)
    columns = ("t=Time,v=Commanded Pos,x1=Encoder 1 Pos,x2=Encoder 2 Pos,"
               "x3=Encoder 3 Pos")
    code, out, err = _cli(["lsq", str(path), "--columns", columns, "--input-scale",
                           "1/800", "--json"])
    assert code == 2, err
    js = json.loads(out)                       # --json still prints the whole result
    assert js["identified"] is False
    se = np.array([np.nan if s is None else s for s in js["stderr"].values()])
    theta = np.array(list(js["parameters"].values()))
    assert not np.all(np.isfinite(se)) or np.any(se >= np.abs(theta))
    assert err[-1].startswith(f"bayesmodal lsq: error: {path}: not identified: ")
    assert "Control Effort" in err[-1]
