"""Contract of the speed benchmarks (not their timings: those live in `bayesmodal bench`)."""

import json

import numpy as np
import pytest

from bayesmodal.bench import (
    ACCELERATION_MAX_RATIO,
    BEST_COMBINED,
    BUSY_LOAD_PER_CORE,
    COMBINED,
    COMBINED_MAX_RATIO,
    EFFECT_KINDS,
    EXTENSION_MAX_RATIO,
    bench_effect_sensor_kinds,
    bench_extensions,
    bench_sensor_kinds,
    headline,
    machine_load,
    rig_input,
)
from bayesmodal.cli import main
from bayesmodal.model.effects import EXTENSIONS


@pytest.mark.slow  # the default suite reaches bench_extensions through the CLI test below
def test_bench_extensions_reports_every_extension_against_the_same_run():
    out = bench_extensions(n_samples=300, batch=4, quick=True, rounds=2)
    assert set(out) == set(EXTENSIONS) | set(COMBINED)
    for name, r in out.items():
        assert r["us_per_eval"] > 0 and r["linear_us_per_eval"] > 0, name
        assert len(r["ratio_per_round"]) == 2
        lo, hi = sorted(r["ratio_per_round"])
        assert r["ratio_to_linear"] == pytest.approx((lo + hi) / 2)  # median of two
        target = COMBINED_MAX_RATIO if "+" in name else EXTENSION_MAX_RATIO
        assert r["target_ratio"] == target
        assert r["meets_target"] == (r["ratio_to_linear"] <= target)
        lo, hi = sorted(r["ratio_per_round_rig_input"])
        assert r["ratio_to_linear_rig_input"] == pytest.approx((lo + hi) / 2)
        assert r["meets_target_rig_input"] == (r["ratio_to_linear_rig_input"] <= target)
        # best against best, from the rounds' own times
        assert r["ratio_of_best_rig_input"] == pytest.approx(
            min(r["us_per_eval_rounds_rig_input"])
            / min(r["linear_us_per_eval_rounds_rig_input"]))
        assert r["ratio_of_best"] > 0
    assert out["coulomb_friction"]["n_sub"] == EXTENSIONS["coulomb_friction"].n_sub
    assert out["motor_lag"]["n_sub"] is None


