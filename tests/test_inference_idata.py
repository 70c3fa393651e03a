"""InferenceData assembly, NetCDF round trip, summaries and posterior plots."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.data import Experiment
from bayesmodal.inference import (
    experiments_from_idata,
    likelihood_from_idata,
    load_idata,
    lsq_vs_posterior,
    posterior_modes,
    sample_posterior,
    save_idata,
    simulate_noise,
    summary_dict,
    to_inference_data,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

TRUTH = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])


@pytest.fixture(scope="module")
def run():
    model = LinearModel(Rig(), "proportional")
    n = 600
    t = np.arange(n) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    e = simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=3)[0]
    y = simulate_linear(model, TRUTH, v, 0.005) + e
    exp = Experiment(t, v, y, name="syn", sha256="0" * 64)
    return sample_posterior(exp, model, noise="ar1", n_walkers=24, n_steps=300, burn=100,
                            rng=5, warn=False)


@pytest.fixture(scope="module")
def idata(run):
    return to_inference_data(run, n_predictive=48, rng=1)


def test_groups_dims_and_physical_units(run, idata):
    assert set(idata.groups()) >= {"posterior", "sample_stats", "log_likelihood",
                                   "posterior_predictive", "observed_data", "constant_data"}
    post = idata.posterior
    assert list(post.data_vars) == list(run.names)
    assert post["m2"].dims == ("chain", "draw")
    assert np.array_equal(post["m2"].values, run.draws[:, :, 2])
    ll = idata.log_likelihood["y"]
    assert ll.dims == ("chain", "draw", "obs", "output")
    assert ll.shape == (24, run.draws.shape[1], 600, 3)
    # pointwise terms add up to the total log-likelihood of each draw (float32 storage)
    total = idata.sample_stats["total_log_likelihood"].values
    assert np.allclose(ll.values.astype(float).sum(axis=(2, 3)), total, rtol=1e-5)
    pp = idata.posterior_predictive
    assert pp["y"].shape[0] == 24 and pp["y"].shape[2:] == (600, 3)
    assert np.array_equal(idata.observed_data["y"].values, run.likelihood.experiments[0].y_m)
    assert post.attrs["noise"] == "ar1" and post.attrs["damping"] == "proportional"
    assert len(post.attrs["config_hash"]) == 16


def test_netcdf_round_trip_is_atomic_and_lossless(idata, tmp_path):
    path = save_idata(idata, tmp_path / "sub" / "posterior.nc")
    assert sorted(p.name for p in path.parent.iterdir()) == ["posterior.nc"]
    back = load_idata(path)
    for g in idata.groups():
        if g == "posterior_predictive":  # packed in steps (tests/test_outputs_size.py)
            continue
        a, b = getattr(idata, g), getattr(back, g)
        for v in a.data_vars:
            assert np.array_equal(a[v].values, b[v].values), (g, v)
    assert back.posterior.attrs["priors_json"] == idata.posterior.attrs["priors_json"]
    with pytest.raises(DataError, match="no such InferenceData"):
        load_idata(tmp_path / "missing.nc")


def test_run_can_be_rebuilt_from_its_file(run, idata):
    exps = experiments_from_idata(idata)
    assert len(exps) == 1 and np.array_equal(exps[0].y_m, run.likelihood.experiments[0].y_m)
    lik = likelihood_from_idata(idata)
    d = run.flat_draws[:5]
    assert np.allclose(lik(d), run.likelihood(d))


def test_summary_has_the_documented_keys(idata):
    s = summary_dict(idata)
    for key in ("parameters", "omega_rad_s", "zeta", "mode_shapes", "diagnostics"):
        assert key in s
    assert set(s["parameters"]) == set(json.loads(idata.posterior.attrs["parameter_names"]))
    g = s["parameters"]["g_v"]
    assert g["lo"] <= g["median"] <= g["hi"]
    assert len(s["omega_rad_s"]["median"]) == 3
    assert np.array(s["mode_shapes"]["median"]).shape == (3, 3)
    assert set(s["diagnostics"]) >= {"max_rhat", "min_ess", "tau", "acceptance", "converged"}
    assert s["method_agreement"]["max_rel_diff_iteration_rayleigh_vs_eig"] < 1e-9
    json.dumps(s)  # serialisable


def test_lsq_vs_posterior_flags_values_outside(idata):
    rows = lsq_vs_posterior(idata)
    names = [r.quantity for r in rows]
    assert names[:6] == ["g_v", "m1", "m2", "m3", "ca", "cb"]
    assert "omega_3" in names and "zeta_1" in names and "shape_3[x3]" in names
    for r in rows:
        assert r.inside == (r.lo <= r.lsq <= r.hi)


def test_plots_return_labelled_axes(idata):
    import matplotlib.pyplot as plt

    from bayesmodal.inference.propagate import propagate_modes
    from bayesmodal.plots.posterior import (
        plot_bode_bands,
        plot_corner,
        plot_modal_intervals,
        plot_predictive,
        plot_trace,
    )

    ax = plot_trace(idata, var_names=["g_v", "m1"])
    assert ax.shape == (2, 2) and "N/V" in ax[0, 0].get_ylabel()
    ax = plot_corner(idata, var_names=["g_v", "m1", "ca"], reference={"g_v": 6.2})
    assert ax.shape == (3, 3) and "kg" in ax[1, 0].get_ylabel()
    ax = plot_predictive(idata, t_range=(0, 2))
    assert len(ax) == 6 and ax[-1].get_xlabel() == "time (s)" and "mm" in ax[0].get_ylabel()
    ax = plot_bode_bands(idata, n_draws=20)
    assert len(ax) == 3 and ax[-1].get_xlabel() == "frequency (Hz)"
    # up to 0.8 of the Nyquist frequency (where the residual diagnostics look), the
    # measured H1 of the fitted record drawn as dots, the bands as filled areas
    dt = float(np.diff(idata.observed_data["t_s"].values[:2])[0])
    assert ax[0].get_xlim()[1] == pytest.approx(0.8 * 0.5 / dt)
    assert any(ln.get_marker() == "." for ln in ax[0].get_lines())
    assert len(ax[0].collections) >= 3
    assert len(ax[-1].get_xticklabels()) >= 5
    ms = posterior_modes(idata)
    ref = propagate_modes(LinearModel(Rig(), "proportional"), TRUTH[None], methods=("eig",))
    lsce = [("rec", np.asarray(ref.omega_rad_s).ravel(), np.asarray(ref.zeta).ravel())]
    ax = plot_modal_intervals(ms, reference=ref, lsce=lsce)
    assert ax.shape == (2, 3) and ax[0, 0].get_ylabel() == "natural frequency (Hz)"
    # the legend sits outside the panels and names the LSCE values
    legend = ax[0, 0].figure.legends[0]
    assert "LSCE (rec)" in [t.get_text() for t in legend.get_texts()]
    assert all(a.get_legend() is None for a in ax.ravel())
    plt.close("all")


def test_write_run_writes_every_file(idata, tmp_path):
    import matplotlib.pyplot as plt

    from bayesmodal.runs import write_run

    s = write_run(idata, tmp_path / "run")
    files = {p.name for p in (tmp_path / "run").iterdir()}
    assert files == {"posterior.nc", "summary.json", "lsq_vs_posterior.md", "trace.png",
                     "corner.png", "predictive.png", "bode.png", "modal_intervals.png"}
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["damping"] == s["damping"]
    plt.close("all")


def test_corner_zooms_on_the_posterior_and_marks_far_references(idata):
    import matplotlib.pyplot as plt

    from bayesmodal.plots.posterior import plot_corner

    g = idata.posterior["g_v"].values.ravel()
    m1 = idata.posterior["m1"].values.ravel()
    far = float(g.max() + 50 * g.std())  # a reference far outside the posterior
    near = float(np.median(m1))
    ax = plot_corner(idata, var_names=["g_v", "m1"], reference={"g_v": far, "m1": near})
    lo, hi = ax[1, 0].get_xlim()
    # the axes frame the draws (0.5-99.5 % quantiles, padded) and are not stretched to it
    q_lo, q_hi = np.quantile(g, [0.005, 0.995])
    assert lo <= q_lo and hi >= q_hi and hi < far
    assert hi - lo < 2 * (q_hi - q_lo)
    # its value is written on the diagonal; the reference inside is a line
    assert any(f"LSQ {far:.4g}" == t.get_text() for t in ax[0, 0].texts)
    assert any(np.allclose(ln.get_xdata(), near) for ln in ax[1, 1].get_lines())
    plt.close("all")
