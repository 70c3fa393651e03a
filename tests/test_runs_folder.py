"""Run-folder mechanics: atomic writes, the lock, status, the atomic emcee checkpoint."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import emcee
import numpy as np
import pytest

from bayesmodal import ConfigError
from bayesmodal.runs import AtomicCheckpoint, RunFolder, RunLockedError, checkpoint_iteration
from bayesmodal.runs.crosscheck import sample_acf
from bayesmodal.runs.folder import atomic_write_json, atomic_write_text
from bayesmodal.runs.runner import one_line, parse_moves


def test_atomic_write_replaces_whole_file_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "a.json"
    atomic_write_json(p, {"x": 1.0, "nan": float("nan"), "arr": np.arange(3)})
    assert json.loads(p.read_text()) == {"x": 1.0, "nan": None, "arr": [0, 1, 2]}
    atomic_write_text(p, "{}")
    assert p.read_text() == "{}"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json"]


def test_status_round_trip_and_validation(tmp_path):
    f = RunFolder(tmp_path / "run")
    assert f.status() is None
    with f.lock():
        st = f.write_status("running", config_hash="abc", steps=10)
        assert st["state"] == "running" and st["pid"] == os.getpid()
        f.write_status("failed", error="boom")
        assert f.status()["error"] == "boom"
        f.write_status("finished")
    st = f.status()
    assert st["state"] == "finished" and "error" not in st and st["config_hash"] == "abc"
    with pytest.raises(ValueError, match="state must be one of"):
        f.write_status("paused")
    (f.path / "status.json").write_text('{"state": "weird"}')
    with pytest.raises(ConfigError, match="not a run status"):
        f.status()


def test_lock_refuses_a_second_writer_and_is_released(tmp_path):
    f = RunFolder(tmp_path / "run")
    with f.lock():
        holder = json.loads(f.lock_path.read_text())
        assert holder["pid"] == os.getpid()
        with pytest.raises(RunLockedError, match=f"process {os.getpid()}"):
            with RunFolder(tmp_path / "run").lock():
                pass
    assert not f.lock_path.exists()


def test_stale_lock_of_a_dead_process_is_taken_over(tmp_path):
    # a lock left by a process that no longer exists (as after SIGKILL)
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = int(proc.stdout)
    f = RunFolder(tmp_path / "run")
    f.path.mkdir()
    import socket

    f.lock_path.write_text(json.dumps({"pid": dead, "host": socket.gethostname()}))
    with f.lock():
        assert json.loads(f.lock_path.read_text())["pid"] == os.getpid()
    # a lock of another host is never assumed stale
    f.lock_path.write_text(json.dumps({"pid": dead, "host": "elsewhere.invalid"}))
    with pytest.raises(RunLockedError, match="elsewhere.invalid"):
        with f.lock():
            pass


def test_clear_removes_only_run_files(tmp_path):
    f = RunFolder(tmp_path)
    for name in ("summary.json", "chain.h5", "trace.png", "x.tmp", "bode.tmp.png", "notes.txt"):
        (tmp_path / name).write_text("x")
    f.clear()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def _log_prob(x):
    # a correlated 2-D Gaussian and a blob, as the rig posterior returns (log p, log L)
    icov = np.array([[2.0, -1.2], [-1.2, 1.5]])
    lp = -0.5 * float(x @ icov @ x)
    return lp, lp + 1.0


def test_checkpoint_resume_gives_the_uninterrupted_chain(tmp_path):
    rng = np.random.default_rng(3)
    p0 = rng.normal(size=(8, 2))
    state = emcee.State(p0, random_state=np.random.RandomState(5).get_state())
    ref = emcee.backends.Backend()
    emcee.EnsembleSampler(8, 2, _log_prob, backend=ref).run_mcmc(state, 60)

    path = tmp_path / "chain.h5"
    be = AtomicCheckpoint(path, every_s=1e9)  # writes only at the end of run_mcmc
    state = emcee.State(p0, random_state=np.random.RandomState(5).get_state())
    emcee.EnsembleSampler(8, 2, _log_prob, backend=be).run_mcmc(state, 25)
    assert be.n_writes == 1 and checkpoint_iteration(path) == 25
    # a new process would see only the file: reload it and continue
    be2 = AtomicCheckpoint(path)
    assert be2.iteration == 25
    s2 = emcee.EnsembleSampler(8, 2, _log_prob, backend=be2)
    s2.run_mcmc(None, 35)
    assert np.array_equal(be2.get_chain(), ref.get_chain())
    assert np.array_equal(be2.get_log_prob(), ref.get_log_prob())
    assert np.array_equal(be2.get_blobs(), ref.get_blobs())
    assert np.array_equal(be2.accepted, ref.accepted)
    # the file has emcee's own HDF layout
    hdf = emcee.backends.HDFBackend(str(path), read_only=True)
    assert hdf.iteration == 60
    assert np.array_equal(hdf.get_chain(), ref.get_chain())
    # negative control: a different generator state gives a different chain
    other = emcee.backends.Backend()
    state = emcee.State(p0, random_state=np.random.RandomState(6).get_state())
    emcee.EnsembleSampler(8, 2, _log_prob, backend=other).run_mcmc(state, 60)
    assert not np.array_equal(other.get_chain(), ref.get_chain())


def test_checkpoint_keeps_tags_and_writes_on_interval(tmp_path):
    path = tmp_path / "chain.h5"
    be = AtomicCheckpoint(path, every_s=0.0)  # every step
    be.reset(4, 2)
    be._bayesmodal_bayesmodal_config_hash = "abc123"
    s = emcee.EnsembleSampler(4, 2, _log_prob, backend=be)
    s.run_mcmc(np.random.default_rng(1).normal(size=(4, 2)), 5)
    assert be.n_writes == 5
    again = AtomicCheckpoint(path)
    assert again._bayesmodal_bayesmodal_config_hash == "abc123"
    assert checkpoint_iteration(tmp_path / "absent.h5") == 0


def test_sample_acf_of_ar1_and_white_noise():
    rng = np.random.default_rng(0)
    n, phi = 20000, 0.8
    e = rng.normal(size=(n, 2))
    x = np.empty_like(e)
    x[0] = e[0]
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    acf = sample_acf(x, 5)
    # AR(1): rho_k = phi^k; the standard error of a sample ACF is about 1/sqrt(n) * sqrt(
    # (1 + phi^2) / (1 - phi^2)) (Bartlett), about 0.015 here
    se = np.sqrt((1 + phi**2) / (1 - phi**2) / n)
    lags = np.arange(1, 6)[:, None]
    assert np.all(np.abs(acf[1:] - phi**lags) < 5 * se * lags)
    white = sample_acf(e, 5)
    assert np.all(np.abs(white[1:]) < 4 / np.sqrt(n))
    assert np.allclose(acf[0], 1.0)


def test_parse_moves_and_one_line():
    mv = parse_moves("de:0.8, de-snooker:0.2")
    assert [type(m).__name__ for m, _ in mv] == ["DEMove", "SnookerMove"]
    assert [w for _, w in mv] == [0.8, 0.2]
    assert type(parse_moves("stretch")[0][0]).__name__ == "StretchMove"
    with pytest.raises(ConfigError, match=r"\[sampler.moves\]"):
        parse_moves("gibbs")
    exc = ConfigError("2 problem(s) in the configuration:\na.toml: [x] bad\na.toml: [y] worse")
    assert one_line(exc) == "a.toml: [x] bad; a.toml: [y] worse"
