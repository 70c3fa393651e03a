"""Joint least squares of several records with per-record parameters, and its
leave-one-record-out check (bayesmodal.fit.records)."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import measured
from reference_effects import simulate_linear_chain_ref
from reference_sim import RTOL

from bayesmodal import ConfigError, DataError
from bayesmodal.data import Experiment
from bayesmodal.fit.records import (
    fit_records_lsq,
    loro_lsq,
    new_record_theta,
    simulate_model,
)
from bayesmodal.metrics import fit_percent
from bayesmodal.model.effects import get_extension
from bayesmodal.model.system import Rig

RIG = Rig()
DT = 0.005
OFFSET = get_extension("input_offset")
#: A rig with non-zero dampers between the carts (inside the bounds, not on them).
LIN = np.array([6.0, 1.565, 1.461, 1.146, 2.9, 1.8, 2.0, 0.3, 0.2])


def _inputs(N=500):
    t = np.arange(N) * DT
    a = np.zeros(N)
    a[1:11] = 3.0
    a[200:320] = 0.5
    b = 0.4 * np.sin(2 * np.pi * (0.8 + 2.0 * t / t[-1]) * t)
    return t, a, b


def _truth():
    """Two records with their own gain and offset, shared physics."""
    th = np.tile(np.r_[LIN, 0.0], (2, 1))
    th[:, 0] = (6.0, 5.0)
    th[:, -1] = (0.02, -0.01)
    return th


def _records(theta, sigma, rng):
    t, a, b = _inputs()
    exps = []
    for r, v in enumerate((a, b)):
        y = simulate_model(OFFSET, RIG, theta[r:r + 1], Experiment(t, v, np.zeros((t.size, 3))))[0]
        exps.append(Experiment(t, v, y + sigma * rng.standard_normal(y.shape), name=f"r{r}"))
    return exps


def test_simulation_is_the_independent_reference_chain():
    """simulate_model of the offset model against the event-free reference of tests/."""
    t, a, _ = _inputs()
    th = _truth()[0]
    e = Experiment(t, a, np.zeros((t.size, 3)))
    y = simulate_model(OFFSET, RIG, th[None], e)[0]
    ref = simulate_linear_chain_ref(RIG.springs_n_m, th[:9], a, DT, v_offset=th[9])
    # the reference integrates the ODE at RTOL (tolerance as in test_effects_combined)
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e3 * RTOL * np.max(np.abs(ref)))
    # negative control: without the offset the reference is far off
    ref0 = simulate_linear_chain_ref(RIG.springs_n_m, th[:9], a, DT)
    assert np.max(np.abs(ref0 - ref)) > 1e6 * RTOL * np.max(np.abs(ref))


def test_joint_fit_recovers_per_record_gains_within_standard_errors():
    rng = np.random.default_rng(7)
    truth = _truth()
    sigma = 2e-5
    exps = _records(truth, sigma, rng)
    start = truth.copy()
    start[:, 0] *= (1.08, 0.93)
    start[:, 4:7] *= 1.2
    fit = fit_records_lsq(exps, OFFSET, RIG, theta0=start, max_nfev=60)
    # shared columns are shared, per-record columns are each record's own
    shared = [i for i, n in enumerate(fit.names) if n not in fit.per_record]
    np.testing.assert_array_equal(fit.theta[0, shared], fit.theta[1, shared])
    assert fit.per_record == ("g_v", "v_offset")
    # standard errors of the per-record gains from the sandwich of the weighted problem at
    # the truth (weights: 1 / |y - mean y| per record and cart), central differences
    norms = [np.linalg.norm(e.y_m - e.y_m.mean(axis=0), axis=0) for e in exps]

    def resid(z):  # z = (shared 8, g_v[2], v_offset[2]) natural units
        th = np.tile(np.r_[0.0, z[:8], 0.0], (2, 1))
        th[:, 0], th[:, -1] = z[8:10], z[10:12]
        out = [((simulate_model(OFFSET, RIG, th[r:r + 1], e)[0]) / norms[r]).ravel()
               for r, e in enumerate(exps)]
        return np.concatenate(out)

    z0 = np.r_[truth[0, 1:9], truth[:, 0], truth[:, -1]]
    h = 1e-6 * np.maximum(np.abs(z0), 1e-2)
    J = np.column_stack([(resid(z0 + hi * np.eye(12)[i]) - resid(z0 - hi * np.eye(12)[i]))
                         / (2 * hi) for i, hi in enumerate(h)])
    w = np.concatenate([np.tile(1 / n, e.n_samples) for n, e in zip(norms, exps, strict=True)])
    bread = np.linalg.inv(J.T @ J)
    cov = sigma**2 * bread @ (J.T * w**2) @ J @ bread
    se = np.sqrt(np.diag(cov))
    est = np.r_[fit.theta[0, 1:9], fit.theta[:, 0], fit.theta[:, -1]]
    z = np.abs(est - z0) / se
    assert np.all(z[8:] < 4.5), z  # 4.5 sd: two-sided p < 1e-5 for each of four
    # negative control: the start was many standard errors away
    start_z = np.abs(np.r_[start[:, 0], start[:, -1]] - z0[8:]) / se[8:]
    assert np.max(start_z) > 100


def test_cost_is_the_fit_deficit_of_the_returned_estimate():
    rng = np.random.default_rng(3)
    exps = _records(_truth(), 1e-4, rng)
    fit = fit_records_lsq(exps, OFFSET, RIG, theta0=_truth(), max_nfev=3)
    fits = np.array([fit_percent(e.y_m, simulate_model(OFFSET, RIG, fit.theta[r:r + 1], e)[0])
                     for r, e in enumerate(exps)])
    np.testing.assert_array_equal(fits, fit.fit_percent)
    tol = 100 * fits.size * np.finfo(float).eps
    assert abs(fit.cost - 0.5 * np.sum((1 - fits / 100) ** 2)) <= tol


def test_new_record_takes_geometric_mean_gain_and_mean_offset():
    th = _truth()
    names = OFFSET.names(RIG)
    new = new_record_theta(th, names, ("g_v", "v_offset"))
    assert new[0] == pytest.approx(np.sqrt(6.0 * 5.0), rel=4 * np.finfo(float).eps)
    assert new[-1] == pytest.approx(0.005, rel=4 * np.finfo(float).eps)
    np.testing.assert_array_equal(new[1:9], th[0, 1:9])


def test_loro_predicts_a_record_of_the_same_rig_exactly_without_noise():
    """Same gain and offset in both records: the held-out record is the model itself."""
    th = _truth()
    th[:, 0], th[:, -1] = 5.5, 0.01
    exps = _records(th, 0.0, np.random.default_rng(0))
    loro = loro_lsq(exps, OFFSET, RIG, theta0=th, max_nfev=5)
    # started at the truth with zero residuals, every fold stays there (gradient zero)
    np.testing.assert_allclose(loro.theta, th, rtol=1e-12)
    assert np.all(loro.fit_percent > 100 - 1e-6)
    # negative control: a wrong shared gain loses the held-out fit
    bad = new_record_theta(th * np.r_[1.1, np.ones(9)], OFFSET.names(RIG), ("g_v",))
    y = simulate_model(OFFSET, RIG, bad[None], exps[0])[0]
    assert np.all(fit_percent(exps[0].y_m, y) < 95)


def test_nothing_per_record_shares_every_parameter():
    rng = np.random.default_rng(11)
    exps = _records(_truth(), 1e-4, rng)
    fit = fit_records_lsq(exps, OFFSET, RIG, per_record=(), theta0=_truth()[0], max_nfev=3)
    assert fit.per_record == ()
    np.testing.assert_array_equal(fit.theta[0], fit.theta[1])
    assert new_record_theta(fit.theta, fit.names, ()).tolist() == fit.theta[0].tolist()


def test_bad_inputs_are_refused_with_the_fix():
    t, a, _ = _inputs()
    e = Experiment(t, a, np.zeros((t.size, 3)), name="z")
    with pytest.raises(ConfigError, match="not parameters of the model"):
        fit_records_lsq([e], OFFSET, RIG, per_record=("k9",))
    with pytest.raises(DataError, match="no records"):
        fit_records_lsq([], OFFSET, RIG)
    with pytest.raises(DataError, match="at least two"):
        loro_lsq([e], OFFSET, RIG)


def _docs_script(name: str):
    """The docs script ``docs/<name>.py`` as a module (docs/ on the path while it loads,
    for the scripts that import docs/_measured.py)."""
    docs = Path(__file__).resolve().parents[1] / "docs"
    spec = importlib.util.spec_from_file_location(name, docs / f"{name}.py")
    script = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(docs))
    try:
        spec.loader.exec_module(script)
    finally:
        sys.path.remove(str(docs))
    return script


@pytest.mark.slow
def test_documented_table_is_what_its_estimates_give():
    """docs/figures/discrepancy_table.json (docs/discrepancy.md section 6): every fit it
    reports, in sample and held out, is the fit of the estimate it stores."""
    root = Path(__file__).resolve().parents[1]
    table = json.loads((root / "docs" / "figures" / "discrepancy_table.json").read_text())
    recs = [measured(f"{n}.mat") for n in table["records"]]
    script = _docs_script("make_discrepancy_table")
    steps = {s[0]: s[1] for s in script.STEPS}
    for label in table["steps"]:
        ext = None if steps[label] is None else get_extension(steps[label])
        for kind in ("joint", "loro"):
            item = (table[kind] or {}).get(label)
            if item is None:
                continue
            theta = np.array(item["theta"])
            for r, e in enumerate(recs):
                f = fit_percent(e.y_m, simulate_model(ext, RIG, theta[r:r + 1], e)[0])
                # stored rounded to 0.1
                np.testing.assert_allclose(f, item["fit"][r], rtol=0, atol=0.05 + 1e-9,
                                           err_msg=f"{kind} {label} {e.name}")


@pytest.mark.slow
def test_documented_cart3_check_is_what_its_estimates_give():
    """docs/figures/impulses_cart3_check.json (docs/discrepancy.md section 7): every fit it
    reports is the fit of the estimate it stores, no refit costs more than the end-stop
    fit it started from, and the claims of the section hold: of the models tried only
    masses per record lift the impulses' cart 3 to 92 %, and no start of the multistart
    does."""
    root = Path(__file__).resolve().parents[1]
    check = json.loads((root / "docs" / "figures" / "impulses_cart3_check.json").read_text())
    table = json.loads((root / "docs" / "figures" / "discrepancy_table.json").read_text())
    recs = [measured(f"{n}.mat") for n in table["records"]]
    script = _docs_script("make_impulses_cart3_check")
    rows = {**{k: (f"{script.BASE}+{script.EXTRA[k][0]}", v) for k, v in check["extra"].items()},
            **{k: (script.BASE, v) for k, v in check["per_record"].items()}}
    assert set(rows) == set(script.EXTRA) | set(script.PER_RECORD)
    for label, (effects, item) in rows.items():
        ext = get_extension(effects)
        theta = np.array(item["theta"])
        for r, e in enumerate(recs):
            f = fit_percent(e.y_m, simulate_model(ext, RIG, theta[r:r + 1], e)[0])
            # stored rounded to 0.01
            np.testing.assert_allclose(f, item["fit"][r], rtol=0, atol=0.005 + 1e-9,
                                       err_msg=f"{label} {e.name}")
        assert item["cost"] <= check["base"]["cost"], label
        assert (item["fit"][0][2] >= 92.0) == (label == "masses per record"), label
    # the multistart (--multistart N): each run's fit is its estimate's, its summary is
    # its runs', and no start of the end-stop model lifts cart 3 to 92 %
    ms = check["multistart"]
    ext = get_extension(script.BASE)
    assert len(ms["runs"]) == ms["n"]
    for k, item in enumerate(ms["runs"]):
        theta = np.array(item["theta"])
        for r, e in enumerate(recs):
            f = fit_percent(e.y_m, simulate_model(ext, RIG, theta[r:r + 1], e)[0])
            np.testing.assert_allclose(f, item["fit"][r], rtol=0, atol=0.005 + 1e-9,
                                       err_msg=f"start {k} {e.name}")
    cart3 = np.array([item["fit"][0][2] for item in ms["runs"]])
    cost = np.array([item["cost"] for item in ms["runs"]])
    assert ms["cart3_max"] == cart3.max() < 92.0
    assert ms["n_lower_cost"] == int(np.sum(cost < check["base"]["cost"]))
    assert ms["cart3_at_best_cost"] == cart3[np.argmin(cost)]


@pytest.mark.slow
def test_documented_target_front_is_what_its_estimates_give():
    """docs/figures/target_front.json (docs/discrepancy.md section 7): each weighting's fit
    percentages and margins are those of the estimate it stores, its start is `diagnose`'s
    estimate from the committed diagnosis, and the section's claims hold: `diagnose`'s
    own fit, the unweighted, the spread-weighted and the record-and-cart joint fits each
    miss a target, and a fast-sweep weighting of the traced trade meets every one."""
    root = Path(__file__).resolve().parents[1]
    front = json.loads((root / "docs" / "figures" / "target_front.json").read_text())
    script = _docs_script("make_target_front")
    ext, rig, theta = script.diagnosed_model()
    rows = front["rows"]
    np.testing.assert_array_equal(rows["diagnose"]["theta"], theta)
    recs = [measured(f"{n}.mat") for n in front["records"]]
    for label, item in rows.items():
        th = np.array(item["theta"])
        fits = [fit_percent(e.y_m, ext.simulate(rig, th[None], e.v_volt, e.dt)[0])
                for e in recs]
        # stored rounded to 0.01
        np.testing.assert_allclose(fits, item["fit"], rtol=0, atol=0.005 + 1e-9,
                                   err_msg=label)
        margin = min(min(f) - front["targets"][n]
                     for f, n in zip(fits, front["records"], strict=True))
        assert item["min_margin"] == pytest.approx(margin, abs=0.005 + 1e-9), label
        assert item["meets_all"] == (margin >= 0.0), label
    for label in ("diagnose", "unweighted", "spread", "record and cart"):
        assert not rows[label]["meets_all"], label
    assert any(r["meets_all"] for k, r in rows.items() if k.startswith("fast sweep")), rows
