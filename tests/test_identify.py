"""``identify``: records to modal parameters with the model that explains them.

Records from tests/identify_records.py (the independent reference simulators, noise and
counts; one rig per seed, a different input per record).  The default suite runs the
workflow on one cart with a hidden amplifier offset (input-side effects only, so that it
stays short) and on a clean rig (negative control); the slow suite hides stick-slip
friction, which the final posterior samples as LuGre friction.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _chromium import HEIGHT, WIDTH, first_screen, page_check
from identify_records import write_records
from scipy.stats import norm

from bayesmodal.model.rigs import load_rig
from bayesmodal.model.system import Rig
from bayesmodal.runs.config import load_config
from bayesmodal.runs.identify import (
    DiagnosisSpec,
    diagnosis_records,
    final_config,
    identify,
    sampled_effects,
    spec_from_config,
    warm_start,
)
from bayesmodal.runs.identify_summary import summarize

#: a two-sided tail of 1e-4: an estimate this many Laplace sds from the truth is an error
Z_FAR = float(norm.isf(5e-5))
INPUT_CANDIDATES = ("input_offset", "drive_deadband", "input_saturation")


def _toml(paths, *, rig="ecp210-1cart", candidates=INPUT_CANDIDATES, steps=400) -> str:
    """A run configuration of the linear model on ``paths`` that asks for the workflow,
    with samplers short enough for a test."""
    files = ", ".join(f'"{p}"' for p in paths)
    names = ", ".join(f'"{c}"' for c in candidates)
    return (f'[data]\nfiles = [{files}]\n[rig]\nfile = "{rig}"\n'
            f"[sampler]\nwalkers = 16\nsteps = {steps}\nburn = {steps // 2}\nthin = 5\n"
            "seed = 1\n"
            "[outputs]\npredictive_draws = 10\npointwise_loglik = false\nplots = false\n"
            f"[crossval]\nenabled = true\nsteps = {steps}\ndraws = 40\n"
            f"[identify]\nenabled = true\ncandidates = [{names}]\nmax_effects = 2\n"
            f"global_search = false\nstarts = 1\nwalkers = 16\nsteps = {steps}\n"
            f"burn = {steps // 2}\nthin = 5\n")


def _spec(paths, folder, **kw):
    cfg = folder / "rig.toml"
    cfg.write_text(_toml(paths, **kw))
    return spec_from_config(load_config(cfg)), cfg


@pytest.fixture(scope="module")
def offset_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("identify_offset")
    paths, theta = write_records(folder, "one_cart", 3, n_records=2, n_samples=1600,
                                 v_offset=0.1)
    spec, cfg = _spec(paths, folder)
    return spec, identify(spec, folder / "out"), folder, cfg


def test_names_the_hidden_offset_and_samples_it(offset_run):
    _, res, _, _ = offset_run
    s = res.summary
    assert s["found"] == ["input_offset"] and s["final_model"] == "linear+input_offset"
    (cause,) = s["causes"]
    diag = json.loads((res.out_dir / "diagnosis.json").read_text())["diagnosis"]
    iv = diag["parameters"]["v_offset"]
    sd = (iv["hi"] - iv["lo"]) / (2 * norm.isf(0.05))
    assert abs(cause["parameters"]["v_offset"] - 0.1) < Z_FAR * sd, iv
    assert cause["heldout_delta_lpd"] > 0 and cause["heldout_fit_after"] > \
        cause["heldout_fit_before"]
    # the final run sampled the found model, and its summary has the linear core's modes
    final = json.loads((res.out_dir / "final" / "summary.json").read_text())
    assert final["run"]["config"]["extensions"] == ["input_offset"]
    assert s["final"]["modal"]["omega_rad_s"] == final["omega_rad_s"]
    assert s["linear"]["modal"]["omega_rad_s"] != final["omega_rad_s"]
    # each record left out in turn: its own estimate against the others' interval
    assert [r["record"] for r in s["final"]["heldout"]] == ["record_1", "record_2"]
    for r in s["final"]["heldout"]:
        for c in r["omega_rad_s"]:
            assert c["inside"] == (c["lo"] <= c["own"] <= c["hi"])


def test_report_tells_the_story(offset_run):
    _, res, _, _ = offset_run
    html = (res.out_dir / "report.html").read_text()
    s = res.summary
    f1 = s["final"]["modal"]["omega_rad_s"]["median"][0] / (2 * np.pi)
    assert "What the records say" in html and "input offset" in html
    assert f"{f1:.4g} Hz" in html
    assert "final/report.html" in html and (res.out_dir / "final" / "report.html").is_file()


def test_run_and_batch_of_the_config_reuse_the_folder(offset_run):
    _, res, _, cfg = offset_run
    p = subprocess.run([sys.executable, "-m", "bayesmodal", "run", str(cfg), "--out",
                        str(res.out_dir)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.startswith("Final model: ") and "input offset" in p.stdout
    from bayesmodal.runs.batch import run_one

    item = run_one(str(cfg), str(res.out_dir))
    assert item.action == "identify" and item.error is None
    assert item.omega_rad_s == res.summary["final"]["modal"]["omega_rad_s"]["median"]


def test_rerun_reuses_every_stage(offset_run):
    spec, res, folder, _ = offset_run
    before = json.loads((res.out_dir / "diagnosis.json").read_text())["finished"]
    again = identify(spec, folder / "out")
    assert again.stage_s["linear"] == 0.0 and again.stage_s["final"] == 0.0
    assert json.loads((res.out_dir / "diagnosis.json").read_text())["finished"] == before
    assert again.summary["causes"] == res.summary["causes"]


def test_cli_refuses_two_configs_in_one_line(tmp_path):
    cfg = tmp_path / "rig.toml"
    cfg.write_text('[data]\nfiles = ["x.csv"]\n')
    bad = subprocess.run([sys.executable, "-m", "bayesmodal", "identify", str(cfg), str(cfg)],
                         capture_output=True, text=True)
    assert bad.returncode == 2, bad.stderr
    assert "give one CONFIG" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_clean_rig_keeps_the_linear_model(tmp_path):
    paths, _ = write_records(tmp_path, "one_cart", 5, n_records=2, n_samples=1600)
    res = identify(_spec(paths, tmp_path)[0], tmp_path / "out")
    s = res.summary
    assert s["found"] == [] and s["final_model"] == "linear"
    assert not (tmp_path / "out" / "final").exists()
    assert s["final"] == s["linear"]
    assert "the linear model is the final one" in (tmp_path / "out" / "report.html").read_text()
    # other diagnosis options: the diagnosis runs again, the linear run is reused and the
    # old diagnosis is kept beside the new one
    from dataclasses import replace

    spec = _spec(paths, tmp_path)[0]
    again = identify(replace(spec, diagnosis=replace(spec.diagnosis, max_effects=1)),
                     tmp_path / "out")
    assert again.stage_s["linear"] == 0.0
    kept = sorted(p.name for p in (tmp_path / "out").glob("diagnosis.*.json"))
    assert len(kept) == 1 and kept[0] == f"diagnosis.{spec.diagnosis_key()[:8]}.json"
    # a run folder of another configuration is set aside, not overwritten
    (tmp_path / "out" / "final").mkdir()
    (tmp_path / "out" / "final" / "status.json").write_text('{"config_hash": "abcdef1234"}')
    identify(replace(spec, diagnosis=replace(spec.diagnosis, max_effects=1)),
             tmp_path / "out")
    assert not (tmp_path / "out" / "final").exists()
    assert (tmp_path / "out" / "final.abcdef12" / "status.json").is_file()


def test_diagnosis_cuts_the_record_that_moves_furthest(tmp_path):
    # 6000 samples of 5 ms: 3.3 s between the pulses, in which friction stops the cart
    paths, _ = write_records(tmp_path, "one_cart", 3, n_records=2, n_samples=6000,
                             noise=False, friction={1: (0.6, 0.8)})
    from bayesmodal.data import load_experiment

    exps = [load_experiment(p) for p in paths]
    rig = load_rig("ecp210-1cart")
    cut, train, names = diagnosis_records(exps, rig, DiagnosisSpec())
    peaks = [np.abs(e.y_m[:, 0]).max() for e in exps]
    assert names == [exps[int(np.argmax(peaks))].name]
    assert len(cut) > len(exps) and train == list(range(len(cut)))
    # one record, or no cutting asked: the records as given
    assert diagnosis_records(exps[:1], rig, DiagnosisSpec())[2] == []
    assert diagnosis_records(exps, rig, DiagnosisSpec(split="none"))[0] == exps


def test_stick_slip_friction_is_sampled_as_lugre_from_the_diagnosis_fit():
    assert sampled_effects(("coulomb_friction", "input_offset")) == (
        "lugre_friction", "input_offset")
    rig = Rig()
    lin = {n: {"after": v} for n, v in zip(
        ("g_v", "m1", "m2", "m3", "c1", "c2", "c3", "c12", "c23"),
        (6.2, 1.56, 1.46, 1.15, 2.9, 1.8, 2.0, 0.1, 0.05), strict=True)}
    pars = {f"Fc{i}": {"median": 0.1 * i} for i in (1, 2, 3)}
    pars.update({f"Fs{i}": {"median": 0.15 * i} for i in (1, 2, 3)})
    pars["v_offset"] = {"median": 0.02}
    theta = warm_start(rig, ("lugre_friction", "input_offset"),
                       {"linear_parameters": lin, "parameters": pars})
    from bayesmodal.model.effects import get_extension

    ext = get_extension(["lugre_friction", "input_offset"])
    named = dict(zip(ext.names(rig), theta, strict=True))
    assert named["g_v"] == 6.2 and named["Fc2"] == pytest.approx(0.2)
    assert named["Fs3"] == pytest.approx(0.45) and named["v_offset"] == 0.02
    # LuGre's own bristle parameters start at their catalogue values
    spec = {p.name: p for p in ext.specs(rig)}
    assert named["sigma0"] == spec["sigma0"].null


def test_final_config_keeps_the_records_and_takes_the_final_sampler(tmp_path):
    paths, _ = write_records(tmp_path, "one_cart", 3, n_records=2, n_samples=400)
    spec, _ = _spec(paths, tmp_path)
    assert spec.linear.identify is None  # the linear run is the configuration without it
    assert spec.diagnosis.candidates == INPUT_CANDIDATES and spec.final.steps == 400
    cfg = final_config(spec, ("lugre_friction",))
    assert cfg.data.files == spec.linear.data.files and cfg.model.rig == spec.linear.model.rig
    assert cfg.model.extensions == ("lugre_friction",) and cfg.sampler.walkers == spec.final.walkers
    assert cfg.name == "rig_final" and cfg.hash() != spec.linear.hash()
    assert cfg.records.per_record == spec.linear.records.per_record
    # the population layer: every mass of the core per record
    from dataclasses import replace

    pop = final_config(replace(spec, final=replace(spec.final, population=True)),
                       ("lugre_friction",))
    assert pop.records.per_record == {"m1": "hierarchical"}


def test_summary_without_crossval_has_no_heldout_rows():
    lin = {"omega_rad_s": {"median": [10.0], "lo": [9.9], "hi": [10.1]},
           "zeta": {"median": [0.05], "lo": [0.04], "hi": [0.06]},
           "diagnostics": {"converged": True, "max_rhat": 1.0, "min_ess": 1000}}
    fin = {**lin, "zeta": {"median": [0.04], "lo": [0.035], "hi": [0.045]}}
    diag = {"diagnosis": {"effects": ["input_offset"], "causes": [], "gain": {}}}
    s = summarize(lin, diag, fin, ("input_offset",))
    assert s["final"]["heldout"] == [] and s["linear"]["heldout"] == []
    # the linear model's zeta is 25 % above the final one's
    assert s["ignoring_causes"][0]["zeta"] == pytest.approx(25.0)


@pytest.mark.slow
def test_names_stick_slip_friction_and_samples_lugre(tmp_path):
    paths, _ = write_records(tmp_path, "one_cart", 4, n_records=2, n_samples=2400,
                             friction={1: (0.6, 0.8)})
    spec, _ = _spec(paths, tmp_path, candidates=("coulomb_friction",) + INPUT_CANDIDATES,
                    steps=600)
    res = identify(spec, tmp_path / "out")
    s = res.summary
    assert s["found"][0] == "coulomb_friction" and s["sampled"][0] == "lugre_friction"
    final = json.loads((res.out_dir / "final" / "summary.json").read_text())
    assert final["run"]["config"]["extensions"][0] == "lugre_friction"
    # dry friction read as viscous damping: the linear model's zeta is the larger
    assert s["ignoring_causes"][0]["zeta"] > 0


@pytest.mark.slow
def test_cli_runs_the_workflow_on_data_files(tmp_path):
    paths, _ = write_records(tmp_path, "one_cart", 3, n_records=2, n_samples=1600,
                             v_offset=0.1)
    p = subprocess.run([sys.executable, "-m", "bayesmodal", "identify", *map(str, paths),
                        "--rig", "ecp210-1cart", "--out", str(tmp_path / "out"),
                        "--steps", "600", "--walkers", "16", "--max-effects", "1"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "input offset at motor input" in p.stdout and "report: file://" in p.stdout


def test_stage_table_reads_every_stage_of_the_folder(offset_run):
    _, res, _, _ = offset_run
    bench = str(Path(__file__).resolve().parents[1] / "benchmarks")
    sys.path.insert(0, bench)
    try:
        from identify_stages import stage_table
    finally:
        sys.path.remove(bench)
    rows = stage_table(res.out_dir)
    names = [r[0] for r in rows]
    assert names[:2] == ["linear: posterior", "linear: leave-one-record-out (2 folds)"]
    assert "diagnosis" in names and "final: posterior" in names
    # every part of a run's wall time is accounted for, none negative
    assert all(r[1] is not None and r[1] >= 0 for r in rows), rows
    assert rows[0][2] > 0 and rows[0][3] > 0  # evaluations and ESS per second


def test_identify_table_errors_are_listed_together(tmp_path):
    from bayesmodal import ConfigError
    from bayesmodal.runs.config import parse_config

    raw = {"data": {"files": ["x.csv"]},
           "identify": {"enabled": True, "null": 5, "split": "sometimes", "steps": 100,
                        "burn": 100, "candidates": ["friction"]}}
    with pytest.raises(ConfigError) as e:
        parse_config(raw, check_files=False)
    text = str(e.value)
    for key in ("identify.null", "identify.split", "identify.burn", "identify.candidates"):
        assert f"[{key}]" in text, text
    # without the table, or with enabled = false, a configuration is the plain run
    raw["identify"]["enabled"] = False
    assert parse_config(raw, check_files=False).identify is None


def test_identify_options_are_checked_in_one_place():
    """The configuration and the specs the command line builds refuse an option with the
    same words (``identify_problems``); options in range pass both (negative control)."""
    from dataclasses import replace

    from bayesmodal import ConfigError
    from bayesmodal.runs.config import parse_config
    from bayesmodal.runs.identify_spec import DiagnosisSpec, FinalSpec, identify_problems

    bad = {"null": 5, "weights": "heavy", "burn": 600, "steps": 600, "prune": 700}
    problems = dict(identify_problems(bad))
    assert sorted(problems) == ["burn", "null", "prune", "weights"]
    with pytest.raises(ConfigError) as e:
        parse_config({"data": {"files": ["x.csv"]}, "identify": {"enabled": True, **bad}},
                     check_files=False)
    for key, message in problems.items():
        assert f"[identify.{key}] {message}" in str(e.value)
    with pytest.raises(ConfigError, match=r"\[identify\] null must be >= 19, got 5"):
        replace(DiagnosisSpec(), n_null=5)
    with pytest.raises(ConfigError, match=r"\[identify\] burn must be < identify.steps"):
        replace(FinalSpec(), steps=600, burn=600)
    good = {"null": 19, "weights": "spread", "steps": 600, "burn": 100, "prune": 50}
    assert identify_problems(good) == []
    assert parse_config({"data": {"files": ["x.csv"]}, "identify": {"enabled": True, **good}},
                        check_files=False).identify["null"] == 19


IDENTIFY_CHECK_JS = """<script>
window.addEventListener('load', function () {
  var box = function (sel) { return document.querySelector(sel).getBoundingClientRect(); };
  var out = document.createElement('pre');
  out.id = 'bm-check';
  out.textContent = JSON.stringify({
    verdict_bottom: box('#verdict').bottom, story_bottom: box('ul.story').bottom,
    modal_bottom: box('#modal + table').bottom, width: document.body.scrollWidth
  });
  document.body.appendChild(out);
});
</script></body>"""


def test_first_screen_renders_in_headless_chromium(offset_run, tmp_path):
    _, res, _, _ = offset_run
    report = res.out_dir / "report.html"
    box = page_check(report, IDENTIFY_CHECK_JS, tmp_path)
    # the verdict, the story and the modal table of both models on the first screen
    assert 0 < box["verdict_bottom"] < box["story_bottom"] < box["modal_bottom"] <= HEIGHT
    assert box["width"] <= WIDTH, box
    first_screen(report, tmp_path)  # a page with text and a tinted verdict box


def test_positions_out_of_cart_order_are_refused_before_any_run(tmp_path):
    # the diagnosis reads position records as cart 1, 2, ... in order (accelerometer
    # records it reads in any order): one line naming the fix, and no posterior sampled
    # first (the folder stays empty)
    data = Path(__file__).resolve().parents[1] / "data"
    toml = (data / "accel_rig.toml").read_text()
    head, _, _ = toml.partition("[[sensors]]")
    rig = tmp_path / "reversed.toml"
    rig.write_text(head + '[[sensors]]\ncart = "2"\nunit = "m"\n'
                          '[[sensors]]\ncart = "1"\nunit = "m"\n')
    t = np.arange(2000) * 0.005  # a record in m, its values of no matter here
    x = 1e-3 * np.sin(2 * np.pi * t)
    csv = tmp_path / "r.csv"
    np.savetxt(csv, np.column_stack([t, np.sign(x), x, 0.5 * x]), delimiter=",",
               header="t,v,x2,x1", comments="")
    p = subprocess.run([sys.executable, "-m", "bayesmodal", "identify", str(csv),
                        "--rig", str(rig), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode != 0
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "identify (its diagnosis)" in lines[0], p.stderr
    assert "cart order" in lines[0]
    assert not (tmp_path / "o" / "linear").exists()


def test_story_counts_the_left_out_records_inside_their_intervals():
    from bayesmodal.runs.identify_summary import story

    def rec(name, own_f, lo, hi, band):
        row = {"record": name, "band": band}
        for key in ("omega_rad_s", "zeta"):
            row[key] = [{"own": own_f, "lo": lo, "median": (lo + hi) / 2, "hi": hi,
                         "inside": lo <= own_f <= hi}]
        return row

    lin = {"omega_rad_s": {"median": [10.0], "lo": [9.9], "hi": [10.1]},
           "zeta": {"median": [0.05], "lo": [0.04], "hi": [0.06]},
           "diagnostics": {"converged": True, "max_rhat": 1.0, "min_ess": 1000}}
    fin = {**lin, "zeta": {"median": [0.04], "lo": [0.035], "hi": [0.045]}}
    diag = {"diagnosis": {"effects": ["coulomb_friction"], "causes": [
        {"cause": "coulomb_friction", "location_label": "cart 1", "parameters": {"Fc1": 0.2},
         "gain": {"held_out": {"delta_lpd": 50.0, "se": 5.0}}}], "gain": {}}}
    s = summarize(lin, diag, fin, ("lugre_friction",))
    s["final"]["heldout"] = [rec("a", 0.5, 0.4, 0.6, "ok"), rec("b", 0.7, 0.4, 0.6, "ok"),
                             rec("c", 0.45, 0.4, 0.6, "narrow")]
    verdict, lines = story(s)
    assert verdict.startswith("Final model: ")
    text = " ".join(lines)
    assert "2 of 3 records have their own natural frequencies inside" in text
    assert "2 of 3 predictive bands" in text
    assert "coulomb friction at cart 1" in text and "LuGre" in text
    assert "moves zeta1 by +25 %" in text
