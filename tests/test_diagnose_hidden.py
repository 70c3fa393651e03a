"""diagnose: hidden effects are named with their location, clean data give "none".

The data come from tests/hidden_effects.py: the independent reference simulators of
tests/reference_sim.py with the effect's size and location drawn from the seed (never
passed to the package), sensor noise and encoder quantisation.  posterior=False (the
decision does not depend on the sampler); 19 null data sets, the fewest that calibrate a
5 % false-positive rate.  More seeds: benchmarks/detection.py.
"""

import json

import numpy as np
import pytest
from hidden_effects import EFFECTS, make

from bayesmodal import ConfigError, DataError
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, save_csv
from bayesmodal.discrepancy.diagnosis import (
    CAUSES,
    DEFAULT_CANDIDATES,
    calibrate_null,
    diagnose,
    fit_noise,
    infer_quantum,
    quantise,
)
from bayesmodal.fit import fit_lsq
from bayesmodal.model.system import LinearModel, Rig

N_NULL = 19
#: Record length (12 s) and one seed per case (the failure message prints the drawn sizes).
N_SAMPLES = 2400
SEEDS = {"none": 1, "coulomb_friction": 1, "motor_lag": 1, "input_delay": 1, "backlash": 1,
         "cubic_stiffness": 2, "input_saturation": 1}


@pytest.fixture(scope="module")
def diagnosed():
    cache = {}

    def get(effect):
        if effect not in cache:
            h = make(None if effect == "none" else effect, SEEDS[effect], N_SAMPLES)
            cache[effect] = (h, diagnose(h.experiment, posterior=False, n_null=N_NULL,
                                         rng=SEEDS[effect]))
        return cache[effect]

    return get


#: Cases run in the slow suite only (each a minute or more, for the default suite's
#: 15-minute budget; the default suite keeps the clean record, friction and the rest).
SLOW_CASES = ("motor_lag", "backlash")


@pytest.mark.parametrize("effect", [pytest.param(e, marks=pytest.mark.slow)
                                    if e in SLOW_CASES else e
                                    for e in ("none",) + EFFECTS])
def test_names_the_hidden_cause_and_where(diagnosed, effect):
    h, d = diagnosed(effect)
    msg = (f"truth {h.effect} at {h.location} size {h.theta_extension}; got {d.cause} at "
           f"{d.location}; ranking {[(c.name, round(c.score, 1), c.passes) for c in d.ranking]}")
    assert d.cause == h.effect, msg
    assert d.location == h.location, msg
    assert d.discrepancy == (effect != "none")
    # explained: the accepted model's residuals pass every residual diagnostic
    assert d.explained == (not any(t.exceeded for t in d.tests_after))
    if effect == "none":
        assert d.statistic <= d.threshold and d.parameters == {}
        return
    # the accepted model explains the data: fit close to 100 % (noise of about one count)
    after = np.array(d.gain["fit_percent_after"])
    before = np.array(d.gain["fit_percent_before"])
    assert np.all(after >= before) and np.all(after > 97), msg
    assert d.ranking[0].name == effect and d.ranking[0].significant
    # forward selection starts from it (it may add an effect the kernels' difference
    # from the reference simulators asks for: docs/diagnose.md, "Several effects")
    assert d.causes[0].cause == effect and d.effects[0] == effect, (msg, d.notes)


def test_recovers_the_effect_size(diagnosed):
    # Coulomb level of the cart that has friction, within 10 % (fit of an exact model to
    # data with sub-count noise; the Laplace interval brackets it)
    h, d = diagnosed("coulomb_friction")
    i = h.location[0]
    fc = d.parameters[f"Fc{i}"]
    assert fc.median == pytest.approx(h.theta_extension[i - 1], rel=0.1)
    h, d = diagnosed("input_delay")
    assert d.parameters["delay_s"].median == pytest.approx(h.theta_extension[0], abs=1e-3)


def test_result_schema_and_json(diagnosed):
    _, d = diagnosed("input_saturation")
    out = json.loads(d.to_json())
    for key in ("discrepancy", "cause", "location", "parameters", "ranking", "gain", "tests"):
        assert key in out
    assert out["cause"] in CAUSES
    assert {"median", "lo", "hi"} <= set(out["parameters"]["v_sat"])
    assert len(out["ranking"]) == len(DEFAULT_CANDIDATES)
    assert all("score" in c for c in out["ranking"])
    # forward selection: the causes in order, the first one is the top-level cause
    assert out["causes"][0]["cause"] == out["cause"] == "input_saturation"
    assert out["causes"][0]["location"] == out["location"]
    assert {"in_sample", "held_out"} <= set(out["causes"][0]["gain"])
    assert out["effects"][0] == "input_saturation"
    assert {"fit_percent_before", "fit_percent_after", "delta_elpd",
            "delta_elpd_se"} <= set(out["gain"])
    assert all({"name", "statistic", "threshold"} <= set(t) for t in out["tests"])
    with pytest.raises(AttributeError):
        d.cause = "none"


