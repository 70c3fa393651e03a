"""Forward selection in diagnose: several hidden effects are named one after another.

Data: tests/hidden_pairs.py (independent reference simulators, never the package's
kernels; sizes and locations drawn from the seed).  The reduced version of
benchmarks/detection_pairs.py: one seed per case, which the benchmark's measured rate
(docs/diagnose.md) makes a test that fails with probability at most the benchmark's
miss rate; a wrong answer prints what was found.
"""

import itertools
import json
from types import SimpleNamespace

import numpy as np
import pytest
from hidden_effects import make
from hidden_pairs import CASES, judge, make_case

from bayesmodal import ConfigError, ModelError
from bayesmodal.data import ECP_M_PER_COUNT
from bayesmodal.discrepancy.diagnosis import diagnose
from bayesmodal.discrepancy.diagnosis.candidates import REFINES
from bayesmodal.discrepancy.diagnosis.gains import loro_gain
from bayesmodal.fit import fit_extension_lsq, fit_lsq
from bayesmodal.fit.effects import extension_fit_at
from bayesmodal.model.effects import EXTENSIONS, get_extension
from bayesmodal.model.system import LinearModel, Rig

N_NULL = 19
N_SAMPLES = 2400


def _two_records(case, seed):
    """Two records of one rig: the first from the reference simulator, the second the
    same response with more sensor noise, quantised again (same input; the benchmark's
    ``_records``)."""
    h = make_case(case, seed, 1600) if case else make(None, seed, 1600)
    return _pairs_benchmark()._records(h.experiment, seed, 2)


def test_loro_gain_is_significant_for_a_hidden_offset_and_not_without():
    rig = Rig()
    model = LinearModel(rig, "free")
    off = EXTENSIONS["input_offset"]
    out = {}
    for case in ("input_offset", None):
        exps = _two_records(case, 4)
        lin = fit_lsq(exps, model)
        f = fit_extension_lsq(exps, off, rig, linear=lin, n_starts=2)
        out[case] = loro_gain(exps, rig, None, lin.theta, off, f.theta, lin)
        assert len(out[case]["records"]) == 2
        assert out[case]["delta_lpd"] == pytest.approx(sum(out[case]["records"]))
        assert np.shape(out[case]["fit_percent"]) == (2, 3)
        assert np.shape(out[case]["fit_percent_current"]) == (2, 3)
    # the offset's held-out predictions fit better, record by record and cart by cart
    assert np.all(np.greater(out["input_offset"]["fit_percent"],
                             out["input_offset"]["fit_percent_current"])), out
    # the offset predicts each held-out record far better than the linear model ...
    assert out["input_offset"]["z"] > 5, out
    # ... and without an offset it gains nothing beyond its standard error (negative
    # control; one extra parameter fitted on the other record)
    assert out[None]["z"] < 3, out


#: Cases whose test seed forward selection is known to miss (strict: a fix shows).  Empty
#: since 24 Nov, fifth session: directional levels on cart 1 (found as equal friction plus
#: an offset and a dead band) and friction on cart 3 behind a 0.1 V dead band (found as
#: directional friction with the dead band) were local least-squares fits stopped on the
#: terraces of the stick-slip cost; the global search of forward selection finds both
#: (docs/diagnose.md).
KNOWN_MISSES: set[str] = set()


@pytest.mark.slow
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(
    strict=True, reason="measured miss, see KNOWN_MISSES")) if c in KNOWN_MISSES else c
    for c in CASES])
def test_forward_selection_names_every_effect(case):
    h = make_case(case, 1, N_SAMPLES)
    d = diagnose(h.experiment, posterior=False, n_null=N_NULL, rng=1)
    ok, found = judge(h, d)
    fw = d.detail["forward"]
    assert ok, (f"truth {h.effects} sizes {h.sizes}; found {found}; stop: "
                f"{fw.stop if fw else None}; notes {d.notes}")
    # the first cause is the top-level one; causes are listed in the order found
    assert d.cause == d.causes[0].cause and d.location == d.causes[0].location
    out = json.loads(d.to_json())
    assert [c["cause"] for c in out["causes"]] == [c.cause for c in d.causes]
    for c in out["causes"]:
        assert {"cause", "location", "parameters", "gain"} <= set(c)
        assert {"in_sample", "held_out"} <= set(c["gain"])
        assert c["gain"]["in_sample"]["delta_lpd"] > 0
    assert [[c["cause"] for c in st["candidates"]] for st in out["forward_steps"]] == [
        [c["cause"] for c in st["candidates"]] for st in fw.steps]
    assert all(c["cost_ratio"] > 0 for st in out["forward_steps"] for c in st["candidates"])
    # every effect added after the first passed its likelihood-ratio test
    for step in fw.steps:
        acc = [r for r in step["candidates"] if r["significant"]]
        assert all(r["p_value"] < d.alpha and r["bic_gain"] > 0 for r in acc)


