"""``bayesmodal run`` end to end on short synthetic records, and ``compare RUN_DIR...``.

Two small runs (free and proportional damping, the data made by the free model) are
sampled once per module; the tests then read their folders.  The chains are short and
not converged (that is the point of a fast test): the statistical claims below use
tolerances stated against the run's own interval widths.
"""

from __future__ import annotations

import base64
import html
import json
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from importlib import metadata

import numpy as np
import pytest
from _chromium import HEIGHT, first_screen, page_check

from bayesmodal import __version__
from bayesmodal.cli import main
from bayesmodal.data import Experiment, file_sha256, save_csv
from bayesmodal.inference import load_idata, propagate_modes, save_idata, simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.config import load_config
from bayesmodal.runs.verdict import run_verdict

TRUTH = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])

CONFIG = """\
# synthetic record <script>alert("x")</script> & "quotes"
[data]
files = ["fit.csv"]
heldout = ["held.csv"]

[model]
damping = "{damping}"

[sampler]
walkers = {walkers}
steps = 300
burn = 100
thin = 5
seed = 3
moves = "de:0.8,de-snooker:0.2"

[outputs]
predictive_draws = 40
"""


def _record(path, n, pulse_s, seed):
    dt = 0.005
    t = np.arange(n) * dt
    v = np.where((t >= pulse_s) & (t < pulse_s + 0.05), 3.0, 0.0)
    y = simulate_linear(LinearModel(Rig(), "free"), TRUTH, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=seed)[0]
    save_csv(Experiment(t, v, y, name=path.stem), path)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    _record(root / "fit.csv", 1000, 0.1, 1)
    _record(root / "held.csv", 800, 0.2, 2)
    out = {}
    for name, damping, walkers in (("free", "free", 30), ("prop", "proportional", 24)):
        cfg = root / f"{name}.toml"
        cfg.write_text(CONFIG.format(damping=damping, walkers=walkers))
        assert main(["run", str(cfg), "--out-root", str(root / "out"), "--quiet"]) == 0
        out[name] = (cfg, root / "out" / name)
    return root, out


def _summary(d):
    return json.loads((d / "summary.json").read_text())


def _checked_pair(tmp_path, name, n, likelihood="", outputs=""):
    """Two simulated records of ``n`` samples and a configuration ``<name>.toml`` that
    samples them briefly and leaves each out in turn ([crossval]); ``likelihood`` and
    ``outputs`` are extra lines of those tables."""
    _record(tmp_path / "a.csv", n, 0.1, 1)
    _record(tmp_path / "b.csv", n, 0.2, 2)
    cfg = tmp_path / f"{name}.toml"
    cfg.write_text('[data]\nfiles = ["a.csv", "b.csv"]\n'
                   f'[likelihood]\nnoise = "white"\n{likelihood}'
                   "[sampler]\nwalkers = 24\nsteps = 30\nburn = 10\nthin = 2\nseed = 3\n"
                   "[crossval]\nenabled = true\ndraws = 10\nsteps = 20\n"
                   f"[outputs]\nplots = false\nreport = false\n{outputs}")
    return cfg


def test_run_folder_holds_every_output(runs):
    _, out = runs
    d = out["free"][1]
    names = {p.name for p in d.iterdir()}
    assert {"chain.h5", "posterior.nc", "summary.json", "status.json", "report.html",
            "run.log", "config.toml", "config.json", "trace.png", "corner.png",
            "predictive.png", "bode.png", "modal_intervals.png", "residuals.png",
            "residual_acf.png"} <= names
    assert "run.lock" not in names
    assert not [n for n in names if n.endswith(".tmp") or ".tmp." in n]
    st = json.loads((d / "status.json").read_text())
    assert st["state"] == "finished" and st["action"] == "fresh"
    log = (d / "run.log").read_text()
    assert "stage done: sampling" in log and "run finished" in log