def test_bench_cli_json_keeps_linear_keys_and_adds_extensions(capsys):
    assert main(["bench", "--json", "--quick", "--samples", "300", "--batch", "4"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("n_samples", "batch", "us_per_eval", "us_per_eval_fresh_output",
                "lsim_us_per_eval", "speedup", "speedup_fresh_output",
                "max_rel_diff_vs_lsim"):
        assert key in out["linear"]
    assert set(out["extensions"]) == set(EXTENSIONS) | set(COMBINED)
    for r in out["extensions"].values():
        assert {"us_per_eval", "ratio_to_linear", "meets_target"} <= set(r)
        assert isinstance(r["meets_target"], bool)
    assert out["headline"] == headline(out["extensions"])
    assert set(out["headline"]) == {"coulomb_friction", "best_combined"}
    assert set(out["machine"]) == {"load_average", "cores", "busy"}
    st = out["stamps"]
    assert st["n_distinct_steps"] >= 2 and st["target"] == 1.5
    assert out["sensor_kinds"]["target"] == ACCELERATION_MAX_RATIO
    assert set(out["effect_sensor_kinds"]) == set(EFFECT_KINDS)
    assert st["meets_target"] == (st["ratio"] <= st["target"])
    s = out["sampler"]
    assert s["n_samples"] == 300
    # the emcee run does all a likelihood call does and more, which does all a bare
    # simulation does and more: the rates must come out in that order
    assert s["sampler_evals_per_s"] < s["simulator_evals_per_s"]
    # the fraction is the median of the per-round fractions (paired timings), not the
    # ratio of the median rates
    per_round = s["sampler_fraction_per_round"]
    assert len(per_round) == s["rounds"] >= 2
    assert s["sampler_fraction"] == np.median(per_round)
    assert s["meets_target"] == (s["sampler_fraction"] >= 0.5)
    assert np.median(s["records"]["sampler_fraction_per_round"]) == \
        s["records"]["sampler_fraction"]
    assert main(["bench", "--json", "--quick", "--samples", "300", "--batch", "4",
                 "--no-extensions", "--no-sampler"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert "extensions" not in out and "sampler" not in out
    assert "effect_sensor_kinds" not in out


def test_bench_sensor_kinds_reports_the_median_ratio_of_paired_rounds():
    out = bench_sensor_kinds(n_samples=300, batch=4, quick=True, rounds=3)
    assert out["us_per_eval_position"] > 0 and out["us_per_eval_acceleration"] > 0
    assert len(out["ratio_per_round"]) == 3
    assert out["ratio"] == np.median(out["ratio_per_round"])
    assert out["target"] == ACCELERATION_MAX_RATIO == 1.3
    assert out["meets_target"] == (out["ratio"] <= 1.3)


def test_bench_effect_sensor_kinds_times_each_effect_in_paired_rounds():
    out = bench_effect_sensor_kinds(n_samples=300, batch=4, quick=True, rounds=3)
    assert set(out) == set(EFFECT_KINDS) == {"cubic_stiffness", "coulomb_friction",
                                             "lugre_friction", "backlash", "motor_lag"}
    for r in out.values():
        assert r["us_per_eval_position"] > 0 and r["us_per_eval_acceleration"] > 0
        assert len(r["ratio_per_round"]) == 3
        assert r["ratio"] == np.median(r["ratio_per_round"])
        assert r["meets_target"] == (r["ratio"] <= ACCELERATION_MAX_RATIO)


def test_rig_input_has_pulses_steps_and_a_sweep():
    dt = 0.005
    u = rig_input(12000, dt)
    assert u.shape == (12000,) and np.all(np.isfinite(u))
    pulses, steps, sweep = u[:4000], u[4000:8000], u[8000:]
    # pulses: 9 samples (45 ms) of 3 V every 10 s, zero in between
    assert set(np.unique(pulses)) == {0.0, 3.0}
    assert np.count_nonzero(pulses) == 9 * 2
    # steps: 0.5 V held for 5 s, then 0 for 5 s
    assert set(np.unique(steps)) == {0.0, 0.5}
    assert np.count_nonzero(steps) == 1000 + 1000
    # sweep: 0.2 V amplitude, its zero crossings speed up (rising frequency)
    assert np.max(np.abs(sweep)) == pytest.approx(0.2, abs=0.005)
    crossings = np.flatnonzero(np.diff(np.sign(sweep)) != 0)
    gaps = np.diff(crossings)
    assert gaps[:5].mean() > 4 * gaps[-5:].mean()


def test_headline_takes_friction_and_the_costlier_best_combination():
    def result(random, rig, best=None):
        return {"ratio_to_linear": random, "ratio_to_linear_rig_input": rig,
                "ratio_per_round_rig_input": [rig, rig, rig],
                "ratio_of_best_rig_input": rig if best is None else best}

    a, b = BEST_COMBINED[:2]
    # friction: the median of the rounds under the target, best against best over it (a
    # baseline a neighbour slowed in some rounds): the target is judged best against best
    over = EXTENSION_MAX_RATIO * 1.1
    ext = {"coulomb_friction": result(20.0, 9.0, over), a: result(30.0, 12.0),
           b: result(5.0, 25.0)}
    h = headline(ext)
    assert h["coulomb_friction"]["ratio_rig_input"] == 9.0
    assert h["coulomb_friction"]["ratio_of_best_rig_input"] == over
    assert h["coulomb_friction"]["ratio_random_input"] == 20.0
    assert h["coulomb_friction"]["meets_target"] is False
    # the costlier on the rig-like input, judged against the combined target
    assert h["best_combined"]["name"] == b
    assert h["best_combined"]["target"] == COMBINED_MAX_RATIO
    assert h["best_combined"]["meets_target"] == (25.0 <= COMBINED_MAX_RATIO)
    assert headline({a: result(1.0, 2.0)}).keys() == {"best_combined"}
    assert headline({}) == {}


def test_best_combined_includes_the_posteriors_lugre_model_and_is_timed_by_default():
    # the converged posterior of docs/discrepancy.md is the LuGre model with dead band and
    # offset: the headline must not leave the costliest model it is about out
    assert "lugre_friction+drive_deadband+input_offset" in BEST_COMBINED
    assert set(BEST_COMBINED) <= set(COMBINED)


def test_machine_load_calls_busy_above_the_per_core_threshold():
    import os

    cores = os.cpu_count() or 1
    below = BUSY_LOAD_PER_CORE * cores * 0.9
    above = BUSY_LOAD_PER_CORE * cores * 1.1
    assert machine_load(lambda: (below, 0.0, 0.0))["busy"] is False
    m = machine_load(lambda: (above, 1.0, 2.0))
    assert m["busy"] is True and m["load_average"] == [above, 1.0, 2.0]
    assert m["cores"] == cores

    def unavailable():
        raise OSError("no load average")

    assert machine_load(unavailable) == {"load_average": None, "cores": os.cpu_count(),
                                         "busy": None}


def test_no_benchmark_script_shadows_an_installed_module():
    # a script run as `python benchmarks/x.py` has benchmarks/ first on sys.path: a file
    # named like an installed module (benchmarks/coverage.py shadowed `coverage`, which
    # numba imports) breaks every benchmark that imports numba
    import importlib.util
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "benchmarks"
    scripts = sorted(p.stem for p in folder.glob("*.py"))
    assert scripts  # the folder is there
    # (a test that imports a benchmark puts benchmarks/ on sys.path: the scripts
    # themselves are found then, and are not what this looks for)
    specs = {s: importlib.util.find_spec(s) for s in scripts}
    shadowing = [s for s, spec in specs.items()
                 if spec is not None and Path(spec.origin).parent != folder]
    assert shadowing == []
    assert importlib.util.find_spec("numpy") is not None  # control: the check can fire
