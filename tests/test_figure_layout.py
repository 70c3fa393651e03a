"""Every figure of the run report and of the command line's ``--plots`` is readable.

The figures are drawn on the Agg canvas and searched for text drawn over text (titles,
suptitle, axis labels, tick labels, legends) and for legends over the data
(``tests/_layout.py``).  The report's figures are drawn for runs on one, four and seven
short synthetic records: the posterior is a few steps of the sampler started at the
truth, enough for valid draws at every place a figure reads them, not a converged run.
"""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from _layout import MAX_LEGEND_SHARE, layout_problems, legend_cover, legend_hides_peaks

from bayesmodal.cli import main
from bayesmodal.data import Experiment, save_csv
from bayesmodal.inference import (
    sample_posterior,
    simulate_noise,
    to_inference_data,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

TRUTH = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])

#: Record names as a run on the measured data has them: the four files, and for seven
#: records the pieces of them cut at rest (``bayesmodal.segments``).
NAMES = {
    1: ["data_impulses"],
    4: ["data_impulses", "data_steps", "data_sine_sweep_fast", "data_sine_sweep_slow"],
    7: ["data_impulses[0]", "data_impulses[1]", "data_steps[0]", "data_steps[1]",
        "data_sine_sweep_fast[0]", "data_sine_sweep_slow[0]", "data_sine_sweep_slow[1]"],
}


def _input(name: str, t: np.ndarray) -> np.ndarray:
    """A drive of the kind the record's name says, V."""
    if "impulses" in name:
        return 3.0 * sum(((t >= s) & (t < s + 0.05)) for s in (0.1, 1.2))
    if "steps" in name:
        return 1.0 * (t >= 0.2) - 1.0 * (t >= 1.4)
    f_hz = 0.5 + 4.0 * t / t[-1]  # a short sweep through the three modes
    return 0.8 * np.sin(2 * np.pi * np.cumsum(f_hz) * (t[1] - t[0]))


def _records(k: int) -> list[Experiment]:
    model = LinearModel(Rig(), "free")
    out = []
    for i, name in enumerate(NAMES[k]):
        dt = 0.01 if "slow" in name else 0.005
        n = 300 + 60 * i
        t = np.arange(n) * dt
        v = _input(name, t)
        y = simulate_linear(model, TRUTH, v, dt)
        y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=i)[0]
        out.append(Experiment(t, v, y, name=name, sha256="0" * 64))
    return out


def _posterior(exps):
    """A few sampler steps from the truth: valid draws for every plot, in well under a
    second of sampling."""
    from bayesmodal.inference.record_layout import RecordLayout
    from bayesmodal.inference.record_priors import record_priors
    from bayesmodal.inference.records import RecordsLikelihood

    model = LinearModel(Rig(), "free")
    layout = None
    n_par = len(TRUTH) + 6
    if len(exps) > 1:
        layout = RecordLayout({"g_v": "hierarchical", "v0": "shared"}, noise_scale="response")
        n_par = record_priors(RecordsLikelihood(model, exps, "ar1", None, layout)).n_params
    run = sample_posterior(exps, model, noise="ar1", layout=layout, start=TRUTH,
                           refine=False, n_walkers=2 * n_par, n_steps=12, burn=4, thin=1,
                           rng=1, warn=False)
    return run, to_inference_data(run, n_predictive=10, pointwise=False, rng=1)


