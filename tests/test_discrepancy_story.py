"""The key claims of docs/discrepancy.md, re-checked on the measured data.

Skipped without the measured records.  The least-squares claims are recomputed with the
same functions as ``docs/make_discrepancy_figures.py``; the Bayesian-criterion claim uses
short posterior runs (the margin is thousands of nats, far beyond what the length of the
chain changes); the numbers written to ``docs/figures/discrepancy.json`` must agree with
the recomputation.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from bayesmodal.data import find_data

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "docs" / "make_discrepancy_figures.py"
NUMBERS = ROOT / "docs" / "figures" / "discrepancy.json"

pytestmark = pytest.mark.slow


def _script():
    spec = importlib.util.spec_from_file_location("make_discrepancy_figures", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def story():
    for name in ("data_impulses", "data_steps", "data_sine_sweep_fast",
                 "data_sine_sweep_slow"):
        if find_data(f"ecp210-3dof/{name}.mat") is None:
            pytest.skip(f"measured record {name}.mat not found")
    mod = _script()
    recs = mod.load_records()
    lin = mod.linear_part(recs)
    diag = mod.diagnostics_part(recs, lin["theta"])
    # the tutorial's friction least squares: three starts with scaled-down dampers
    fr = mod.friction_part(recs, lin["_lsq"], n_starts=3, damper_scales=(1.0, 0.3, 0.1))
    return mod, recs, lin, diag, fr


def test_linear_misfit(story):
    """The linear model fits the impulses at about 81 % and predicts the others worse."""
    _, _, lin, _, _ = story
    f = lin["fits"]
    assert np.all(np.abs(np.array(f["data_impulses"]) - 81.5) < 1.5)
    assert np.mean(f["data_steps"]) < np.mean(f["data_impulses"]) - 5
    assert np.mean(f["data_sine_sweep_fast"]) < 50
    assert np.mean(f["data_sine_sweep_slow"]) < 55


def test_diagnostics_point_at_friction(story):
    """The residual diagnostics that detect an effect on the impulses suggest friction."""
    _, _, _, diag, _ = story
    detected = {n: d for n, d in diag.items() if not n.startswith("_") and d["detected"]}
    friction_tests = {"friction_signature", "decay_envelope", "stick"}
    hits = [n for n in detected if "coulomb_friction" in detected[n]["suggests"]]
    assert len(set(hits) & friction_tests) >= 2, {n: d["summary"] for n, d in diag.items()
                                                  if not n.startswith("_")}


def test_friction_least_squares(story):
    """Least squares of friction on the impulses: more than 5 points on every impulse
    cart and more than 10 on both held-out sweeps; friction takes over viscous damping,
    and the drive gain falls below the 5.9-6.1 N/V of the step plateaus (section 3)."""
    mod, recs, lin, _, fr = story
    a, b = np.array(lin["fits"]["data_impulses"]), np.array(fr["fits"]["data_impulses"])
    assert np.all(b > a + 5)
    for name in ("data_sine_sweep_fast", "data_sine_sweep_slow"):
        assert np.mean(fr["fits"][name]) > np.mean(lin["fits"][name]) + 10, name
    assert np.all(np.array(fr["theta"][4:7]) < np.array(lin["theta"][4:7]))
    static = mod.static_gain_part(recs)
    assert 5.9 < static["g_v_min"] and static["g_v_max"] < 6.15
    assert fr["theta"][0] < static["g_v_min"] - 0.3


def test_numbers_in_the_docs_match(story):
    """docs/figures/discrepancy.json holds what the code computes now.

    The least-squares friction fit sits in a flat, rough valley (docs/discrepancy.md,
    section 3): a change of the simulator at the level of rounding moves its held-out
    predictions by points, so only its in-sample fit is compared (within 1 point); the
    linear fit and the posterior numbers are compared as written.
    """
    if not NUMBERS.is_file():
        pytest.fail("docs/figures/discrepancy.json missing: run docs/make_discrepancy_figures.py")
    num = json.loads(NUMBERS.read_text())
    _, _, lin, _, fr = story
    for name, vals in lin["fits"].items():
        np.testing.assert_allclose(num["linear"]["fits"][name], vals, atol=0.1, err_msg=name)
    np.testing.assert_allclose(num["friction_multistart"]["fits"]["data_impulses"],
                               fr["fits"]["data_impulses"], atol=1.0)
    post = num.get("posterior")
    assert post is not None, "the posterior part is missing (run without --quick)"
    assert post["elpd"]["decisive"] and post["elpd"]["preferred"] == "friction"


@pytest.mark.xfail(strict=True, reason=(
    "the friction posterior on the impulses settles at Fs1 1.43 N and predicts the "
    "held-out steps 14 points worse than the linear model (docs/discrepancy.md, section 5)"))
def test_posterior_heldout_steps_gain_in_the_docs():
    """The issue's target on the shipped runs: held-out steps at least 10 points better
    (posterior predictive medians of the runs fitted on the impulses, mean over the
    carts), every cart better.  Checked on docs/figures/discrepancy.json."""
    if not NUMBERS.is_file():
        pytest.fail("docs/figures/discrepancy.json missing: run docs/make_discrepancy_figures.py")
    held = json.loads(NUMBERS.read_text())["posterior"]["heldout"]
    gain = (np.array(held["friction"]["data_steps"]["fit_median"])
            - np.array(held["linear"]["data_steps"]["fit_median"]))
    assert np.mean(gain) >= 10 and np.all(gain > 5), gain


def test_least_squares_heldout_steps_gain(story):
    """Section 3's table at fixed points, not along the optimiser's path: at the friction
    optimum recorded in docs/figures/discrepancy.json the impulse cost is the recorded one
    and the held-out steps gain on every cart over the recorded linear fit (4-7 points).
    Which of the valley's near-equal optima the three-start fit reaches depends on scipy
    (with 1.17 it is the basin of cost 3.93e-3, whose steps gain 0-2 points: section 3's
    ``basins``), so the fit reached now is only required to be one of them: no costlier
    than the costliest recorded basin, and far below the linear fit."""
    mod, recs, lin, _, fr = story
    doc = json.loads(NUMBERS.read_text())
    th_f, th_l = np.array(doc["friction"]["theta"]), np.array(doc["linear"]["theta"])
    imp = recs["data_impulses"]
    r = imp.y_m - mod.predict(th_f, imp, mod.FRICTION)
    # the cost is half the sum of squared residuals (m^2): recomputed, it differs from the
    # recorded one by the rounding of a sum of y.size squares at most (8.8e-14 measured)
    assert 0.5 * np.sum(r**2) == pytest.approx(doc["friction"]["cost"],
                                               rel=imp.y_m.size * np.finfo(float).eps)
    fits_f = mod.fits_on(th_f, recs, mod.FRICTION)["data_steps"]
    fits_l = mod.fits_on(th_l, recs)["data_steps"]
    gain = np.array(fits_f) - np.array(fits_l)
    assert np.all(gain > 2), gain
    costliest = max(b["cost"] for b in doc["basins"])
    lin_cost = 0.5 * np.sum((imp.y_m - mod.predict(np.array(lin["theta"]), imp)) ** 2)
    assert fr["cost"] <= costliest * (1 + 1e-6) < lin_cost, (fr["cost"], costliest, lin_cost)


def test_the_impulses_do_not_identify_the_steps_predicting_fit(story):
    """Section 5's trade-off at its recorded points, not along the optimiser's path: the
    friction fit with the steps weighted 0.03 (docs/figures/discrepancy.json, "tradeoff")
    costs the impulse fit less than half a point against the unweighted one and predicts
    the steps at least 10 points better than the linear model, so the target is
    reachable by the model class (an existence claim, checked at the point the optimiser
    found).  Where a fit started now lands depends on the optimiser's path: the BLAS
    threads of its SVD alone moved the weighted fit's steps from 89 % to 77 %, so no test
    asserts it.  The fits are recomputed from the recorded parameters."""
    mod, recs, lin, _, _ = story
    doc = json.loads(NUMBERS.read_text())
    points = {p["weight_steps"]: p for p in doc["tradeoff"]}
    fits = {w: mod.fits_on(np.array(points[w]["theta"]), recs, mod.FRICTION)
            for w in (0.0, 0.03)}
    for w, f in fits.items():  # the recorded fits are those of the recorded parameters,
        # both rounded to 0.1 points (fits_on): one rounding step apart at most
        assert np.allclose(f["data_steps"], points[w]["fits"]["data_steps"], rtol=0,
                           atol=0.1 * (1 + 1e-9))
    lin_steps = np.mean(lin["fits"]["data_steps"])
    assert np.mean(fits[0.03]["data_steps"]) >= lin_steps + 10
    assert (np.mean(fits[0.0]["data_impulses"]) - np.mean(fits[0.03]["data_impulses"])
            < 0.5)


def test_bayesian_criterion_prefers_friction(story):
    """PSIS-LOO ELPD of friction against linear, from posterior runs on the impulses."""
    from bayesmodal.inference import elpd_change, sample_posterior

    mod, recs, lin, _, fr = story
    imp = recs["data_impulses"]
    kw = dict(noise="ar1", n_steps=300, burn=200, rng=5, warn=False)
    run_lin = sample_posterior(imp, mod.MODEL, n_walkers=32, start=lin["_lsq"], **kw)
    run_fr = sample_posterior(imp, mod.MODEL, extension="coulomb_friction", n_walkers=44,
                              start=fr["_fit"], **kw)
    ch = elpd_change(run_lin, run_fr, labels=("linear", "friction"))
    assert ch.decisive and ch.preferred == "friction", ch.reading
    assert ch.delta > 10 * ch.se
