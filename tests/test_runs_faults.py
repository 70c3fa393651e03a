"""Faults during a run: SIGKILL at random moments, a full disk, an unwritable folder, and
two runs writing one folder at once.

After any of them every file in the run folder is complete (only ``*.tmp`` temporaries
of an interrupted atomic write may be partial), and ``--resume`` (or ``--force``) ends
with exactly the ``summary.json`` of an uninterrupted run.  Kill moments are drawn from a
fixed-seed ``numpy.random.Generator`` over the whole run, start-up and report included;
the default suite kills at one moment, ``-m slow`` at five more.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from bayesmodal.cli import main
from bayesmodal.data import Experiment, save_csv
from bayesmodal.inference import load_idata, simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

STEPS = 500

CONFIG = f"""\
[data]
files = ["rec.csv"]

[sampler]
walkers = 30
steps = {STEPS}
burn = 200
thin = 10
seed = 5
moves = "de:0.8,de-snooker:0.2"

[outputs]
plots = false
report = true
ema = false
predictive_draws = 20
checkpoint_every_s = 0.2
chain = "full"   # whole float64 chains compared bit for bit (not compacted at the end)
"""


def _check_files_complete(folder) -> list[str]:
    """Open every file of a run folder; return the temporaries (which may be partial)."""
    temporaries = []
    for p in sorted(folder.iterdir()):
        if p.name.endswith(".tmp") or ".tmp." in p.name:
            temporaries.append(p.name)
        elif p.name == "run.lock":
            text = p.read_text()
            if text:  # empty when killed between creating and filling it (then stale)
                json.loads(text)
        elif p.suffix == ".json":
            json.loads(p.read_text())
        elif p.suffix == ".nc":
            load_idata(p)
        elif p.suffix == ".h5":
            with h5py.File(p, "r") as f:
                g = f["mcmc"]
                it = int(g.attrs["iteration"])
                assert g["chain"].shape[0] == it and np.all(np.isfinite(g["chain"][:it]))
        elif p.suffix == ".html":
            assert p.read_text().rstrip().endswith("</html>"), p
        elif p.suffix == ".png":
            data = p.read_bytes()
            assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[-8:-4] == b"IEND", p
        elif p.suffix in (".toml", ".log", ".md"):
            p.read_text()
        else:
            raise AssertionError(f"unexpected file {p.name}")
    return temporaries


def _cmd(config, out, *extra):
    return [sys.executable, "-m", "bayesmodal", "run", str(config), "--out", str(out),
            "--quiet", *extra]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Data, configuration, and one uninterrupted run in a subprocess (with its wall time)."""
    root = tmp_path_factory.mktemp("faults")
    n, dt = 300, 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0]
    y = simulate_linear(LinearModel(Rig(), "free"), theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=8)[0]
    save_csv(Experiment(t, v, y, name="rec"), root / "rec.csv")
    cfg = root / "cfg.toml"
    cfg.write_text(CONFIG)
    ref = root / "ref"
    t0 = time.monotonic()
    proc = subprocess.run(_cmd(cfg, ref), capture_output=True, text=True, timeout=600)
    wall = time.monotonic() - t0
    assert proc.returncode == 0, proc.stderr
    return cfg, ref, wall


def _same_as_reference(folder, ref) -> None:
    assert (folder / "summary.json").read_bytes() == (ref / "summary.json").read_bytes()
    with h5py.File(folder / "chain.h5", "r") as a, h5py.File(ref / "chain.h5", "r") as b:
        for key in ("chain", "log_prob", "accepted"):
            assert np.array_equal(a["mcmc"][key][:], b["mcmc"][key][:]), key


def _kill_at(cfg, out, after_s: float) -> str:
    """Start a run, SIGKILL it ``after_s`` seconds later; return where it was."""
    proc = subprocess.Popen(_cmd(cfg, out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + after_s
        while time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.01)
        finished = proc.poll() is not None
        if not finished:
            os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=60)
    if finished:
        return "finished before the kill"
    st = out / "status.json"
    state = json.loads(st.read_text())["state"] if st.is_file() else "no status yet"
    return f"killed ({state})"


def _kill_points(wall: float, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.05, 0.98, n) * wall