def _report_figures(exps, tmp_path, monkeypatch) -> dict:
    """Every figure of a run's report, by file name, drawn by the code the run uses."""
    import bayesmodal.runs.outputs as outputs
    from bayesmodal.plots.runs import plot_residual_acf, plot_residuals
    from bayesmodal.runs.crosscheck import residual_check
    from bayesmodal.runs.outputs import write_modal_plot, write_run
    from bayesmodal.runs.report import REPORT_IMAGES

    figs = {}
    monkeypatch.setattr(outputs, "atomic_savefig",
                        lambda fig, path, **kw: figs.__setitem__(path.name, fig))
    run, idata = _posterior(exps)
    summary = write_run(idata, tmp_path, prob=0.9)
    # the run redraws the modal intervals with the LSCE values of every record (here
    # near the posterior medians, as on the measured records)
    om, ze = (np.asarray(summary[key]["median"]) for key in ("omega_rad_s", "zeta"))
    lsce = [(e.name, om * (1 + 0.01 * k), ze * (1 + 0.05 * k)) for k, e in enumerate(exps)]
    write_modal_plot(idata, tmp_path, lsce=lsce)
    model = LinearModel(Rig(), "free")
    checks = [residual_check(e, model, TRUTH, diagnostics=False) for e in exps]
    figs["residuals.png"] = plot_residuals(checks).flat[0].figure
    figs["residual_acf.png"] = plot_residual_acf(checks).flat[0].figure
    assert set(figs) == set(REPORT_IMAGES)
    return figs


@pytest.mark.parametrize("k", [1, 4, 7])
def test_report_figures_have_no_collisions(k, tmp_path, monkeypatch):
    figs = _report_figures(_records(k), tmp_path, monkeypatch)
    found = {name: layout_problems(fig) for name, fig in figs.items()}
    plt.close("all")
    bad = {name: p for name, p in found.items() if p}
    assert not bad, "\n".join(f"{name} ({k} records): {p}" for name, ps in bad.items()
                              for p in ps[:8])


# ------------------------------------------------------------------ the command line


@pytest.fixture
def saved_figures(monkeypatch):
    """The figures the command line saves, by file name (nothing is written)."""
    from matplotlib.figure import Figure

    figs = {}

    def savefig(self, fname, *args, **kwargs):
        figs[str(getattr(fname, "name", fname)).rsplit("/", 1)[-1]] = self

    monkeypatch.setattr(Figure, "savefig", savefig)
    yield figs
    plt.close("all")


def _cli_record(path, kind: str) -> str:
    """A CSV record long enough for the command line's estimators: a train of pulses
    (``impulses``) or 5 s on / 5 s off steps (``steps``)."""
    dt = 0.005
    t = np.arange(int(20.0 / dt)) * dt
    if kind == "impulses":
        model, theta = LinearModel(Rig(), "free"), TRUTH
        v = 3.0 * sum(((t >= s) & (t < s + 0.05)) for s in (0.5, 4.1, 8.3, 12.2, 16.7))
    else:  # damped enough to settle on each plateau
        model = LinearModel(Rig(), "proportional")
        theta = np.array([6.2, 1.56, 1.46, 1.15, 10.0, 1e-4])
        v = np.where((t % 10.0) < 5.0, 0.5, 0.0)
    y = simulate_linear(model, theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-6), np.full((1, 3), 0.5), len(t), rng=5)[0]
    save_csv(Experiment(t, v, y, name=f"data_{kind}"), path)
    return str(path)


def _assert_clean(figs):
    assert figs
    bad = {name: layout_problems(fig) for name, fig in figs.items()}
    bad = {k: v for k, v in bad.items() if v}
    assert not bad, "\n".join(f"{n}: {p}" for n, ps in bad.items() for p in ps[:8])


def test_modal_plots_have_no_collisions(saved_figures, tmp_path):
    assert main(["modal", "--plots", str(tmp_path)]) == 0
    _assert_clean(saved_figures)


@pytest.mark.parametrize("method", ["lsce", "circle"])
def test_ema_plots_have_no_collisions(method, saved_figures, tmp_path, capsys):
    data = _cli_record(tmp_path / "data_impulses.csv", "impulses")
    assert main(["ema", data, "--method", method, "--plots", str(tmp_path / "p")]) == 0
    _assert_clean(saved_figures)