def test_cli_json_on_a_csv(tmp_path, capsys):
    from bayesmodal.cli import main

    h = make(None, 9, n_samples=1000)
    path = tmp_path / "clean.csv"
    save_csv(h.experiment, path)
    code = main(["diagnose", str(path), "--json", "--no-posterior", "--null", "19",
                 "--seed", "3", "--plots", str(tmp_path / "plots")])
    assert code == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["cause"] == "none" and out["discrepancy"] is False and out["location"] is None
    assert out["causes"] == []
    assert out["explained"] is True
    # progress on stderr: plain lines in a log (no carriage returns or escape codes)
    assert "diagnose: least-squares fit of the linear model" in cap.err
    assert "diagnose: null calibration: 19/19 data sets (100 %)" in cap.err
    assert "\r" not in cap.err and "\x1b" not in cap.err
    assert "warning" not in cap.err  # nothing left unexplained
    assert len(list((tmp_path / "plots").glob("*.png"))) >= 9
    assert main(["diagnose", str(path), "--null", "19", "--no-posterior", "--quiet"]) == 0
    cap = capsys.readouterr()
    text = cap.out
    assert "cause: none" in text and "whiteness" in text and "explained: yes" in text
    assert cap.err == ""  # --quiet: no progress
    assert main(["diagnose", str(path), "--null", "5", "--no-posterior"]) == 2
    assert "null" in capsys.readouterr().err
    assert main(["diagnose", str(path), "--null", "19", "--no-posterior", "--starts", "0"]) == 2
    assert "n_starts" in capsys.readouterr().err
    assert main(["diagnose", str(path), "--null", "19", "--no-posterior",
                 "--max-effects", "0"]) == 2
    assert "max_effects" in capsys.readouterr().err


# ------------------------------------------------------------------ calibration pieces
def test_monte_carlo_threshold_is_the_order_statistic():
    h = make(None, 5, n_samples=800)
    model = LinearModel(Rig(), "free")
    fit = fit_lsq(h.experiment, model)
    r = h.experiment.y_m - h.experiment.y_m.mean(0)  # any residual works for the noise
    noise = fit_noise([r], ECP_M_PER_COUNT)
    cal = calibrate_null([h.experiment], model, fit.theta, noise=noise, n_null=19, rng=0)
    # 19 nulls at alpha 5 %: the threshold is the largest null maximum
    assert cal.threshold == pytest.approx(np.max(cal.null_max))
    assert cal.p_value(cal.threshold + 1.0) == pytest.approx(1 / 20)
    assert cal.p_value(-np.inf) == 1.0
    with pytest.raises(ConfigError, match="at least 19"):
        calibrate_null([h.experiment], model, fit.theta, noise=noise, n_null=10)


def test_fit_noise_recovers_ar1_and_removes_quantisation():
    rng = np.random.default_rng(4)
    q = ECP_M_PER_COUNT
    N = 200_000
    phi, sigma = 0.6, 1.5 * q
    e = sigma * rng.standard_normal(N)
    x = np.empty(N)
    x[0] = e[0] / np.sqrt(1 - phi**2)
    for k in range(1, N):
        x[k] = phi * x[k - 1] + e[k]
    smooth = 40 * q * np.sin(np.arange(N) * 0.001)
    r = quantise(smooth + x, q) - smooth
    nm = fit_noise([r[:, None]], q)
    # standard errors at N = 2e5 are below 0.5 %; quantisation would bias phi by ~4 %
    assert nm.phi[0] == pytest.approx(phi, abs=0.01)
    assert nm.sigma_m[0] == pytest.approx(sigma, rel=0.02)


def test_infer_quantum():
    h = make(None, 6, n_samples=400)
    assert infer_quantum([h.experiment]) == ECP_M_PER_COUNT
    e = Experiment(h.experiment.t_s, h.experiment.v_volt, h.experiment.y_m + 1e-7)
    assert infer_quantum([e]) == 0.0


