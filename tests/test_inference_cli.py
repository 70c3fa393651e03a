"""``bayesmodal sample`` and ``bayesmodal compare`` end to end on a small synthetic record."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayesmodal.cli import main
from bayesmodal.data import Experiment, save_csv
from bayesmodal.inference import simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

pytestmark = pytest.mark.filterwarnings("ignore::bayesmodal.inference.ConvergenceWarning")


@pytest.fixture(scope="module")
def csv_path(tmp_path_factory):
    model = LinearModel(Rig(), "proportional")
    n = 500
    t = np.arange(n) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(model, [6.2, 1.57, 1.46, 1.14, 1.6, 1e-4], v, 0.005)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=1)[0]
    p = tmp_path_factory.mktemp("data") / "syn.csv"
    save_csv(Experiment(t, v, y, name="syn"), p)
    return p


ARGS = ["--walkers", "32", "--steps", "60", "--burn", "20", "--seed", "4", "--quiet"]


def test_sample_writes_run_folder_and_resumes(csv_path, tmp_path, capsys):
    out = tmp_path / "prop"
    rc = main(["sample", str(csv_path), "--damping", "proportional", "--out", str(out), *ARGS])
    assert rc == 0
    names = {p.name for p in out.iterdir()}
    assert {"posterior.nc", "summary.json", "chain.h5", "trace.png", "corner.png",
            "predictive.png", "bode.png", "modal_intervals.png"} <= names
    s = json.loads((out / "summary.json").read_text())
    for key in ("parameters", "omega_rad_s", "zeta", "mode_shapes", "diagnostics"):
        assert key in s
    assert set(s["omega_rad_s"]) >= {"median", "lo", "hi"}
    assert set(s["parameters"]["g_v"]) >= {"median", "lo", "hi"}
    assert set(s["diagnostics"]) >= {"max_rhat", "min_ess", "tau", "acceptance", "converged"}
    # the same command again resumes from the finished checkpoint: identical results
    rc = main(["sample", str(csv_path), "--damping", "proportional", "--out", str(out),
               "--json", *ARGS[:-1], "--no-plots"])
    assert rc == 0
    again = json.loads(capsys.readouterr().out)
    assert again["parameters"] == s["parameters"]
    # the finished chain's own sampling figures, kept in its checkpoint (not 0 evaluations
    # over the resumed call's fraction of a second)
    assert again["performance"] == s["performance"]
    assert s["performance"]["n_evaluations"] == 32 * (60 + 1)


def test_compare_runs_without_evidence(csv_path, tmp_path, capsys):
    dirs = []
    for damping in ("free", "proportional"):
        d = tmp_path / damping
        assert main(["sample", str(csv_path), "--damping", damping, "--out", str(d),
                     "--no-plots", *ARGS]) == 0
        dirs.append(str(d))
    rc = main(["compare", "--runs", *dirs, "--no-evidence", "--test", str(csv_path),
               "--out", str(tmp_path / "cmp"), "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)["model_choice"]
    assert set(res["models"]) == {"free", "proportional"}
    assert set(res["preferred"]) == {"loo", "waic", "predictive"}
    assert (tmp_path / "cmp" / "model_choice.md").read_text().startswith("| criterion")


def test_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["sample", str(tmp_path / "nope.csv"), "--quiet"]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["compare", "--no-evidence", "--out", str(tmp_path)]) == 2
    assert "no DATA" in capsys.readouterr().err


def _idata(config_hash, data="[\"ab\"]"):
    import arviz as az

    idt = az.from_dict(posterior={"x": np.zeros((1, 4))})
    idt.posterior.attrs.update(config_hash=config_hash, data_sha256=data)
    return idt


def test_check_distinct_runs(tmp_path):
    from bayesmodal import ConfigError
    from bayesmodal.runs.compare import check_distinct_runs

    a, b = tmp_path / "a", tmp_path / "b"
    with pytest.raises(ConfigError, match="the same folder"):
        check_distinct_runs([a, tmp_path / "x" / ".." / "a"], [_idata("h1"), _idata("h2")])
    with pytest.raises(ConfigError, match="same sampler configuration and seed"):
        check_distinct_runs([a, b], [_idata("h1"), _idata("h1")])
    # negative controls: another configuration, or the same one on other data
    check_distinct_runs([a, b], [_idata("h1"), _idata("h2")])
    check_distinct_runs([a, b], [_idata("h1"), _idata("h1", "[\"cd\"]")])


@pytest.mark.slow
def test_compare_refuses_the_same_run_twice(csv_path, tmp_path, capsys):
    import shutil

    runs = {}
    for seed in ("4", "5"):
        d = tmp_path / f"seed{seed}"
        args = [a if a != "4" else seed for a in ARGS]
        assert main(["sample", str(csv_path), "--out", str(d), "--no-plots", *args]) == 0
        runs[seed] = str(d)
    copy = tmp_path / "copy"
    shutil.copytree(runs["4"], copy)
    capsys.readouterr()
    for argv in (["--runs", runs["4"], runs["4"]], [runs["4"], runs["4"]],
                 [runs["4"], str(tmp_path / "seed4" / ".." / "seed4")], [runs["4"], str(copy)],
                 ["--runs", runs["4"], str(copy)]):
        assert main(["compare", *argv, "--no-evidence", "--out", str(tmp_path / "c")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("bayesmodal compare: error: "), err
        assert "comparing a run with itself" in err[0]
    # negative control: two runs of the same model with different seeds are distinct
    assert main(["compare", "--runs", runs["4"], runs["5"], "--no-evidence", "--quiet",
                 "--out", str(tmp_path / "c")]) == 0
    assert main(["compare", runs["4"], runs["5"], "--quiet",
                 "--out", str(tmp_path / "c2")]) == 0