def test_max_effects_is_validated():
    h = make(None, 7, n_samples=800)
    for bad in (0, 1.5, True):
        with pytest.raises(ConfigError, match="max_effects"):
            diagnose(h.experiment, posterior=False, n_null=19, max_effects=bad)


def test_refinements_are_catalogued():
    for new, old in REFINES.items():
        assert new in EXTENSIONS and old in EXTENSIONS
        assert len(EXTENSIONS[new].specs(Rig())) > len(EXTENSIONS[old].specs(Rig()))


def test_text_and_json_list_the_causes_in_order():
    from bayesmodal.cli._diagnose import _report
    from bayesmodal.discrepancy.diagnosis import Cause, Diagnosis

    ins = {"delta_lpd": 2000.0, "lr_statistic": 4000.0, "n_params": 6, "p_value": 0.0,
           "bic_gain": 3950.0, "fit_percent": [[99.0, 99.0, 99.0]]}
    ho = {"delta_lpd": 500.0, "se": 20.0, "z": 25.0, "records": [250.0, 250.0]}
    c1 = Cause("coulomb_friction", [2], "cart 2", {"Fc2": 0.4},
               {"in_sample": ins, "held_out": None})
    c2 = Cause("input_offset", None, "motor input", {"v_offset": -0.1},
               {"in_sample": dict(ins, n_params=1), "held_out": ho})
    d = Diagnosis(True, "coulomb_friction", [2], "cart 2", True, 5.0, 3.0, 0.05, (), (),
                  (), {}, {}, {}, "laplace", ("a", "b"), (0, 1), 19, 0.05, "rule",
                  causes=(c1, c2), effects=("coulomb_friction", "input_offset"))
    text = _report(d)
    i1 = text.index("cause 1: coulomb_friction at cart 2")
    i2 = text.index("cause 2: input_offset at motor input")
    assert i1 < i2 and "held out 500.0 +- 20.0 nats" in text
    out = json.loads(d.to_json())
    assert [c["cause"] for c in out["causes"]] == ["coulomb_friction", "input_offset"]
    assert out["causes"][1]["gain"]["held_out"]["records"] == [250.0, 250.0]
    assert out["causes"][0]["gain"]["held_out"] is None
    assert out["effects"] == ["coulomb_friction", "input_offset"]
    assert out["forward_steps"] == []  # no forward selection in the detail
    step = {"model": "coulomb_friction", "T": 9.0, "threshold": 3.0,
            "candidates": [{"cause": "input_offset", "delta_lpd": 2000.0, "cost_ratio": 0.4,
                            "held_out": ho, "significant": True}]}
    d2 = Diagnosis(True, "coulomb_friction", [2], "cart 2", True, 5.0, 3.0, 0.05, (), (),
                   (), {}, {}, {}, "laplace", ("a", "b"), (0, 1), 19, 0.05, "rule",
                   causes=(c1, c2), effects=("coulomb_friction", "input_offset"),
                   detail={"forward": SimpleNamespace(steps=(step,))})
    assert json.loads(d2.to_json())["forward_steps"] == [step]
    text2 = _report(d2)
    assert "forward step 2 after coulomb_friction (T = 9.0, threshold 3.0)" in text2
    assert "* input_offset" in text2 and "cost x0.40  held out 500.0 +- 20.0" in text2
    assert "forward step" not in text