def test_bad_input_is_refused():
    h = make(None, 7, n_samples=800)
    with pytest.raises(ConfigError, match="train index"):
        diagnose(h.experiment, train=3, posterior=False, n_null=19)
    with pytest.raises(ConfigError, match="unknown candidate"):
        diagnose(h.experiment, candidates=["magic"], posterior=False, n_null=19)
    for bad in (0, 1.5, True):
        with pytest.raises(ConfigError, match="n_starts"):
            diagnose(h.experiment, posterior=False, n_null=19, n_starts=bad)
    with pytest.raises(DataError, match="no experiments"):
        diagnose([], posterior=False)
    two = Experiment(h.experiment.t_s, h.experiment.v_volt, h.experiment.y_m[:, :2])
    with pytest.raises(DataError, match="outputs"):
        diagnose(two, posterior=False, n_null=19)


def test_profiled_ar1_terms_match_the_likelihood_module():
    # the workflow's scoring equals the inference module's exact AR(1) density at the
    # moment estimates of (sigma, phi)
    from bayesmodal.discrepancy.diagnosis.scoring import ar1_pointwise
    from bayesmodal.inference.likelihood import ar1_terms

    rng = np.random.default_rng(8)
    r = np.cumsum(rng.standard_normal((500, 3)), axis=0) * 1e-6 + rng.standard_normal(
        (500, 3)) * 1e-6
    phi = np.sum(r[1:] * r[:-1], axis=0) / np.sum(r[:-1] ** 2, axis=0)
    sigma = np.sqrt(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0))
    ref = ar1_terms(r[None], sigma[None], phi[None])[0]
    assert np.allclose(ar1_pointwise([r]), ref.ravel(), rtol=1e-12, atol=1e-9)


def test_best_starts_are_the_cheapest_grid_points_in_order():
    from bayesmodal.discrepancy.diagnosis.starts import best_start, best_starts
    from bayesmodal.fit import fit_lsq
    from bayesmodal.fit.effects import extension_residuals
    from bayesmodal.model.effects import EXTENSIONS
    from bayesmodal.model.system import LinearModel, Rig

    h = make("coulomb_friction", 3, n_samples=800)
    rig = Rig()
    ext = EXTENSIONS["coulomb_friction"]
    lin = fit_lsq([h.experiment], LinearModel(rig, "free"))
    starts = best_starts(ext, rig, lin.theta, [h.experiment], 4)
    assert starts.shape == (4, len(ext.names(rig)))
    np.testing.assert_array_equal(starts[0], best_start(ext, rig, lin.theta, [h.experiment]))
    cost = np.sum(extension_residuals(ext, rig, starts, [h.experiment]) ** 2, axis=1)
    assert np.all(np.diff(cost) >= 0), cost
    assert len({tuple(s) for s in starts}) == 4


@pytest.mark.slow
def test_partly_explained_misfit_is_not_explained():
    # hidden friction plus a disturbance outside the catalogue (a 7 Hz pick-up of 6
    # encoder counts on every cart): friction is accepted, the residuals stay coloured
    h = make("coulomb_friction", 1, N_SAMPLES)
    e = h.experiment
    hum = 6 * ECP_M_PER_COUNT * np.sin(2 * np.pi * 7.0 * e.t_s)[:, None]
    y = np.round((e.y_m + hum) / ECP_M_PER_COUNT) * ECP_M_PER_COUNT
    d = diagnose(Experiment(e.t_s, e.v_volt, y, name="friction+hum"), posterior=False,
                 n_null=N_NULL, rng=1)
    rest = [t.name for t in d.tests_after if t.exceeded]
    assert d.discrepancy
    assert d.explained == (not rest)
    assert d.cause == "coulomb_friction" and rest, (d.cause, rest, d.notes)
    assert not d.explained
    assert any("still beyond threshold" in n for n in d.notes)
    from bayesmodal.cli._diagnose import _report, caveats

    (line,) = caveats(d)
    assert line.startswith("coulomb_friction explains part of the misfit; still beyond "
                           f"threshold: {', '.join(sorted(rest))}")
    assert "explained: no" in _report(d)
    # intervals of unconverged chains are labelled as such, with a warning naming the fix
    import dataclasses

    u = dataclasses.replace(d, interval_method="posterior_unconverged")
    assert "UNCONVERGED" in _report(u)
    assert any("did not converge" in c and "--steps" in c for c in caveats(u))