def test_summary_records_provenance(runs):
    root, out = runs
    cfg, d = out["free"]
    s = _summary(d)
    run = s["run"]
    assert run["config_hash"] == load_config(cfg).hash()
    assert run["data"][0]["sha256"] == file_sha256(root / "fit.csv")
    assert run["heldout_data"][0]["sha256"] == file_sha256(root / "held.csv")
    assert run["bayesmodal_version"] == __version__
    for dep in ("numpy", "scipy", "emcee", "arviz", "numba"):
        assert run["dependencies"][dep] == metadata.version(dep)
    assert run["seed"] == 3 and run["walkers"] == 30 and run["steps"] == 300
    timing = json.loads((d / "timing.json").read_text())
    assert timing["wall_time_s"] > 0 and timing["action"] == "fresh"
    assert timing["performance"]["sampling_time_s"] > 0
    assert "wall_time_s" not in run and "performance" not in s  # summary.json is reproducible
    assert s["convergence"]["converged"] is False  # 300 steps: honest verdict
    assert s["convergence"]["verdict"].startswith("NOT converged")
    assert s["heldout"]["experiments"] == ["held"]
    rec = s["heldout"]["records"][0]
    assert rec["name"] == "held" and len(rec["coverage_90"]) == 3
    assert all(0.0 <= c <= 1.0 for c in rec["coverage_90"])
    assert s["heldout"]["fitted_records"][0]["name"] == "fit"
    assert np.isfinite(s["heldout"]["fitted_lpd_per_obs"])
    assert s["warnings"] == [] or all(isinstance(w, str) for w in s["warnings"])


def test_posterior_and_lsce_find_the_true_modes(runs):
    _, out = runs
    s = _summary(out["free"][1])
    truth = propagate_modes(LinearModel(Rig(), "free"), TRUTH[None], methods=("eig",))
    om = s["omega_rad_s"]
    for i, w in enumerate(truth.omega_rad_s[0]):
        width = om["hi"][i] - om["lo"][i]
        # short chain: allow two interval widths around the median
        assert abs(om["median"][i] - w) < 2 * width, (i, om["median"][i], w, width)
    lsce = s["crosscheck"]["lsce"][0]
    assert lsce["error"] is None
    # LSCE sees only the data; with 2e-5 m noise on centimetre motion it is within 0.1 %
    np.testing.assert_allclose(lsce["omega_matched"], truth.omega_rad_s[0], rtol=1e-3)
    np.testing.assert_allclose(lsce["zeta_matched"], truth.zeta[0], rtol=0.05)
    res = s["crosscheck"]["residuals"][0]
    assert res["experiment"] == "fit" and len(res["acf_lag1"]) == 3


def test_finished_run_is_kept_resume_is_a_no_op_force_reruns_identically(runs, capsys):
    _, out = runs
    cfg, d = out["prop"]
    before = (d / "summary.json").read_bytes()
    chain0 = load_idata(d / "posterior.nc").posterior["m1"].values
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(d), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds a finished run" in err and "--force" in err and len(err.splitlines()) == 1
    assert (d / "summary.json").read_bytes() == before
    assert main(["run", str(cfg), "--out", str(d), "--resume"]) == 0
    assert "already finished" in capsys.readouterr().out
    assert (d / "summary.json").read_bytes() == before
    assert main(["run", str(cfg), "--out", str(d), "--force", "--quiet"]) == 0
    assert json.loads((d / "timing.json").read_text())["action"] == "fresh"
    # same seed, same chain: the rerun reproduces the first run exactly
    assert np.array_equal(load_idata(d / "posterior.nc").posterior["m1"].values, chain0)
    assert (d / "summary.json").read_bytes() == before


def test_interrupted_run_needs_resume_and_the_same_configuration(runs, tmp_path, capsys):
    from bayesmodal.runs import RunFolder

    _, out = runs
    cfg, d = out["free"]
    copy = tmp_path / "copy"
    shutil.copytree(d, copy)
    with RunFolder(copy).lock():
        RunFolder(copy).write_status("running")
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(copy), "--quiet"]) == 2
    assert "use --resume" in capsys.readouterr().err
    other = tmp_path / "other.toml"
    other.write_text(cfg.read_text().replace("seed = 3", "seed = 4"))
    shutil.copy(cfg.parent / "fit.csv", tmp_path)
    shutil.copy(cfg.parent / "held.csv", tmp_path)
    assert main(["run", str(other), "--out", str(copy), "--resume", "--quiet"]) == 2
    assert "different configuration" in capsys.readouterr().err


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.tables, self.scripts, self.h2 = [], 0, 0, []
        self._in_h2 = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a)
        elif tag == "table":
            self.tables += 1
        elif tag == "script":
            self.scripts += 1
        elif tag == "h2":
            self._in_h2 = True

    def handle_endtag(self, tag):
        if tag == "h2":
            self._in_h2 = False

    def handle_data(self, data):
        if self._in_h2:
            self.h2.append(data)


