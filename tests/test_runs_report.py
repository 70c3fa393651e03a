"""The report's first screen (``bayesmodal.runs.verdict``) and the predictive coverage.

Summaries are fabricated dicts with the keys ``summary.json`` has, so each answer can be
driven to each state; the coverage is checked on records drawn from the noise model itself.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from bayesmodal.data import Experiment
from bayesmodal.inference import Likelihood, simulate_noise
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.crosscheck import predictive_coverage
from bayesmodal.runs.report import render_report
from bayesmodal.runs.verdict import COVERAGE_TOLERANCE, coverage_status, run_verdict

TRUTH = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])


def _iv(med, lo, hi):
    return {"median": med, "lo": lo, "hi": hi, "hdi_lo": lo, "hdi_hi": hi}


def _diag(name, detected, p):
    return {"name": name, "detected": detected, "p_value": p, "statistic": 1.0,
            "suggests": [], "location": None, "summary": f"{name} summary"}


def _summary(*, converged=True, n_fail=0, coverage=(0.9, 0.91, 0.89), lsq_inside=True):
    n_all = 8
    diags = [_diag(f"check_{k}", k < n_fail, 1e-5 if k < n_fail else 0.4)
             for k in range(n_all)]
    return {
        "damping": "free", "noise": "ar1", "prob": 0.9,
        "parameters": {"m1": _iv(1.57, 1.56, 1.58), "sigma_1": _iv(2e-5, 1.9e-5, 2.1e-5)},
        "omega_rad_s": _iv([8.2], [8.1], [8.3]), "zeta": _iv([0.1], [0.09], [0.11]),
        "damped_rad_s": _iv([8.1], [8.0], [8.2]),
        "diagnostics": {"max_rhat": 1.01 if converged else 1.3, "min_ess": 800,
                        "n_over_tau": 80, "acceptance": 0.3, "converged": converged,
                        "problems": [] if converged else ["max R-hat 1.300 (m1) >= 1.05"],
                        "tau": {"m1": 20.0}},
        "lsq_comparison": [{"quantity": "m1", "unit": "kg", "lsq": 1.57 if lsq_inside else 1.6,
                            "median": 1.57, "lo": 1.56, "hi": 1.58, "inside": lsq_inside}],
        "crosscheck": {
            "residuals": [{"experiment": "fit", "rms_m": [1e-5], "fit_percent": [99.0],
                           "acf_lag1": [0.01], "white_band": 0.02, "diagnostics": diags}],
            "lsce": [{"experiment": "fit", "omega_rad_s": [8.2], "zeta": [0.1], "error": None,
                      "omega_matched": [8.2], "zeta_matched": [0.1]}]},
        "heldout": {"experiments": ["held"], "lpd": 100.0, "lpd_per_obs": 8.0,
                    "fitted_lpd_per_obs": 8.5, "fit_percent_median": [[98.0]],
                    "fit_percent_lo": [[97.0]], "fit_percent_hi": [[99.0]],
                    "records": [{"name": "held", "coverage_90": list(coverage),
                                 "width_90": [1e-4] * 3, "fit_percent": [98.0] * 3}]},
    }


def test_all_fine_is_the_only_green_verdict():
    v = run_verdict(_summary())
    assert v.ok and [a.status for a in v.answers] == ["ok", "ok", "ok"]
    assert v.sentence.startswith("The sampler converged and the model passes")
    assert "held-out 90 % band covers 89-91 %" in v.sentence


@pytest.mark.parametrize("change, which", [
    ({"converged": False}, 0),
    ({"n_fail": 7}, 1),
    ({"coverage": (0.68, 0.70, 0.73)}, 2),
])
def test_each_failure_turns_its_answer_red(change, which):
    v = run_verdict(_summary(**change))
    assert not v.ok
    assert [a.status == "bad" for a in v.answers].count(True) >= 1
    assert v.answers[which].status == "bad"


def test_the_rejected_model_sentence_gives_its_numbers():
    v = run_verdict(_summary(n_fail=7, coverage=(0.68, 0.70, 0.73), lsq_inside=False))
    assert v.sentence == (
        "The sampler converged, but the model does not explain the data: 7 of 8 residual "
        "checks fail; the intervals below are conditional on this model and are too narrow "
        "for the next record (held-out 90 % band covers 68-73 %).")
    assert "1 of 1 least-squares parameter values" in v.intervals.text
    assert "conditional on this model" in v.intervals.text


def test_without_new_data_the_intervals_are_untested():
    s = _summary()
    del s["heldout"]
    v = run_verdict(s)
    assert v.intervals.status == "unknown" and not v.ok
    assert "untested on new data" in v.sentence


def _render(tmp_path, s):
    d = tmp_path / "run"
    d.mkdir(parents=True)
    (d / "summary.json").write_text(json.dumps(s))
    return render_report(d)


def test_report_opens_with_the_verdict_and_shows_crossval(tmp_path):
    s = _summary(n_fail=7)
    s["crossval"] = {"method": "each of 3 records left out in turn", "records": [
        {"name": "rec_a", "coverage_90": [0.61, 0.64, 0.66], "width_90": [0.73] * 3,
         "fit_percent": [71.0, 70.0, 69.0], "band_factor_90": [2.41, 2.2, 2.05]},
        {"name": "rec_b", "coverage_90": [0.9, 0.92, 0.88], "width_90": [3e-3] * 3,
         "fit_percent": [80.0, 81.0, 82.0]}]}
    page = _render(tmp_path, s)
    v = run_verdict(s)
    first = page.index("<h2")
    # the sentence and the three questions come before any section
    assert page.index(v.sentence) < first
    for a in v.answers:
        assert page.index(a.question) < first
    assert page.index("Leave-one-record-out") < first
    for name, cov in (("rec_a", "61"), ("rec_b", "92")):
        assert page.index(name) < first and f">{cov}</span>" in page
    assert "left out" in page and "0.73" in page  # band width / record sd
    # the factor that would calibrate the band, where crossval reported it (rec_b: none)
    assert "width factor that would cover 90 %" in page and "2.41, 2.20, 2.05" in page
    # leaving records out changes the third answer
    assert "leaving one record out, the 90 % band covers 61-92 %" in v.intervals.text
    assert "class='verdict big bad'" in page


@pytest.mark.parametrize("n_fail", [0, 7])
def test_coverage_colours_follow_the_sentence(tmp_path, n_fail):
    """A band that covers more than nominal (100 % for a 90 % band) is amber and the
    sentence calls it wider than needed; one that covers less is red and called too
    narrow; within the window green.  The window edges come from COVERAGE_TOLERANCE."""
    tol = COVERAGE_TOLERANCE
    edge_lo, edge_hi = round(0.9 - tol, 6), round(0.9 + tol, 6)
    cells = {"ok": [edge_lo, 0.9, edge_hi], "wide": [1.0, edge_hi + 0.02],
             "narrow": [0.5, edge_lo - 0.02]}
    for status, values in cells.items():
        assert all(coverage_status(c) == status for c in values), status
    expect = {"ok": "ok", "wide": "wide", "narrow": "bad"}
    words = {"wide": "wider than needed", "narrow": "too narrow"}
    for status, values in cells.items():
        s = _summary(n_fail=n_fail, coverage=(0.9, *values[:2]))
        page = _render(tmp_path / f"{status}{n_fail}", s)
        v = run_verdict(s)
        for c in values[:2]:
            assert f"<span class='{expect[status]}'>{100 * c:.0f}</span>" in page, (status, c)
        if status in words:
            assert words[status] in v.sentence
        else:
            assert "wider than needed" not in v.sentence and "too narrow" not in v.sentence
    # the fitted, in-sample rows and the left-out rows are coloured the same way
    s = _summary(n_fail=n_fail)
    s["crossval"] = {"records": [{"name": "rec_w", "coverage_90": [1.0, 0.99, 0.98],
                                  "width_90": [2.0] * 3, "fit_percent": [80.0] * 3}]}
    del s["heldout"]   # left-out records only (the main job): the legend is shown there
    page = _render(tmp_path / f"cv{n_fail}", s)
    assert "<span class='wide'>100</span>" in page
    assert page.count("<span class='wide'>amber</span>: wider than needed") == 1
    assert "wider than needed" in run_verdict(s).sentence
    assert "<span class='ok'>100</span>" not in page


def test_report_without_crossval_has_no_crossval_table(tmp_path):
    page = _render(tmp_path, _summary())
    assert "Leave-one-record-out" not in page
    assert "class='verdict big ok'" in page


def test_noise_levels_are_shown_in_mm_like_the_residuals(tmp_path):
    page = _render(tmp_path, _summary())
    row = page[page.index("<td class=\"l\">sigma_1</td>"):][:200]
    assert "mm" in row and "0.02" in row


# ------------------------------------------------------------------ predictive coverage
def _noise_record(sigma, phi, n, seed):
    model = LinearModel(Rig(), "free")
    dt = 0.005
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(model, TRUTH, v, dt)
    y = y + simulate_noise(np.full((1, 3), sigma), np.full((1, 3), phi), n, rng=seed)[0]
    return model, Experiment(t, v, y, name="rec")


@pytest.mark.parametrize("scale, expect_ok", [(1.0, True), (0.5, False)])
def test_predictive_coverage_is_nominal_for_the_true_noise(scale, expect_ok):
    sigma, phi, n = 2e-5, 0.8, 3000
    model, e = _noise_record(sigma, phi, n, seed=5)
    lik = Likelihood(model, (e,), "ar1")
    theta = np.r_[TRUTH, np.full(3, scale * sigma), np.full(3, phi)]
    cov = predictive_coverage(lik, np.tile(theta, (300, 1)), prob=0.9, max_draws=300,
                              rng=1)[0]
    # AR(1) samples: about n (1 - phi) / (1 + phi) independent ones per output; binomial
    # error of the pooled coverage, and 4 of them
    n_eff = 3 * n * (1 - phi) / (1 + phi)
    se = np.sqrt(0.9 * 0.1 / n_eff)
    c = float(np.mean(cov["coverage"]))
    if expect_ok:
        assert abs(c - 0.9) < 4 * se, c
    else:  # negative control: a noise level half the truth gives a band far too narrow
        assert c < 0.9 - 10 * se, c
    assert cov["width_m"].shape == (3,) and np.all(cov["width_m"] > 0)
    # copies of one draw: the half-width of the band is about 1.645 marginal sd
    sd = scale * sigma / np.sqrt(1 - phi**2)
    assert np.allclose(cov["width_m"], 2 * 1.645 * sd, rtol=0.1)


def test_summary_is_not_modified_by_the_verdict():
    s = _summary(n_fail=3)
    before = copy.deepcopy(s)
    run_verdict(s)
    assert s == before


def test_diagnostics_rows_say_pass_or_fail_with_their_test(tmp_path):
    s = _summary(n_fail=1)
    s["crosscheck"]["residuals"][0]["diagnostics"].append(
        {"name": "decay_envelope", "detected": True, "p_value": None, "statistic": 0.451,
         "threshold": 0.3, "suggests": ["coulomb_friction"], "location": None,
         "summary": "free decay linear"})
    page = _render(tmp_path, s)
    assert "statistic 0.451 vs threshold 0.3" in page
    assert page.count("<span class='bad'>fails</span>") == 2
    assert page.count("<span class='ok'>passes</span>") == 7
    # the white-noise limit of the lag-1 autocorrelation is explained with its value
    assert "here the limit is &plusmn;0.020" in page


def _with_reference(rec: dict, *, pit, factor_pit, expected=(0.7, 1.0),
                    factor_expected=(0.65, 1.45), factor=1.0) -> dict:
    """A scored record carrying the fields of its coverage reference."""
    n = len(rec["coverage_90"])
    return {**rec, "coverage_90_expected": [list(expected)] * n,
            "coverage_90_pit": [pit] * n, "band_factor_90": [factor] * n,
            "band_factor_90_expected": [list(factor_expected)] * n,
            "band_factor_90_pit": [factor_pit] * n, "record_pit_90": pit,
            "record_band_factor_pit_90": factor_pit}


def test_verdict_judges_coverage_against_what_a_calibrated_band_shows(tmp_path):
    """With a coverage reference, 99 % coverage of a record on which calibrated bands
    cover 70-100 % is no evidence against the band (green, no flag), while 83 % with
    misses 1.9 times the band where a calibrated band needs at most 1.45 is too narrow;
    a record is flagged only in a tail of VERDICT_FAMILY_LEVEL / (4 n_records)."""
    from bayesmodal.runs.verdict import VERDICT_FAMILY_LEVEL, record_status

    s = _summary()
    del s["heldout"]
    typical = _with_reference({"name": "rec_ok", "coverage_90": [0.99, 0.98, 0.99],
                               "width_90": [1.3] * 3, "fit_percent": [75.0] * 3},
                              pit=0.8, factor_pit=0.2, factor=0.7)
    far = _with_reference({"name": "rec_far", "coverage_90": [0.83, 0.82, 0.83],
                           "width_90": [0.6] * 3, "fit_percent": [60.0] * 3},
                          pit=0.2, factor_pit=1.0, factor=1.9)
    s["crossval"] = {"records": [typical]}
    v = run_verdict(s)
    assert v.intervals.status == "ok" and "too narrow" not in v.sentence
    assert "a calibrated band would cover 70-100 %" in v.intervals.text
    page = _render(tmp_path / "a", s)
    assert "<span class='ok'>99</span>" in page and "70-100" in page
    # without the reference the same coverage is amber (the fixed tolerance)
    bare = {k: typical[k] for k in ("name", "coverage_90", "width_90", "fit_percent")}
    assert record_status(bare) == "wide"
    s["crossval"] = {"records": [typical, far]}
    v = run_verdict(s)
    assert v.intervals.status == "bad" and "too narrow" in v.sentence
    assert "rec_far (its misses lie further out" in v.intervals.text
    assert "1.9 times as wide, a calibrated one at most 1.4" in v.intervals.text
    page = _render(tmp_path / "b", s)
    assert "<span class='bad'>83</span>" in page
    # the family-wise tail: just inside it is not flagged, just beyond it is
    tail = VERDICT_FAMILY_LEVEL / (4 * 2)
    for u, want in ((1.0 - 0.9 * tail, "wide"), (1.0 - 1.1 * tail, "ok"),
                    (0.9 * tail, "narrow"), (1.1 * tail, "ok")):
        rec = {**far, "record_band_factor_pit_90": 0.5, "record_pit_90": u}
        assert record_status(rec, n_records=2) == want, (u, want)