def test_static_plots_have_no_collisions(saved_figures, tmp_path, capsys):
    data = _cli_record(tmp_path / "data_steps.csv", "steps")
    assert main(["static", data, "--plots", str(tmp_path / "p")]) == 0
    _assert_clean(saved_figures)


@pytest.mark.slow
def test_diagnose_plots_have_no_collisions(saved_figures, tmp_path, capsys):
    """Every figure of ``diagnose --plots`` (the residual diagnostics of each training
    record and the before/after fit); slow: the null calibration needs 19 refits."""
    data = _cli_record(tmp_path / "data_impulses.csv", "impulses")
    assert main(["diagnose", data, "--no-posterior", "--null", "19", "--max-effects", "1",
                 "--plots", str(tmp_path / "p"), "--quiet"]) == 0
    assert len(saved_figures) >= 10
    _assert_clean(saved_figures)


# ------------------------------------------------------------------ the checker itself


def _crowded():
    """Four narrow panels with long titles and ylabels and legends over the curves."""
    fig, ax = plt.subplots(1, 4, figsize=(6, 2.5))
    t = np.linspace(0, 2, 400)
    for a in ax:
        for j in range(3):
            a.plot(t, np.cos(6 * t + j), label=f"x{j + 1}")
        a.set_title("data_impulses: measured - model at posterior median")
        a.set_ylabel("autocorrelation of the residual (-)")
        a.legend(loc="upper left")
    return fig


def test_checker_flags_a_crowded_figure():
    problems = layout_problems(_crowded())
    plt.close("all")
    assert any("title" in p and "overlaps" in p and "title" in p.split("overlaps")[1]
               for p in problems)
    assert any("y label" in p and "overlaps" in p for p in problems)
    assert any("covers" in p for p in problems)
    assert any("hides the largest" in p for p in problems)


def test_checker_passes_a_clean_figure():
    fig, ax = plt.subplots(1, 2, figsize=(9, 3), layout="constrained")
    t = np.linspace(0, 2, 400)
    for a in ax:
        a.plot(t, np.exp(-3 * t), label="decay")
        a.set_title("rec")
        a.set_xlabel("time (s)")
    ax[0].set_ylabel("x1 (mm)")
    fig.legend(*ax[0].get_legend_handles_labels(), loc="outside lower center")
    assert layout_problems(fig) == []
    plt.close("all")


def test_legend_cover_counts_the_points_under_the_legend():
    # a line through the middle of the axes: a legend in the centre covers the points of
    # its width, one in an empty corner none
    fig, ax = plt.subplots(figsize=(6, 4))
    t = np.linspace(0, 1, 1001)
    ax.plot(t, np.full_like(t, 0.5), label="a flat line with a long legend label")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    leg = ax.legend(loc="center")
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    (name, i, share), = legend_cover(fig, r)
    box, frame = leg.get_window_extent(r), ax.get_window_extent(r)
    assert share == pytest.approx(box.width / frame.width, abs=2e-3)
    assert share > MAX_LEGEND_SHARE
    assert legend_hides_peaks(fig, r) == []  # a flat line's extremes are its ends
    ax.legend(loc="upper left")
    fig.canvas.draw()
    assert legend_cover(fig)[0][2] == 0.0
    ax.plot([0.05, 0.5, 0.9] + [0.5] * 7, [0.92] + [0.5] * 9)  # a peak under the legend
    fig.canvas.draw()
    assert legend_hides_peaks(fig) == [("axes 0 legend", 0)]
    plt.close("all")


def test_tick_labels_of_one_axis_are_checked_among_themselves():
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.set_xlim(0, 1e6)
    ax.set_xticks(np.linspace(0, 1e6, 9), [f"{x:,.0f}" for x in np.linspace(0, 1e6, 9)])
    problems = layout_problems(fig)
    plt.close("all")
    assert any(p.startswith("axes 0 x tick") and "overlaps axes 0 x tick" in p
               for p in problems)


def test_agg_backend():
    assert matplotlib.get_backend().lower() == "agg"
