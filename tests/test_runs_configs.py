"""The shipped run configurations, the extension cross-check and the evidence option."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bayesmodal.data import Experiment, find_data, save_csv
from bayesmodal.inference import default_priors, simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs import prepare_run, render_report, run_config
from bayesmodal.runs.config import load_config

RUNS = Path(__file__).resolve().parents[1] / "runs"
SHIPPED = {
    # name: (damping, extensions, fitted record stems)
    "impulses_free": ("free", (), ["data_impulses"]),
    "impulses_proportional": ("proportional", (), ["data_impulses"]),
    "steps": ("free", (), ["data_steps"]),
    "sweeps": ("free", (), ["data_sine_sweep_fast", "data_sine_sweep_slow"]),
    "impulses_friction": ("free", ("coulomb_friction",), ["data_impulses"]),
    "records_free": ("free", (), ["data_impulses", "data_steps", "data_sine_sweep_fast",
                                  "data_sine_sweep_slow"]),
    "records_friction": ("free", ("lugre_friction", "drive_deadband", "input_offset"),
                         ["data_impulses", "data_steps", "data_sine_sweep_fast",
                          "data_sine_sweep_slow"]),
}


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_config_is_valid(name):
    cfg = load_config(RUNS / f"{name}.toml", check_files=False)
    damping, ext, stems = SHIPPED[name]
    assert cfg.model.damping == damping and cfg.model.extensions == ext
    assert [Path(f).stem for f in cfg.data.files] == stems
    model = LinearModel(Rig(cfg.model.springs_n_m), cfg.model.damping)
    n_par = default_priors(model, noise=cfg.likelihood.noise,
                           extension=cfg.model.extension).n_params
    assert cfg.sampler.walkers >= 2 * n_par and cfg.sampler.walkers % 2 == 0
    # about a thousand retained draws: posterior.nc stays near 100 MB on 7400 samples
    smp = cfg.sampler
    draws = smp.walkers * ((smp.steps - smp.burn + smp.thin - 1) // smp.thin)
    assert 500 <= draws <= 2000
    assert cfg.outputs.report and cfg.outputs.plots


def test_every_shipped_config_is_documented():
    readme = (RUNS / "README.md").read_text()
    names = sorted(p.stem for p in RUNS.glob("*.toml"))
    assert names == sorted(SHIPPED)
    for n in names:
        assert f"{n}.toml" in readme


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_config_matches_the_measured_data(name):
    cfg = load_config(RUNS / f"{name}.toml", check_files=False)
    missing = [f for f in cfg.data.files + cfg.data.heldout if not Path(f).is_file()]
    if missing:
        pytest.skip(f"measured data not found: {missing}")
    prep = prepare_run(cfg)
    assert all(e.n_outputs == 3 for e in prep.experiments + prep.heldout)


def _record(path: Path, n: int = 800) -> Path:
    dt = 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0]
    y = simulate_linear(LinearModel(Rig(), "free"), theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=4)[0]
    save_csv(Experiment(t, v, y, name=path.stem), path)
    return path


def test_extension_config_samples_the_extended_posterior(tmp_path):
    """A run with ``extensions`` samples the extended model (its parameters are in the
    posterior, summary and report), scores the held-out record with it and checks the
    residuals of the extended model."""
    _record(tmp_path / "rec.csv", n=400)
    _record(tmp_path / "held.csv", n=300)
    cfg = tmp_path / "fric.toml"
    cfg.write_text("""
[data]
files = ["rec.csv"]
heldout = ["held.csv"]
[model]
damping = "free"
extensions = ["coulomb_friction"]
[likelihood]
noise = "white"
[priors]
Fs2 = [0.0, 2.0]
[sampler]
walkers = 36
steps = 60
burn = 20
thin = 2
seed = 3
[outputs]
plots = false
ema = false
""")
    res = run_config(cfg, tmp_path / "out")
    s = res.summary
    assert s["extension"] == "coulomb_friction"
    assert {"Fc1", "Fs3", "sigma_3", "g_v"} <= set(s["parameters"])
    ext = s["extensions"]["coulomb_friction"]
    assert "posterior" in ext["method"]
    assert set(ext["params"]) == {f"F{k}{i}" for k in "cs" for i in (1, 2, 3)}
    for nm, (lo, hi) in ext["intervals"].items():
        assert lo <= ext["params"][nm] <= hi
    # the overridden prior bounds the draws
    assert s["parameters"]["Fs2"]["hi"] <= 2.0
    # the data have no friction: the kinetic levels stay negligible next to the
    # 3 V x 6.2 N/V = 19 N drive, and the fit is no worse than the linear LSQ fit
    fc = np.array([ext["params"][f"Fc{i}"] for i in (1, 2, 3)])
    assert np.all(np.abs(fc) < 0.05)
    assert np.all(np.asarray(ext["fit_percent"]) >= np.asarray(ext["linear_fit_percent"]) - 0.5)
    assert s["heldout"]["experiments"] == ["held"]
    assert np.all(np.asarray(s["heldout"]["fit_percent_median"]) > 90)
    assert len(s["crosscheck"]["lsq"]["theta"]) == 15
    html = render_report(tmp_path / "out")
    assert "Model extensions" in html and "Fc1" in html and "posterior" in html


@pytest.mark.slow
def test_evidence_option_is_stored_and_reported(tmp_path):
    pytest.importorskip("dynesty", reason="dynesty (the 'evidence' extra) not installed")
    _record(tmp_path / "rec.csv", n=400)
    cfg = tmp_path / "ev.toml"
    cfg.write_text("""
[data]
files = ["rec.csv"]
[model]
damping = "proportional"
[likelihood]
noise = "white"
[sampler]
walkers = 18
steps = 60
burn = 20
seed = 3
[outputs]
plots = false
ema = false
[evidence]
enabled = true
nlive = 30
dlogz = 5.0
""")
    res = run_config(cfg, tmp_path / "out")
    ev = res.summary["evidence"]
    assert ev["nlive"] == 30 and np.isfinite(ev["log_z"]) and ev["log_z_err"] > 0
    # nested sampling's identity ln Z = E_post[ln L] - H (H: information, KL of posterior
    # from prior); E_post[ln L] from the MCMC draws of the same run
    from bayesmodal.inference import load_idata

    ll = load_idata(tmp_path / "out" / "posterior.nc").sample_stats["total_log_likelihood"]
    expected = float(ll.mean()) - ev["information_nats"]
    assert abs(ev["log_z"] - expected) < 4 * ev["log_z_err"] + 5, (ev, expected)
    assert "ln Z" in render_report(tmp_path / "out")


@pytest.mark.slow
def test_shipped_proportional_config_finishes_and_converges(tmp_path):
    if find_data("ecp210-3dof/data_impulses.mat") is None:
        pytest.skip("measured data not found")
    res = run_config(RUNS / "impulses_proportional.toml", tmp_path / "run")
    s = res.summary
    assert s["convergence"]["converged"], s["convergence"]["verdict"]
    assert res.wall_time_s < 600  # "a few minutes" on a 2-core machine
    assert (tmp_path / "run" / "report.html").stat().st_size > 100_000
