"""Kill ``bayesmodal run`` with SIGKILL half-way, resume it, get the uninterrupted chain.

While the run is killed, every file in its folder must be complete (JSON loads, NetCDF
and HDF5 open); only temporary files of an unfinished atomic write (``*.tmp``) may be
partial, and the resumed run removes them.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from bayesmodal.data import Experiment, save_csv
from bayesmodal.inference import load_idata, simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs import RunLockedError, checkpoint_iteration, prepare_run, run_config
from bayesmodal.runs.config import load_config
from bayesmodal.runs.runner import execute_run

STEPS = 3000

CONFIG = f"""\
[data]
files = ["rec.csv"]

[model]
damping = "free"

[sampler]
walkers = 30
steps = {STEPS}
burn = 1000
thin = 20
seed = 11
moves = "de:0.8,de-snooker:0.2"

[outputs]
plots = false
report = false
ema = false
predictive_draws = 20
checkpoint_every_s = 0.2
chain = "full"   # whole float64 chains compared bit for bit (not compacted at the end)
"""


@pytest.fixture
def config(tmp_path):
    n, dt = 500, 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0]
    y = simulate_linear(LinearModel(Rig(), "free"), theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=5)[0]
    save_csv(Experiment(t, v, y, name="rec"), tmp_path / "rec.csv")
    p = tmp_path / "cfg.toml"
    p.write_text(CONFIG)
    return p


def _check_files_complete(folder) -> list[str]:
    """Open every file; return the names of temporaries (allowed to be partial)."""
    temporaries = []
    for p in sorted(folder.iterdir()):
        if p.name.endswith(".tmp") or ".tmp." in p.name:
            temporaries.append(p.name)
        elif p.suffix == ".json" or p.name == "run.lock":
            json.loads(p.read_text())
        elif p.suffix == ".nc":
            load_idata(p)
        elif p.suffix == ".h5":
            with h5py.File(p, "r") as f:
                g = f["mcmc"]
                it = int(g.attrs["iteration"])
                assert g["chain"].shape[0] == it and np.all(np.isfinite(g["chain"][:it]))
        elif p.suffix in (".toml", ".log", ".md"):
            p.read_text()
        else:
            raise AssertionError(f"unexpected file {p.name}")
    return temporaries


def _run_cmd(config, out, *extra):
    return [sys.executable, "-m", "bayesmodal", "run", str(config), "--out", str(out),
            "--quiet", *extra]


def test_sigkill_then_resume_gives_the_uninterrupted_chain(config, tmp_path):
    killed = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(_run_cmd(config, killed), env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 240
        done = 0
        while time.monotonic() < deadline and proc.poll() is None:
            done = checkpoint_iteration(killed / "chain.h5")
            if done >= STEPS // 5:
                break
            time.sleep(0.05)
        assert proc.poll() is None, f"run ended before it could be killed: {proc.stderr.read()}"
        # a second writer is refused while the first one lives
        with pytest.raises(RunLockedError, match=f"process {proc.pid}"):
            execute_run(prepare_run(load_config(config)), killed, resume=True)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=60)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    at_kill = checkpoint_iteration(killed / "chain.h5")
    assert STEPS // 5 <= at_kill < STEPS  # really half-way
    assert json.loads((killed / "status.json").read_text())["state"] == "running"
    _check_files_complete(killed)

    # without --resume the interrupted run is left alone, with a clear message
    again = subprocess.run(_run_cmd(config, killed), capture_output=True, text=True,
                           timeout=240)
    assert again.returncode == 2 and "use --resume" in again.stderr
    resumed = subprocess.run(_run_cmd(config, killed, "--resume"), capture_output=True,
                             text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    assert _check_files_complete(killed) == []
    s = json.loads((killed / "summary.json").read_text())
    timing = json.loads((killed / "timing.json").read_text())
    assert timing["action"] == "resume"
    assert timing["steps_in_checkpoint_at_start"] == at_kill

    # the same configuration, never interrupted (in this process)
    whole = run_config(config, tmp_path / "whole")
    assert whole.action == "fresh"
    with h5py.File(killed / "chain.h5", "r") as a, h5py.File(tmp_path / "whole" / "chain.h5",
                                                             "r") as b:
        for key in ("chain", "log_prob", "blobs", "accepted"):
            assert np.array_equal(a["mcmc"][key][:], b["mcmc"][key][:]), key
        assert a["mcmc"].attrs["iteration"] == STEPS
    pa = load_idata(killed / "posterior.nc").posterior
    pb = load_idata(tmp_path / "whole" / "posterior.nc").posterior
    for nm in pa.data_vars:
        assert np.array_equal(pa[nm].values, pb[nm].values), nm
    assert s["parameters"] == whole.summary["parameters"]
    # and summary.json as a whole: timings live in timing.json
    assert (killed / "summary.json").read_bytes() == (tmp_path / "whole" / "summary.json"
                                                      ).read_bytes()
