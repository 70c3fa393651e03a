"""Contract of the speed benchmarks (not their timings: those live in `bayesmodal bench`)."""

import json

import pytest

from bayesmodal.bench import EXTENSION_MAX_RATIO, bench_extensions
from bayesmodal.cli import main
from bayesmodal.extensions import EXTENSIONS


def test_bench_extensions_reports_every_extension_against_the_same_run():
    out = bench_extensions(n_samples=300, batch=4, quick=True, rounds=2)
    assert set(out) == set(EXTENSIONS)
    for name, r in out.items():
        assert r["us_per_eval"] > 0 and r["linear_us_per_eval"] > 0, name
        assert len(r["ratio_per_round"]) == 2
        lo, hi = sorted(r["ratio_per_round"])
        assert r["ratio_to_linear"] == pytest.approx((lo + hi) / 2)  # median of two
        assert r["meets_target"] == (r["ratio_to_linear"] <= EXTENSION_MAX_RATIO)
    assert out["coulomb_friction"]["n_sub"] == EXTENSIONS["coulomb_friction"].n_sub
    assert out["motor_lag"]["n_sub"] is None


def test_bench_cli_json_keeps_linear_keys_and_adds_extensions(capsys):
    assert main(["bench", "--json", "--quick", "--samples", "300", "--batch", "4"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("n_samples", "batch", "us_per_eval", "us_per_eval_fresh_output",
                "lsim_us_per_eval", "speedup", "speedup_fresh_output",
                "max_rel_diff_vs_lsim"):
        assert key in out["linear"]
    assert set(out["extensions"]) == set(EXTENSIONS)
    for r in out["extensions"].values():
        assert {"us_per_eval", "ratio_to_linear", "meets_target"} <= set(r)
        assert isinstance(r["meets_target"], bool)
    assert main(["bench", "--json", "--quick", "--samples", "300", "--batch", "4",
                 "--no-extensions"]) == 0
    assert "extensions" not in json.loads(capsys.readouterr().out)