def _kill_and_recover(reference, tmp_path, points) -> list[str]:
    cfg, ref, _ = reference
    seen = []
    for i, after in enumerate(points):
        out = tmp_path / f"k{i}"
        where = _kill_at(cfg, out, float(after))
        if where == "finished before the kill":  # a faster machine than the reference
            out = tmp_path / f"k{i}-again"
            where = _kill_at(cfg, out, float(after) / 2)
        seen.append(where)
        if out.exists():
            _check_files_complete(out)  # complete files only, whatever the moment
        # --resume continues a killed run, starts one that never got going, and leaves a
        # finished one alone; --force starts over: all end at the uninterrupted result
        flag = "--force" if i % 3 == 2 else "--resume"
        proc = subprocess.run(_cmd(cfg, out, flag), capture_output=True, text=True,
                              timeout=600)
        assert proc.returncode == 0, (where, proc.stderr)
        assert _check_files_complete(out) == []
        assert not (out / "run.lock").exists()
        _same_as_reference(out, ref)
    return seen


def test_sigkill_at_random_moments_then_resume_gives_the_same_result(reference, tmp_path):
    points = _kill_points(reference[2], 1, seed=2026)
    seen = _kill_and_recover(reference, tmp_path, points)
    assert any(s.startswith("killed") for s in seen), seen


@pytest.mark.slow
def test_sigkill_at_many_random_moments(reference, tmp_path):
    # one to two minutes: five more moments, including start-up and the very end
    points = np.r_[_kill_points(reference[2], 3, seed=7), 0.3, reference[2] * 0.99]
    seen = _kill_and_recover(reference, tmp_path, points)
    assert sum(s.startswith("killed") for s in seen) >= 2, seen


# ---------------------------------------------------------------- full disk
class _DiskFull:
    """``os.replace`` that fails with ENOSPC from the ``after``-th call on: every atomic
    write of a run ends with a rename, so the disk "fills up" at that write."""

    def __init__(self, after: int) -> None:
        self.after = after
        self.calls = 0
        self.real = os.replace

    def __call__(self, src, dst, *args, **kwargs):
        self.calls += 1
        if self.calls > self.after:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))
        return self.real(src, dst, *args, **kwargs)


def _disk_full_then_resume(reference, tmp_path, monkeypatch, capsys, writes) -> None:
    cfg, ref, _ = reference
    before = {p.name: p.read_bytes() for p in ref.iterdir()}
    for i, after in enumerate(writes):
        out = tmp_path / f"d{i}"
        full = _DiskFull(after)
        monkeypatch.setattr(os, "replace", full)
        capsys.readouterr()
        code = main(["run", str(cfg), "--out", str(out), "--quiet"])
        monkeypatch.setattr(os, "replace", full.real)
        err = capsys.readouterr().err
        if full.calls <= after:  # the run needed fewer writes than that: it finished
            assert code == 0
        else:
            assert code == 2, err
            lines = err.strip().splitlines()
            assert len(lines) == 1 and "No space left on device" in lines[0], err
            assert str(out) in lines[0]  # names the file it could not write
        if out.exists():
            _check_files_complete(out)
            assert not (out / "run.lock").exists()  # the lock is released
        # space again: the run continues to the uninterrupted result
        assert main(["run", str(cfg), "--out", str(out), "--resume", "--quiet"]) == 0
        _same_as_reference(out, ref)
    # a finished run elsewhere is never touched
    assert {p.name: p.read_bytes() for p in ref.iterdir()} == before


def test_full_disk_at_a_random_write_keeps_earlier_results(reference, tmp_path, monkeypatch,
                                                           capsys):
    writes = np.random.default_rng(11).integers(3, 30, 1).tolist()
    _disk_full_then_resume(reference, tmp_path, monkeypatch, capsys, writes)


@pytest.mark.slow
def test_full_disk_at_many_random_writes(reference, tmp_path, monkeypatch, capsys):
    writes = [0, 1, 2, *np.random.default_rng(12).integers(3, 40, 4).tolist()]
    _disk_full_then_resume(reference, tmp_path, monkeypatch, capsys, writes)