def test_train_takes_indices_in_one_argument_so_data_may_follow(capsys):
    from bayesmodal.cli import build_parser, main

    a = build_parser().parse_args(["diagnose", "--train", "0,1", "a.mat", "b.mat"])
    assert a.train == [0, 1] and a.data == ["a.mat", "b.mat"]
    assert build_parser().parse_args(["diagnose", "a.mat", "--train", "1"]).train == [1]
    with pytest.raises(SystemExit) as stop:
        main(["diagnose", "--train", "x", "a.mat"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "record indices such as 0 or 0,1" in err[0]
    assert build_parser().parse_args(["diagnose", "a.mat"]).weights == "none"
    assert build_parser().parse_args(["diagnose", "--weights", "spread", "a.mat"]).weights \
        == "spread"
    with pytest.raises(SystemExit) as stop:
        main(["diagnose", "--weights", "equal", "a.mat"])
    assert stop.value.code == 2
    assert "invalid choice: 'equal'" in capsys.readouterr().err


@pytest.mark.slow
def test_every_candidate_is_fitted_so_a_tied_start_cannot_hide_the_dead_band():
    """Friction on cart 3 behind a 0.11 V dead band (pairs case, seed 1): after friction,
    every candidate whose grid holds its null value starts at the current cost exactly
    (saturation, offset and dead band: the same simulation), and a capped step fits the
    tied ones in the catalogue's order: with three fits per step (the old cap) the dead
    band once came behind motor lag, delay and saturation, which all lost.  Fitting every
    candidate finds it significant at the step's own level; one fit per step is the
    negative control (the tie puts saturation first whatever the starts of lag and delay,
    which the friction fit of the first step moves: with scipy 1.17 they start above the
    tie and a cap of three reached the dead band)."""
    h = make_case("coulomb_friction+drive_deadband", 1, N_SAMPLES)
    out = {}
    for cap in (1, None):
        d = diagnose(h.experiment, posterior=False, n_null=N_NULL, rng=1, max_effects=2,
                     max_fits=cap)
        step = d.detail["forward"].steps[0]
        out[cap] = {r["cause"]: r for r in step["candidates"]}
    assert "drive_deadband" not in out[1] and len(out[1]) == 1, out[1]
    db = out[None]["drive_deadband"]
    assert db["significant"] and db["delta_lpd"] > 0, db
    assert "drive_deadband" in [c.cause for c in d.causes]
    # the before/after plot draws the final model (it once simulated the first cause's
    # name with the first step's parameters, which fails once that cause is refined)
    import matplotlib
    matplotlib.use("Agg")
    from bayesmodal.plots.diagnosis import plot_before_after
    ax = plot_before_after(d, h.experiment)
    final = d.detail["forward"].fit.extension
    assert set(final.name.split("+")) == set(d.effects)
    assert f"({final.name})" in ax[0].get_title()


def test_final_causes_take_location_and_parameters_from_the_final_fit():
    """A cause found first with friction spread over carts 1 and 2 (the first step's fit,
    before the dead band was in the model) is reported where the final model puts it,
    cart 3, with the final fit's levels; a refinement simplified back keeps its gain and
    takes the simpler name; the gains stay those measured when each was found."""
    from types import SimpleNamespace

    from bayesmodal.discrepancy.diagnosis.forward import Cause
    from bayesmodal.discrepancy.diagnosis.location import final_causes
    from bayesmodal.model.effects import get_extension

    rig = Rig()
    model = LinearModel(rig, "free")
    lin = np.array([6.2, 1.56, 1.46, 1.15, 2.9, 1.8, 2.0, 0.0, 0.0])
    names = ("coulomb_friction", "drive_deadband")
    ext = get_extension(list(names))
    theta = np.r_[lin, 0.0, 0.0, 0.9, 0.0, 0.0, 1.1, 0.12]
    fwd = SimpleNamespace(names=names, fit=SimpleNamespace(theta=ext.check(rig, theta)),
                          simplified=())
    first = Cause(cause="coulomb_friction", location=[1, 2], location_label="carts 1, 2",
                  parameters={"Fc1": 0.4, "Fc2": 0.3}, gain={"in_sample": {"delta_lpd": 5}})
    dead = Cause(cause="drive_deadband", location=None, location_label="input",
                 parameters={"v_dead": 0.1}, gain={"in_sample": {"delta_lpd": 7}})
    out = final_causes((first, dead), fwd, rig, model)
    assert [c.cause for c in out] == list(names)
    assert out[0].location == [3] and out[0].parameters["Fc3"] == 0.9
    assert out[0].gain == first.gain and out[1].parameters == {"v_dead": 0.12}
    # directional levels simplified back to equal ones: the simpler name, no 'replaces'
    fwd2 = SimpleNamespace(names=names, fit=fwd.fit,
                           simplified=(("coulomb_directional", "coulomb_friction"),))
    refined = Cause(cause="coulomb_directional", location=[3], location_label="cart 3",
                    parameters={}, gain={"in_sample": {"delta_lpd": 9}},
                    replaces="coulomb_friction")
    out2 = final_causes((refined, dead), fwd2, rig, model)
    assert out2[0].cause == "coulomb_friction" and out2[0].replaces is None
    assert out2[0].location == [3] and out2[0].gain == refined.gain


def _pairs_benchmark():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "benchmarks" / "detection_pairs.py"
    spec = importlib.util.spec_from_file_location("detection_pairs", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_pairs_benchmark_resumes_only_from_rows_made_with_the_same_settings(tmp_path, capsys):
    """``--resume`` keeps stored rows and runs nothing they hold; other settings: an error."""
    bench = _pairs_benchmark()
    out = tmp_path / "pairs.json"
    row = {"case": "input_offset", "seed": bench.SEED_OFFSET, "truth": {}, "found": [],
           "correct": True, "error": None, "seconds": 1.0}
    null = dict(row, case="none", found=[("none", None)])
    args = {"calibration_nulls": 19, "samples": 2400, "max_effects": 3}
    out.write_text(json.dumps({"rows": [row, null], "args": args}))
    assert bench.main(["--seeds", "1", "--nulls", "1", "--cases", "input_offset",
                       "--workers", "1", "--out", str(out), "--resume"]) == 0
    text = capsys.readouterr().out
    assert "[1/" not in text  # nothing was run again
    assert "input_offset" in text and "correct 100.0 %" in text
    # negative control: a record length the stored rows were not made with
    with pytest.raises(SystemExit, match="samples = 2400"):
        bench.main(["--seeds", "1", "--nulls", "1", "--samples", "1200", "--out", str(out),
                    "--resume"])
    # rows stored before --records existed were made with one record
    with pytest.raises(SystemExit, match="records = 1"):
        bench.main(["--seeds", "1", "--nulls", "1", "--records", "2", "--out", str(out),
                    "--resume"])


def test_pairs_benchmark_several_records_are_quantised_copies_with_more_noise():
    bench = _pairs_benchmark()
    e = make_case("input_offset", 3, 400).experiment
    exps = bench._records(e, 3, 3)
    assert len(exps) == 3 and exps[0] is e
    q = ECP_M_PER_COUNT
    for x in exps[1:]:
        np.testing.assert_array_equal(x.v_volt, e.v_volt)
        np.testing.assert_allclose(x.y_m / q, np.round(x.y_m / q), atol=1e-9)
        assert not np.array_equal(x.y_m, e.y_m)
    assert not np.array_equal(exps[1].y_m, exps[2].y_m)


def test_forward_steps_offer_exchanges_of_the_plant_side_effect():
    """Besides every effect that combines with the model, a step offers the model's
    plant-side effect exchanged for another one together with one input-side effect."""
    from bayesmodal.discrepancy.diagnosis.candidates import _options
    from bayesmodal.discrepancy.diagnosis.workflow import DEFAULT_CANDIDATES

    def side(n):
        return EXTENSIONS[n].side

    opts = _options(("backlash",), DEFAULT_CANDIDATES, set())
    keyed = {(a, d): names for a, d, names, _ in opts}
    assert keyed[(("input_offset",), None)] == ("backlash", "input_offset")
    assert keyed[(("coulomb_friction", "input_offset"), "backlash")] == (
        "coulomb_friction", "input_offset")
    for added, dropped, names, ext in opts:
        assert sum(side(n) != "input" for n in names) <= 1  # never two plant-side effects
        assert ext.name == "+".join(names) or set(ext.name.split("+")) == set(names)
        if len(added) == 2:  # an exchange: a plant-side effect for the dropped one
            assert dropped == "backlash" and side(added[0]) != "input"
            assert side(added[1]) == "input" and added[0] not in REFINES
    n_input = sum(side(c) == "input" for c in DEFAULT_CANDIDATES)
    n_plant = sum(side(c) != "input" and c not in REFINES for c in DEFAULT_CANDIDATES)
    assert sum(len(a) == 2 for a, *_ in opts) == (n_plant - 1) * n_input
    # a refinement replaces what it refines and is no exchange
    ref = [o for o in _options(("coulomb_friction",), DEFAULT_CANDIDATES, set())
           if o[0] == ("coulomb_directional",)]
    assert ref[0][1] == "coulomb_friction" and ref[0][2] == ("coulomb_directional",)
    # without a plant-side effect, and for rejected effects, nothing is exchanged
    assert all(len(a) == 1 for a, *_ in _options(("input_offset",), DEFAULT_CANDIDATES, set()))
    rej = _options(("backlash",), DEFAULT_CANDIDATES, {"input_offset"})
    assert not any("input_offset" in names for _, _, names, _ in rej)


def _forced_first(case, seed, first, from_truth=False):
    """Forward selection started from ``first`` (its local least-squares fit), whatever
    the first step would have chosen; ``from_truth``: that fit starts at the case's true
    linear parameters and the true sizes of ``first``."""
    from bayesmodal.discrepancy.diagnosis.final import outcomes as _outcomes
    from bayesmodal.discrepancy.diagnosis.forward import forward_select
    from bayesmodal.discrepancy.diagnosis.location import effect_location
    from bayesmodal.discrepancy.diagnosis.workflow import DEFAULT_CANDIDATES

    h = make_case(case, seed, N_SAMPLES)
    rig = Rig()
    exps = [h.experiment]
    lin = fit_lsq(exps, LinearModel(rig, "free"))
    if from_truth:
        theta0 = np.r_[h.theta_lin, h.sizes[first]]
        f = fit_extension_lsq(exps, EXTENSIONS[first], rig, theta0=theta0, linear=lin)
    else:
        f = fit_extension_lsq(exps, EXTENSIONS[first], rig, linear=lin, n_starts=3)
    fw = forward_select(exps, rig, first, f, DEFAULT_CANDIDATES, linear=lin,
                        quantum_m=ECP_M_PER_COUNT, n_null=N_NULL, alpha=0.05,
                        rng=np.random.default_rng(seed), outcomes=_outcomes,
                        location=effect_location, max_effects=3)
    return h, fw


@pytest.mark.slow
def test_an_exchange_mends_a_wrong_plant_side_effect_accepted_first():
    """The pair benchmark's friction + offset seed 20002: the first step accepted backlash
    (friction alone fits worse than the linear model there), and backlash could never
    be left.  Started from backlash, forward selection now exchanges it for friction on
    the true cart with the offset (the negative control, backlash + motor lag data, is
    the next test)."""
    h, fw = _forced_first("coulomb_friction+input_offset", 20002, "backlash")
    assert set(fw.names) == set(h.effects), (fw.names, fw.stop, fw.steps)
    fric = next(c for c in fw.added if c.cause == "coulomb_friction")
    assert fric.replaces == "backlash" and fric.location == h.effects["coulomb_friction"]


@pytest.mark.slow
def test_an_exchange_leaves_a_true_plant_side_effect_in_place():
    """Negative control of the exchange: on backlash + motor lag data (seed 20002), started
    from backlash fitted in the truth's basin, the backlash stays and the lag is added.

    The start is the truth's, not a local fit from the catalogue's starts: from those the
    backlash fit of this record closes the gap (gap 6e-27 m), and whether a later step
    then exchanges it turned on the rounding of the cubic spring's starts (1e-16 m), a
    test of an optimiser's path rather than of the exchange rule."""
    h2, fw2 = _forced_first("backlash+motor_lag", 20002, "backlash", from_truth=True)
    detail = ([(c.cause, c.replaces) for c in fw2.added], fw2.stop)
    assert set(fw2.names) == set(h2.effects), (fw2.names, detail)
    assert not any(c.replaces == "backlash" for c in fw2.added), detail


def test_intervals_fit_and_elpd_describe_the_final_model(monkeypatch):
    """Once forward selection changes the model (an effect added, refined or exchanged),
    the top-level intervals, fit percents and ELPD change are the final model's, not the
    first step's (which once showed a backlash's gap after it had been exchanged for
    friction).  Forward selection is replaced by a stub that returns a second effect, the
    motor lag, fitted jointly with the offset the first step accepts; the negative control
    is the same data with ``max_effects=1``."""
    from types import SimpleNamespace

    from bayesmodal.discrepancy.diagnosis import final as final_stage
    from bayesmodal.discrepancy.diagnosis.forward import Cause
    from bayesmodal.metrics import fit_percent
    from bayesmodal.model.effects import get_extension

    h = make_case("input_offset", 20000, N_SAMPLES)
    e = h.experiment
    rig = Rig()
    final = get_extension(["input_offset", "motor_lag"])
    seen = {}

    def stub(exps, rig_, first, first_fit, *args, **kwargs):
        seen["first"] = first_fit
        theta0 = np.r_[first_fit.theta, [s.scale for s in EXTENSIONS["motor_lag"].specs(rig_)]]
        fit = fit_extension_lsq(exps, final, rig_, theta0=theta0, max_nfev=20)
        lag = Cause(cause="motor_lag", location=None, location_label="motor input",
                    parameters={}, gain={"in_sample": {"delta_lpd": 0.0, "lr_statistic": 0.0,
                                                         "n_params": 1}})
        return SimpleNamespace(added=(lag,), names=("input_offset", "motor_lag"), fit=fit,
                               calibration=None, tests=(), stop="stub", steps=(),
                               simplified=())

    monkeypatch.setattr(final_stage, "forward_select", stub)
    d = diagnose(e, posterior=False, n_null=N_NULL, rng=1, max_effects=2)
    alone = diagnose(e, posterior=False, n_null=N_NULL, rng=1, max_effects=1)
    assert d.cause == alone.cause == "input_offset"
    fit = d.detail["forward"].fit
    names = list(final.extension_names(rig))
    p = len(fit.theta) - len(names)
    assert list(d.parameters) == names != list(alone.parameters)
    for i, n in enumerate(names):
        assert d.parameters[n].median == fit.theta[p + i]
    y = final.simulate(rig, fit.theta, e.v_volt, e.dt)
    assert d.gain["fit_percent_after"] == [np.asarray(fit_percent(e.y_m, y)).tolist()]
    assert d.gain["model"] == "input_offset+motor_lag" and alone.gain["model"] == "input_offset"
    # the stub started from the first step's fit, which is what max_effects=1 reports
    assert np.array_equal(seen["first"].theta, alone.detail["extension_fit"].theta)
    from bayesmodal.cli._diagnose import _report
    assert "final model: linear + input_offset+motor_lag" in _report(d)
    assert "forward selection: input_offset -> motor_lag; stopped: stub" in d.notes

    # the same effects, refitted by forward selection's backward check from a later
    # model's optimum (on the measured records an effect added and then removed left the
    # friction model at a better fit than the first step's): that fit is reported
    def refit(exps, rig_, first, first_fit, *args, **kwargs):
        theta0 = first_fit.theta.copy()
        theta0[-1] *= 0.5
        fit = fit_extension_lsq(exps, EXTENSIONS["input_offset"], rig_, theta0=theta0,
                                max_nfev=2)
        return SimpleNamespace(added=(), names=("input_offset",), fit=fit, calibration=None,
                               tests=(), stop="stub", steps=(), simplified=())

    monkeypatch.setattr(final_stage, "forward_select", refit)
    r = diagnose(e, posterior=False, n_null=N_NULL, rng=1, max_effects=2)
    theta = r.detail["forward"].fit.theta
    assert r.parameters["v_offset"].median == theta[-1] != alone.parameters["v_offset"].median
    assert "forward selection: input_offset; stopped: stub" in r.notes


def test_input_side_pairs_are_tried_only_when_no_single_candidate_gains(monkeypatch):
    """The second look of a forward step: when no single candidate is significant, every
    pair of input-side effects not in the model is fitted, tested at ``alpha`` over the
    singles and the pairs together; when a single one is significant, or the pair would
    exceed ``max_effects``, no pair is tried (negative controls).  ``_evaluate`` (fitting
    and testing) is replaced by a recorder; the recalibration is the real one."""
    from bayesmodal.discrepancy.diagnosis import forward
    from bayesmodal.discrepancy.diagnosis.final import outcomes as _outcomes
    from bayesmodal.discrepancy.diagnosis.location import effect_location
    from bayesmodal.discrepancy.diagnosis.workflow import DEFAULT_CANDIDATES

    h = make_case("coulomb_friction+input_offset", 3, 800)
    rig = Rig()
    exps = [h.experiment]
    lin = fit_lsq(exps, LinearModel(rig, "free"))
    first = fit_extension_lsq(exps, EXTENSIONS["coulomb_friction"], rig, linear=lin,
                              max_nfev=5)
    inputs = [c for c in DEFAULT_CANDIDATES if EXTENSIONS[c].side == "input"]
    ALPHA = 0.2  # four null sets calibrate it (a cheap recalibration)

    def run(significant_single, max_effects):
        calls = []

        def record(options, level, **kw):
            calls.append(([o[0] for o in options], level))
            if significant_single and len(calls) == 1:  # accept the model as it is
                return [{"cause": "stub", "added": (), "dropped": None,
                         "names": ("coulomb_friction",), "fit": first, "delta_lpd": 1.0,
                         "lr": 2.0, "n_params": 1, "p_value": 0.0, "bic_gain": 1.0,
                         "cost_ratio": 1.0, "held_out": None, "significant": True}]
            return []

        monkeypatch.setattr(forward, "_evaluate", record)
        fw = forward.forward_select(
            exps, rig, "coulomb_friction", first, DEFAULT_CANDIDATES, linear=lin,
            quantum_m=ECP_M_PER_COUNT, n_null=4, alpha=ALPHA, rng=np.random.default_rng(0),
            outcomes=_outcomes, location=effect_location, max_effects=max_effects,
            global_search=False)
        return calls, fw

    calls, fw = run(False, 3)
    if "pass" in fw.stop:  # the residuals of the short record passed: nothing to test
        pytest.skip(f"the friction fit's residuals pass on this record: {fw.stop}")
    assert len(calls) == 2, calls
    singles, pairs = calls
    assert all(len(a) == 2 and all(x in inputs for x in a) for a in pairs[0])
    assert sorted(tuple(sorted(a)) for a in pairs[0]) == sorted(
        tuple(sorted(a)) for a in itertools.combinations(inputs, 2))
    assert singles[1] == pytest.approx(ALPHA / len(singles[0]))
    assert pairs[1] == pytest.approx(ALPHA / (len(singles[0]) + len(pairs[0])))
    # negative controls: a pair would exceed max_effects; a single candidate gains
    calls2, _ = run(False, 2)
    assert len(calls2) == 1 and calls2[0][0] == singles[0]
    calls3, _ = run(True, 3)
    # the step with a significant single accepts it: the next call is the next step's
    # singles, not this step's pairs
    assert len(calls3) >= 2 and calls3[0][0] == calls3[1][0] == singles[0]


def _lag_setup(effect, seed=5, n=1200):
    """A record with a hidden ``effect`` (or none), the linear fit, the input offset
    fitted, and the offset + motor lag model fitted from it."""
    h = make_case(effect, seed, n) if effect in CASES else make(effect, seed, n)
    rig = Rig()
    exps = [h.experiment]
    lin = fit_lsq(exps, LinearModel(rig, "free"))
    off = EXTENSIONS["input_offset"]
    both = get_extension(["input_offset", "motor_lag"])
    f_off = fit_extension_lsq(exps, off, rig, linear=lin, n_starts=2)
    starts = [np.r_[f_off.theta, tau] for tau in (0.005, 0.02)]
    f_both = min((fit_extension_lsq(exps, both, rig, theta0=s, linear=lin, max_nfev=40)
                  for s in starts), key=lambda f: f.cost)
    return rig, exps, lin, off, both, f_off, f_both


def test_an_addition_is_tested_against_the_current_model_at_its_own_optimum():
    """A candidate's in-sample gain is measured from the current model's best known
    point: its fit or its value at the candidate's optimum without the added effect.  A
    motor lag at ``tau`` = 1e-14 s (no lag) on top of a better offset than the current
    (unconverged) fit gains nothing then, where the plain difference credits it with the
    refit's gain; on data with a hidden lag the lag keeps its gain (negative control)."""
    from bayesmodal.discrepancy.diagnosis.gains import (
        _in_sample,
        _lpd,
        _reference,
        _simulate,
    )

    rig, exps, lin, off, both, f_off, _ = _lag_setup("input_offset")
    poor = extension_fit_at(exps, off, rig, np.r_[f_off.theta[:-1], 0.5 * f_off.theta[-1]],
                            linear=lin)
    cur_pw = _lpd(exps, _simulate(off, rig, poor.theta, exps))
    null_lag = extension_fit_at(exps, both, rig, np.r_[f_off.theta, 1e-14], linear=lin)
    plain = _in_sample(both, null_lag, rig, exps, cur_pw, 1, 0.01)
    assert plain[-1] and plain[0] > 10, plain  # the refit's gain, credited to the lag
    th, ref_pw = _reference(both, null_lag, off, poor, rig, exps, cur_pw)
    assert np.array_equal(th, f_off.theta)
    g = _in_sample(both, null_lag, rig, exps, ref_pw, 1, 0.01)
    scale = np.abs(ref_pw).sum()
    assert abs(g[0]) <= 1e-9 * scale and not g[-1], g
    # a hidden lag: the lag's own gain survives the reference
    rig, exps, lin, off, both, f_off, f_both = _lag_setup("motor_lag")
    cur_pw = _lpd(exps, _simulate(off, rig, f_off.theta, exps))
    th, ref_pw = _reference(both, f_both, off, f_off, rig, exps, cur_pw)
    g = _in_sample(both, f_both, rig, exps, ref_pw, 1, 0.01)
    assert g[-1], (g, f_both.theta[-2:])


def test_the_backward_check_removes_an_effect_at_its_no_effect_value():
    """An effect whose fitted parameters sit at its no-effect value (a lag of 1e-14 s) is
    removed by the backward check, at the point where the two models coincide; a fitted
    hidden lag is kept (negative control)."""
    from bayesmodal.discrepancy.diagnosis.backward import _simplify

    rig, exps, lin, off, both, f_off, _ = _lag_setup("input_offset")
    null_lag = extension_fit_at(exps, both, rig, np.r_[f_off.theta, 1e-14], linear=lin)
    names, fit, changes = _simplify(("input_offset", "motor_lag"), null_lag, rig, exps, lin,
                                    0.01, 20)
    assert names == ("input_offset",) and changes == [("motor_lag", None)]
    assert np.array_equal(fit.theta, f_off.theta)
    rig, exps, lin, off, both, f_off, f_both = _lag_setup("motor_lag")
    names, _, changes = _simplify(("input_offset", "motor_lag"), f_both, rig, exps, lin,
                                  0.01, 20)
    assert "motor_lag" in names, (changes, f_both.theta[-2:])


def test_extension_fit_at_summarises_a_point_like_a_fit():
    rig, exps, lin, off, both, f_off, _ = _lag_setup("input_offset")
    at = extension_fit_at(exps, off, rig, f_off.theta, linear=lin)
    assert at.cost == f_off.cost and np.array_equal(at.fit_percent, f_off.fit_percent)
    assert np.array_equal(at.sigma_m, f_off.sigma_m) and at.n_evaluations == 0
    with pytest.raises(ModelError):
        extension_fit_at(exps, off, rig, f_off.theta[:-1], linear=lin)


@pytest.mark.slow
def test_a_refinement_simplified_to_what_it_refines_is_a_cause():
    """The pair benchmark's friction + offset seed 20016: forward selection added
    directional friction levels, the backward check simplified them to equal levels, and
    the final model held friction and the offset (residuals pass) while the causes had
    lost friction.  The simplified effect is now found under its simpler name."""
    h = make_case("coulomb_friction+input_offset", 20016, N_SAMPLES)
    d = diagnose(h.experiment, posterior=False, n_null=N_NULL, rng=20016)
    ok, found = judge(h, d)
    assert ok, (found, d.notes)
    assert {c.cause for c in d.causes} == set(d.effects)


def test_two_training_records_name_a_hidden_offset_and_nothing_on_null_data():
    """The several-record path of the first step (output-error score, leave-one-record-out
    test): two records of a rig with a hidden input offset name it; two records without
    an effect give ``none`` (negative control).  Forward selection on several records:
    ``benchmarks/detection_pairs.py --records 2`` (docs/diagnose.md)."""
    from bayesmodal.cli._diagnose import _report
    from bayesmodal.discrepancy.diagnosis import diagnose

    found = {}
    for case, seed in (("input_offset", 0), (None, 1)):
        d = diagnose(_two_records(case, seed), train=[0, 1], posterior=False, n_null=N_NULL,
                     rng=seed, max_effects=1,
                     candidates=("input_offset", "drive_deadband", "motor_lag"))
        found[case] = [c.cause for c in d.causes]
        if case:
            assert d.causes[0].gain["held_out"]["criterion"] == "either"
            # the text report lists each record's diagnostics under the record's name
            text = _report(d).split("tests:\n", 1)[1].split("ranking:", 1)[0]
            heads = [ln.strip() for ln in text.splitlines() if ln.startswith("  ") and
                     ln.strip().endswith(":")]
            assert heads == [f"{e}:" for e in d.experiments], heads
            per = len({t.name for t in d.tests})
            assert len(text.splitlines()) == len(d.tests) + len(heads) == 2 * per + 2
    assert found == {"input_offset": ["input_offset"], None: []}, found


def test_records_weighed_by_spread_name_the_hidden_offset_and_nothing_on_null_data():
    """``weights="spread"`` (each record as much as the others in every least-squares fit
    of the workflow: candidates, global search, leave-one-record-out refits, null refits)
    keeps the several-record decision of the unweighted workflow on the same data: the
    hidden offset is named, two records without an effect give ``none`` (negative
    control), and the JSON says how the records were weighed."""
    found = {}
    for case, seed in (("input_offset", 0), (None, 1)):
        d = diagnose(_two_records(case, seed), train=[0, 1], posterior=False, n_null=N_NULL,
                     rng=seed, max_effects=2, weights="spread",
                     candidates=("input_offset", "drive_deadband", "motor_lag"))
        found[case] = [c.cause for c in d.causes]
        assert d.as_dict()["weights"] == "spread"
    assert found == {"input_offset": ["input_offset"], None: []}, found


def test_an_unknown_weighting_is_one_line_naming_the_choices():
    with pytest.raises(ConfigError, match=r"weights must be None or one of \('spread',\)"):
        diagnose(_two_records(None, 1), train=[0, 1], posterior=False, weights="equal")
