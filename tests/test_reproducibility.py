"""A recorded run carries what its result depends on, and re-running it reproduces its
``summary.json`` byte for byte (``bayesmodal rerun RUN_DIR``); a changed record is refused
and a changed result is reported (negative controls)."""

from __future__ import annotations

import json
from importlib import metadata

import numpy as np
import pytest

from bayesmodal import ConfigError, DataError, __version__
from bayesmodal.cli import main
from bayesmodal.data import Experiment, file_sha256, save_csv
from bayesmodal.inference import simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs import recorded_config, rerun_run
from bayesmodal.runs.config import load_config
from bayesmodal.runs.rerun import json_differences

CONFIG = """\
[data]
files = ["rec.csv"]

[sampler]
walkers = 30
steps = 120
burn = 40
thin = 4
seed = 21
moves = "de:0.8,de-snooker:0.2"

[outputs]
plots = false
report = false
ema = false
predictive_draws = 10
"""


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    root = tmp_path_factory.mktemp("repro")
    n, dt = 400, 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0]
    y = simulate_linear(LinearModel(Rig(), "free"), theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=4)[0]
    save_csv(Experiment(t, v, y, name="rec"), root / "rec.csv")
    cfg = root / "cfg.toml"
    cfg.write_text(CONFIG)
    run_dir = root / "out" / "cfg"
    assert main(["run", str(cfg), "--out", str(run_dir), "--quiet"]) == 0
    return root, cfg, run_dir


def test_every_result_records_versions_hash_data_digest_and_seed(recorded):
    root, cfg, run_dir = recorded
    s = json.loads((run_dir / "summary.json").read_text())
    run = s["run"]
    assert run["config_hash"] == load_config(cfg).hash()
    assert run["data"][0]["sha256"] == file_sha256(root / "rec.csv")
    assert run["seed"] == 21
    assert run["bayesmodal_version"] == __version__
    for dep in ("numpy", "scipy", "emcee", "arviz", "numba", "h5py"):
        assert run["dependencies"][dep] == metadata.version(dep)
    # the sampler's own provenance block (also written by `bayesmodal sample`)
    prov = s["provenance"]
    assert prov["seed"] == 21 and prov["dependencies"]["emcee"] == metadata.version("emcee")
    assert prov["data_sha256"] == [file_sha256(root / "rec.csv")]
    # nothing in summary.json depends on the clock
    flat = json.dumps(s)
    for key in ("wall_time_s", "sampling_time_s", "started", "finished", "elapsed_s",
                "evaluations_per_s"):
        assert f'"{key}"' not in flat, key
    timing = json.loads((run_dir / "timing.json").read_text())
    assert timing["wall_time_s"] > 0 and timing["performance"]["n_evaluations"] > 0


def test_rerun_reproduces_summary_exactly(recorded, tmp_path, capsys):
    _, _, run_dir = recorded
    capsys.readouterr()
    out = tmp_path / "again"
    assert main(["rerun", str(run_dir), "--out", str(out), "--quiet"]) == 0
    assert "reproduced byte for byte" in capsys.readouterr().out
    assert (out / "summary.json").read_bytes() == (run_dir / "summary.json").read_bytes()
    # timings are recorded but differ
    assert (out / "timing.json").is_file()


def test_rerun_reports_a_changed_result(recorded, tmp_path, capsys):
    # negative control: a recorded summary altered by hand is not "reproduced"
    root, _, run_dir = recorded
    fake = tmp_path / "fake"
    fake.mkdir()
    for name in ("summary.json", "config.json", "status.json"):
        (fake / name).write_bytes((run_dir / name).read_bytes())
    s = json.loads((fake / "summary.json").read_text())
    s["parameters"]["m1"]["median"] *= 1.0 + 1e-12
    (fake / "summary.json").write_text(json.dumps(s, indent=2) + "\n")
    capsys.readouterr()
    assert main(["rerun", str(fake), "--out", str(tmp_path / "fake-rerun"), "--quiet"]) == 1
    out = capsys.readouterr().out.splitlines()
    again = json.loads((tmp_path / "fake-rerun" / "summary.json").read_text())
    assert out[0].endswith(f"summary.json differs from {fake}:")
    assert out[1:] == [f"  parameters.m1.median: {s['parameters']['m1']['median']!r} != "
                       f"{again['parameters']['m1']['median']!r}"]


def test_rerun_refuses_an_edited_record_or_changed_data(recorded, tmp_path, capsys):
    root, _, run_dir = recorded
    edited = tmp_path / "edited"
    edited.mkdir()
    for name in ("summary.json", "config.json"):
        (edited / name).write_bytes((run_dir / name).read_bytes())
    c = json.loads((edited / "config.json").read_text())
    c["seed"] = 22
    (edited / "config.json").write_text(json.dumps(c))
    with pytest.raises(ConfigError, match="not the recorded configuration hash"):
        recorded_config(edited)
    c["seed"] = 21
    c["source"] = "elsewhere.toml"  # not in the hash, but recorded in summary.json
    (edited / "config.json").write_text(json.dumps(c))
    with pytest.raises(ConfigError, match="edited after the run"):
        recorded_config(edited)
    assert recorded_config(run_dir).sampler.seed == 21
    # data changed after the run: refused before any sampling
    moved = tmp_path / "moved"
    moved.mkdir()
    s = json.loads((run_dir / "summary.json").read_text())
    data = tmp_path / "rec.csv"
    data.write_bytes((root / "rec.csv").read_bytes().replace(b"e-05", b"e-06", 1))
    s["run"]["data"][0]["file"] = str(data)
    (moved / "summary.json").write_text(json.dumps(s))
    (moved / "config.json").write_bytes((run_dir / "config.json").read_bytes())
    with pytest.raises(DataError, match="changed since the run"):
        rerun_run(moved, tmp_path / "never")
    assert not (tmp_path / "never").exists()
    capsys.readouterr()
    assert main(["rerun", str(tmp_path / "nothing")]) == 2
    assert "no summary.json" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="another folder"):
        rerun_run(run_dir, run_dir)


def test_json_differences():
    assert json_differences({"a": {"b": [1, 2]}}, {"a": {"b": [1, 2]}}) == []
    assert json_differences({"a": 1}, {"a": 1.0}) == ["a: 1 != 1.0"]
    assert json_differences({"a": 1}, {"b": 1}) == ["a: present != missing",
                                                    "b: missing != present"]
    assert json_differences([1], [1, 2]) == [": [1] != [1, 2]"]