def test_resume_on_a_full_disk_leaves_the_interrupted_run_untouched(reference, tmp_path,
                                                                    monkeypatch, capsys):
    import shutil

    from bayesmodal.runs import RunFolder

    cfg, ref, _ = reference
    out = tmp_path / "interrupted"
    shutil.copytree(ref, out)
    for name in ("summary.json", "timing.json", "report.html", "posterior.nc"):
        (out / name).unlink()
    with RunFolder(out).lock():  # as if killed after the last checkpoint
        RunFolder(out).write_status("running")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    full = _DiskFull(0)
    monkeypatch.setattr(os, "replace", full)
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(out), "--resume", "--quiet"]) == 2
    monkeypatch.setattr(os, "replace", full.real)
    err = capsys.readouterr().err
    assert "No space left on device" in err and len(err.strip().splitlines()) == 1
    after = {p.name: p.read_bytes() for p in out.iterdir()}
    # checkpoint, status, configuration: all as they were (run.log only grows)
    assert after.pop("run.log").startswith(before.pop("run.log"))
    assert after == before
    assert main(["run", str(cfg), "--out", str(out), "--resume", "--quiet"]) == 0
    _same_as_reference(out, ref)


# ---------------------------------------------------------------- unwritable folders
def test_unwritable_output_folder_gives_a_clear_error(reference, tmp_path, monkeypatch, capsys):
    cfg, _, _ = reference
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(blocker / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot create the run folder" in err[0], err
    assert str(blocker / "run") in err[0]
    assert blocker.read_text() == "not a folder"

    # a folder the process may not write into (simulated: the tests may run as root)
    locked = tmp_path / "readonly"
    locked.mkdir()
    real_open = os.open

    def no_write(path, flags, *args, **kwargs):
        if str(path).startswith(str(locked)) and flags & (os.O_WRONLY | os.O_RDWR):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", no_write)
    assert main(["run", str(cfg), "--out", str(locked), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Permission denied" in err[0] and str(locked) in err[0], err
    assert list(locked.iterdir()) == []  # nothing half-made


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_read_only_folder_for_real(reference, tmp_path, capsys):
    cfg, _, _ = reference
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        capsys.readouterr()
        assert main(["run", str(cfg), "--out", str(locked), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert "Permission denied" in err and len(err.strip().splitlines()) == 1
    finally:
        locked.chmod(0o755)


# ---------------------------------------------------------------- two writers
def test_two_runs_started_together_on_one_folder(reference, tmp_path):
    cfg, ref, _ = reference
    out = tmp_path / "shared"
    procs = [subprocess.Popen(_cmd(cfg, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    results = [p.communicate(timeout=600) for p in procs]
    codes = sorted(p.returncode for p in procs)
    assert codes == [0, 2], results
    loser = next(err for p, (_, err) in zip(procs, results, strict=True) if p.returncode == 2)
    lines = loser.strip().splitlines()
    assert len(lines) == 1 and "is being written by process" in lines[0], loser
    winner_pid = next(p.pid for p in procs if p.returncode == 0)
    assert f"process {winner_pid}" in lines[0]
    # the refused run changed nothing: the winner's result is the uninterrupted one
    _same_as_reference(out, ref)


# ---------------------------------------------------------------- a real full disk
def _mount_tmpfs(where, size: str) -> bool:
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    where.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                       capture_output=True, timeout=30)
    return r.returncode == 0


@pytest.mark.slow
@pytest.mark.parametrize("size", ["200k", "1m", "3m"])
def test_real_full_disk_on_a_tiny_tmpfs(reference, tmp_path, size):
    # HDF5 (checkpoint, posterior.nc) does not fail cleanly on a full disk: the run must
    # check the space first and stop with one line, not crash (it used to segfault)
    cfg, ref, _ = reference
    disk = tmp_path / "tiny"
    if not _mount_tmpfs(disk, size):
        pytest.skip("cannot mount a tmpfs here (needs root and mount privileges)")
    try:
        out = disk / "run"
        proc = subprocess.run(_cmd(cfg, out), capture_output=True, text=True, timeout=600)
        assert proc.returncode == 2, (proc.returncode, proc.stderr[-3000:])
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "No space left on device" in lines[0], proc.stderr[-3000:]
        assert str(out) in lines[0]
        assert _check_files_complete(out) == []
        assert json.loads((out / "status.json").read_text())["state"] == "failed"
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True, timeout=30)