def test_report_is_self_contained_and_escaped(runs):
    _, out = runs
    text = (out["free"][1] / "report.html").read_text()
    page = _Page()
    page.feed(text)
    assert page.scripts == 0
    assert {"What was run", "Sampler convergence", "Parameters", "Modal quantities",
            "Posterior predictive", "Bode diagram with credible bands",
            "Residual diagnostics", "Walker traces"} <= set(page.h2)
    # the traces come after every table
    assert text.index("<h2 id='traces'>") > text.rindex("</table>")
    assert page.tables >= 5
    assert len(page.imgs) == 7
    for img in page.imgs:
        src = img["src"]
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    # the configuration's comment is shown, escaped, never as markup
    assert "<script>alert" not in text
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &quot;quotes&quot;" in text
    assert not re.search(r"(src|href)=['\"](https?:|//)", text)


CHECK_JS = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var out = document.createElement('pre');
  out.id = 'bm-check';
  out.textContent = JSON.stringify({
    images: imgs.length,
    broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
                .map(function (i) { return i.alt; }),
    widths: imgs.map(function (i) { return i.naturalWidth; }),
    tables: document.querySelectorAll('table').length,
    rows: document.querySelectorAll('tr').length,
    verdict_bottom: document.getElementById('verdict').getBoundingClientRect().bottom,
    answers_bottom: document.querySelector('table.answers').getBoundingClientRect().bottom
  });
  document.body.appendChild(out);
});
</script></body>"""


def test_report_renders_in_headless_chromium(runs, tmp_path):
    _, out = runs
    report = out["free"][1] / "report.html"
    text = report.read_text()
    res = page_check(report, CHECK_JS, tmp_path)
    assert res["images"] == 7 and res["broken"] == [], res
    assert min(res["widths"]) > 100
    assert res["tables"] >= 5 and res["rows"] > 30
    # the verdict and the three answers fit on the first screen (1280 x 900)
    assert 0 < res["verdict_bottom"] < res["answers_bottom"] <= HEIGHT, res
    verdict = run_verdict(_summary(out["free"][1])).sentence
    assert html.escape(verdict, quote=True) in text
    assert text.index(html.escape(verdict, quote=True)) < text.index("<h2")
    first_screen(report, tmp_path)  # a page with text and a tinted verdict box


def test_compare_run_dirs_prefers_the_true_model(runs, tmp_path, capsys):
    _, out = runs
    dirs = [str(out["free"][1]), str(out["prop"][1])]
    capsys.readouterr()
    assert main(["compare", *dirs, "--out", str(tmp_path / "cmp"), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    labels = [r["label"] for r in res["runs"]]
    assert sorted(labels) == ["free", "prop"]
    # the data were made by the free model, whose damping is not proportional
    best, second = res["runs"]
    assert best["label"] == "free" and res["preferred"]["loo"] == "free"
    assert abs(second["elpd_diff"]) > 2 * second["dse"]
    assert res["preferred"]["heldout"] == "free"  # held-out record, from summary.json
    for f in ("comparison.json", "comparison.md", "intervals.png"):
        assert (tmp_path / "cmp" / f).is_file()
    md = (tmp_path / "cmp" / "comparison.md").read_text()
    assert md.startswith("| run |") and "PSIS-LOO ranks free first" in md


def test_compare_refuses_mixed_inputs_and_different_data(runs, tmp_path, capsys):
    root, out = runs
    d = out["free"][1]
    assert main(["compare", str(d), str(root / "fit.csv"), "--out", str(tmp_path)]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["compare", str(d), "--out", str(tmp_path)]) == 2
    assert "at least two" in capsys.readouterr().err
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(d / "summary.json", other)
    idata = load_idata(d / "posterior.nc")
    for g in idata.groups():
        idata[g].attrs["data_sha256"] = json.dumps(["0" * 64])
    save_idata(idata, other / "posterior.nc")
    assert main(["compare", str(d), str(other), "--out", str(tmp_path)]) == 2
    assert "different data" in capsys.readouterr().err


# ---------------------------------------------------------------- bad configurations
GOOD = {
    "data": 'files = ["fit.csv"]',
    "model": 'damping = "free"',
    "sampler": "walkers = 30\nsteps = 50\nburn = 10",
}


def _toml(**changes) -> str:
    sections = {**GOOD, **changes}
    return "\n".join(f"[{k}]\n{v}" for k, v in sections.items() if v is not None)


BAD = [
    # (description, config text, text the one-line message must contain)
    ("unknown section", _toml(samplr="walkers = 30"), "[samplr]"),
    ("unknown key", _toml(sampler="walker = 30"), "[sampler.walker]"),
    ("missing data", _toml(data=None), "[data.files]"),
    ("missing data file", _toml(data='files = ["nope.csv"]'), "[data.files]"),
    ("unreadable data file", _toml(data='files = ["garbage.csv"]'), "[data.files]"),
    ("missing held-out file", _toml(data='files = ["fit.csv"]\nheldout = ["nope.csv"]'),
     "[data.heldout]"),
    ("walkers not a number", _toml(sampler='walkers = "many"'), "[sampler.walkers]"),
    ("odd walkers", _toml(sampler="walkers = 31\nsteps = 50\nburn = 10"), "[sampler.walkers]"),
    ("too few walkers for 15 parameters",
     _toml(sampler="walkers = 20\nsteps = 50\nburn = 10"), "[sampler.walkers]"),
    ("burn beyond steps", _toml(sampler="walkers = 30\nsteps = 50\nburn = 50"),
     "[sampler.burn]"),
    ("thin zero", _toml(sampler="walkers = 30\nsteps = 50\nburn = 10\nthin = 0"),
     "[sampler.thin]"),
    ("unknown move", _toml(sampler='walkers = 30\nsteps = 50\nburn = 10\nmoves = "gibbs"'),
     "[sampler.moves]"),
    ("unknown damping", _toml(model='damping = "viscous"'), "[model.damping]"),
    ("unknown extension", _toml(model='extensions = ["magic"]'), "[model.extensions]"),
    ("unknown noise", _toml(likelihood='noise = "pink"'), "[likelihood.noise]"),
    ("prior lo above hi", _toml(priors="m1 = [3.0, 1.0]"), "[priors.m1]"),
    ("prior of an unknown parameter", _toml(priors="k9 = [0.0, 1.0]"), "[priors.k9]"),
    ("AR coefficient prior beyond 1", _toml(priors="phi_1 = [0.5, 1.5]"), "[priors.phi_1]"),
    ("negative noise prior", _toml(priors="sigma2 = [-1.0, 1.0]"), "[priors.sigma_2]"),
    ("prior of an extension that is not sampled",
     _toml(model='extensions = ["motor_lag"]', priors="Fc1 = [0.0, 1.0]"),
     "[priors.Fc1]"),
    ("two plant-side effects",
     _toml(model='extensions = ["coulomb_friction", "backlash"]'), "[model.extensions]"),
    ("extension without free damping",
     _toml(model='damping = "proportional"\nextensions = ["motor_lag"]'), "[model.damping]"),
    ("springs do not match the data", _toml(rig="springs_n_m = [774.0, 770.0]"),
     "[rig.springs_n_m]"),
    ("output folder escapes", _toml(outputs='dir = "../../elsewhere"'), "[outputs.dir]"),
    ("checkpoint interval zero", _toml(outputs="checkpoint_every_s = 0"),
     "[outputs.checkpoint_every_s]"),
    ("too few live points", _toml(evidence="enabled = true\nnlive = 3"), "[evidence.nlive]"),
    ("counts factor zero", _toml(data='files = ["fit.csv"]\nm_per_count = 0'),
     "[data.m_per_count]"),
    ("not TOML", "[data\nfiles = [", "not valid TOML"),
]


@pytest.fixture(scope="module")
def bad_dir(runs):
    root, _ = runs
    (root / "garbage.csv").write_text("this is,not\na record\n")
    return root


@pytest.mark.parametrize("desc,text,key", BAD, ids=[b[0] for b in BAD])
def test_bad_config_is_refused_before_sampling(bad_dir, tmp_path, capsys, desc, text, key):
    cfg = bad_dir / "bad.toml"
    cfg.write_text(text)
    out = tmp_path / "never"
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("bayesmodal run: error: ")
    assert key in err, err
    assert not out.exists()  # nothing sampled, no folder made


def test_bad_config_exit_code_from_the_console(bad_dir, tmp_path):
    cfg = bad_dir / "bad_console.toml"
    cfg.write_text(_toml(sampler='walkers = 30\nsteps = 50\nburn = 10\nseed = -1',
                         model='damping = "viscous"'))
    proc = subprocess.run([sys.executable, "-m", "bayesmodal", "run", str(cfg), "--out",
                           str(tmp_path / "never")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1
    # every problem, on that one line
    assert "[sampler.seed]" in lines[0] and "[model.damping]" in lines[0]
    assert not (tmp_path / "never").exists()


@pytest.mark.slow  # four small leave-one-record-out studies (45 s)
def test_calibrated_temperature_run_reuses_the_calibrations_check(tmp_path, monkeypatch):
    """With ``temperature = "loro"`` the leave-one-record-out study at the chosen
    temperature is measured by the calibration; the run's [crossval] check is that study,
    not a second identical one: one study per calibrated temperature, no more."""
    import bayesmodal.inference.crossval as cv
    import bayesmodal.inference.temperature as temperature_module
    import bayesmodal.runs.runner as runner_module

    calls = []
    real = cv.crossval

    def counting(*args, **kwargs):
        calls.append(args[1].temperature)
        return real(*args, **kwargs)

    # the calibration and the run's own check each call crossval: count both
    monkeypatch.setattr(temperature_module, "crossval", counting)
    monkeypatch.setattr(runner_module, "crossval", counting)
    cfg = _checked_pair(tmp_path, "loro", 600, likelihood='temperature = "loro"\n')
    assert main(["run", str(cfg), "--out-root", str(tmp_path / "out"), "--quiet"]) == 0
    s = _summary(tmp_path / "out" / "loro")
    measured = [c["temperature"] for c in s["temperature_calibration"]["curve"]]
    assert sorted(calls) == sorted(measured)
    chosen = s["temperature_calibration"]["temperature"]
    assert chosen in calls
    assert s["crossval"]["spec"]["temperature"] == chosen
    # a resumed run of the same configuration takes the temperature it started with from
    # the folder (no study at all); another configuration calibrates again
    from bayesmodal.runs.folder import RunFolder
    from bayesmodal.runs.runner import _temperature, prepare_run

    folder = RunFolder(tmp_path / "out" / "loro")
    prep = prepare_run(load_config(cfg))
    calls.clear()
    t, cal, study = _temperature(prep, folder)
    assert (t, calls, study) == (chosen, [], None)
    assert cal == s["temperature_calibration"]
    other = cfg.read_text().replace("seed = 3", "seed = 4")
    (tmp_path / "other.toml").write_text(other)
    t2, _, study2 = _temperature(prepare_run(load_config(tmp_path / "other.toml")), folder)
    assert len(calls) == len(measured) and study2 is not None


def test_a_checked_run_keeps_the_clock_out_of_its_summary(tmp_path):
    """With [crossval] enabled, the folds' times and evaluation rates go to timing.json,
    so the same configuration on the same data gives the same summary.json byte for byte
    (what ``bayesmodal rerun`` compares, tests/test_reproducibility.py); the check's
    results stay in summary.json."""
    cfg = _checked_pair(tmp_path, "cv", 400, outputs="ema = false\n")
    assert main(["run", str(cfg), "--out-root", str(tmp_path / "out"), "--quiet"]) == 0
    one = tmp_path / "out" / "cv"
    s = _summary(one)
    assert [r["name"] for r in s["crossval"]["records"]] == ["a", "b"]
    assert all("elapsed_s" not in r and "evaluations_per_s" not in r
               for r in s["crossval"]["records"]) and "wall_time_s" not in s["crossval"]
    clock = json.loads((one / "timing.json").read_text())["crossval"]
    assert clock["wall_time_s"] > 0 and all(r["elapsed_s"] > 0 for r in clock["records"])
