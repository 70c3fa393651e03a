"""``bayesmodal batch`` on local processes and on a Dask cluster: same results, failures
reported one by one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayesmodal.cli import main
from bayesmodal.data import Experiment, save_csv
from bayesmodal.inference import simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs import run_batch

CONFIG = """\
[data]
files = ["rec.csv"]

[model]
damping = "{damping}"

[sampler]
walkers = {walkers}
steps = 150
burn = 50
thin = 5
seed = {seed}
moves = "de:0.8,de-snooker:0.2"

[outputs]
report = false
ema = false
plots = false
predictive_draws = 20
"""


@pytest.fixture(scope="module")
def configs(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch")
    n, dt = 400, 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(LinearModel(Rig(), "free"), [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0,
                                                     0.0, 0.0], v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=9)[0]
    save_csv(Experiment(t, v, y, name="rec"), root / "rec.csv")
    paths = []
    for name, damping, walkers, seed in (("free", "free", 30, 1),
                                         ("prop", "proportional", 24, 2),
                                         ("odd_walkers", "free", 31, 3)):
        p = root / f"{name}.toml"
        p.write_text(CONFIG.format(damping=damping, walkers=walkers, seed=seed))
        paths.append(p)
    bad = root / "unparsable.toml"
    bad.write_text("[data]\nfiles = ['rec.csv']\n[sampler]\nwalkers = 'many'\n")
    paths.append(bad)
    return root, paths


def _results(summary: dict) -> dict:
    """The parts of summary.json that the chain determines (not timings)."""
    keep = ("parameters", "omega_rad_s", "zeta", "damped_rad_s", "mode_shapes",
            "lsq_comparison")
    out = {k: summary[k] for k in keep}
    d = dict(summary["diagnostics"])
    out["diagnostics"] = d
    out["config_hash"] = summary["run"]["config_hash"]
    return out


def _check_items(res):
    states = {it.name: it.state for it in res.items}
    assert states == {"free": "finished", "prop": "finished", "odd_walkers": "failed",
                      "unparsable": "failed"}
    byname = {it.name: it for it in res.items}
    # the failure of a run inside its worker, and of a file that does not parse
    assert "[sampler.walkers] must be even" in byname["odd_walkers"].error
    assert "[sampler.walkers] must be int" in byname["unparsable"].error
    assert byname["unparsable"].out_dir is None
    assert res.n_failed == 2
    assert [it.name for it in res.items] == ["free", "prop", "odd_walkers", "unparsable"]


@pytest.mark.slow
def test_batch_local_and_dask_give_the_same_results(configs, tmp_path, capsys):
    distributed = pytest.importorskip(
        "distributed", reason="dask[distributed] not installed (pip install '.[dask]')")
    root, paths = configs
    local = run_batch(paths, out_root=tmp_path / "local", workers=2)
    _check_items(local)
    assert local.executor == "local (2 processes)"
    table = local.table()
    assert "2 of 4 runs finished" in table and "error: ConfigError:" in table
    saved = json.loads((tmp_path / "local" / "batch.json").read_text())
    assert saved["n_failed"] == 2 and len(saved["runs"]) == 4

    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster:
        capsys.readouterr()
        rc = main(["batch", *map(str, paths), "--scheduler", cluster.scheduler_address,
                   "--out-root", str(tmp_path / "dask"), "--json", "--quiet"])
    assert rc == 1  # some runs failed
    res = json.loads(capsys.readouterr().out)
    assert res["executor"].startswith("dask tcp://")
    assert {r["name"]: r["state"] for r in res["runs"]} == {
        "free": "finished", "prop": "finished", "odd_walkers": "failed",
        "unparsable": "failed"}
    for name in ("free", "prop"):
        a = json.loads((tmp_path / "local" / name / "summary.json").read_text())
        b = json.loads((tmp_path / "dask" / name / "summary.json").read_text())
        assert _results(a) == _results(b), name
    # negative control: the two configurations differ
    a = json.loads((tmp_path / "local" / "free" / "summary.json").read_text())
    b = json.loads((tmp_path / "local" / "prop" / "summary.json").read_text())
    assert _results(a) != _results(b)


def test_batch_reports_collisions_and_failures_without_stopping(configs, tmp_path, capsys):
    root, paths = configs
    twin = root / "twin.toml"
    # a second configuration writing to the folder of the first
    twin.write_text(paths[0].read_text().replace("[outputs]", '[outputs]\ndir = "free"'))
    capsys.readouterr()
    rc = main(["batch", str(paths[0]), str(twin), str(paths[3]), "--workers", "1",
               "--out-root", str(tmp_path), "--quiet", "--json"])
    assert rc == 1
    res = json.loads(capsys.readouterr().out)
    st = {r["name"]: r for r in res["runs"]}
    assert st["free"]["state"] == "finished"
    assert st["twin"]["state"] == "failed" and "same folder" in st["twin"]["error"]
    assert st["unparsable"]["state"] == "failed"
    assert (tmp_path / "free" / "summary.json").is_file()
    # a second batch does not overwrite the finished run: it reports it and goes on
    rc = main(["batch", str(paths[0]), "--workers", "1", "--out-root", str(tmp_path),
               "--quiet", "--json"])
    assert rc == 1
    res = json.loads(capsys.readouterr().out)
    assert "holds a finished run" in res["runs"][0]["error"]
    rc = main(["batch", str(paths[0]), "--workers", "1", "--out-root", str(tmp_path),
               "--resume", "--quiet", "--json"])
    assert rc == 0
    assert json.loads(capsys.readouterr().out)["runs"][0]["action"] == "none"


def test_batch_scheduler_without_dask_or_bad_workers_is_a_clear_error(configs, capsys):
    _, paths = configs
    assert main(["batch", str(paths[0]), "--workers", "0"]) == 2
    assert "--workers must be >= 1" in capsys.readouterr().err


def test_batch_quiet_still_names_every_failed_config(configs, tmp_path, capsys):
    root, paths = configs
    missing = root / "no_data.toml"
    missing.write_text(paths[0].read_text().replace('"rec.csv"', '"absent.csv"'))
    capsys.readouterr()
    rc = main(["batch", str(paths[3]), str(missing), "--workers", "1",
               "--out-root", str(tmp_path), "--quiet"])
    assert rc == 1
    cap = capsys.readouterr()
    assert cap.out == ""  # no table, no progress
    lines = cap.err.strip().splitlines()
    assert len(lines) == 2, cap.err
    assert lines[0].startswith(f"bayesmodal batch: failed: {paths[3]}: ConfigError:")
    assert "[sampler.walkers] must be int" in lines[0]
    assert lines[1].startswith(f"bayesmodal batch: failed: {missing}:")
    assert "absent.csv" in lines[1]
    # negative control: without --quiet the errors are in the table on stdout instead
    rc = main(["batch", str(paths[3]), "--workers", "1", "--out-root", str(tmp_path)])
    cap = capsys.readouterr()
    assert rc == 1 and "error: ConfigError:" in cap.out and "failed:" not in cap.err
