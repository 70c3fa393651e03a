"""Leave-one-record-out validation: scores against closed forms, the study end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats
from test_inference_records import _records

from bayesmodal._errors import ConfigError, DataError
from bayesmodal.inference.crossval import CrossvalSpec, crossval
from bayesmodal.inference.predictive import band_factor, crps_ensemble, score_samples
from bayesmodal.runs.compare import crossval_difference


def test_crps_of_a_gaussian_ensemble_matches_the_closed_form():
    """CRPS(N(0, 1), y) = y (2 Phi(y) - 1) + 2 phi(y) - 1/sqrt(pi); the ensemble estimate
    is unbiased up to E|X - X'| / (2 S) and scatters with its own standard error."""
    rng = np.random.default_rng(0)
    y = 0.7
    exact = y * (2 * stats.norm.cdf(y) - 1) + 2 * stats.norm.pdf(y) - 1 / np.sqrt(np.pi)
    s = 2000
    est = np.array([crps_ensemble(rng.standard_normal((s, 1)), np.array([y]))[0]
                    for _ in range(40)])
    bias = (2 / np.sqrt(np.pi)) / (2 * s)
    se = est.std(ddof=1) / np.sqrt(est.size)
    assert abs(est.mean() - exact) < 4 * se + bias
    # negative control: a shifted ensemble scores worse by more than that
    shifted = crps_ensemble(rng.standard_normal((s, 1)) + 3.0, np.array([y]))[0]
    assert shifted - exact > 4 * se + bias


def test_band_coverage_of_a_calibrated_ensemble_is_nominal():
    rng = np.random.default_rng(1)
    n, s = 4000, 400
    y = rng.standard_normal((n, 2))
    good = score_samples("x", y, rng.standard_normal((s, n, 2)), np.zeros(s))
    se = np.sqrt(0.9 * 0.1 / n)
    assert np.all(np.abs(good.coverage_90 - 0.9) < 4 * se + 1.0 / s)
    assert np.all(np.abs(good.coverage_50 - 0.5) < 4 * np.sqrt(0.25 / n) + 1.0 / s)
    narrow = score_samples("x", y, 0.3 * rng.standard_normal((s, n, 2)), np.zeros(s))
    assert np.all(narrow.coverage_90 < 0.9 - 10 * se)  # the control is overconfident
    assert np.all(narrow.width_90 < good.width_90)


def test_band_factor_recovers_the_true_spread_of_a_fixed_band():
    """Observations N(0, sigma^2) against the band +-1.645 (unit sd): the factor that
    covers 90 % is sigma (closed form), within the standard error of a sample quantile;
    the band it scales to covers 90 %, and a factor 1 % smaller does not."""
    rng = np.random.default_rng(3)
    n, z90 = 20000, stats.norm.ppf(0.95)
    for sigma in (0.5, 1.0, 1.7):
        y = sigma * rng.standard_normal((n, 1))
        one = np.full((n, 1), z90)
        c = band_factor(y, -one, np.zeros((n, 1)), one)[0]
        # SE of the 0.9 quantile of |y| / z90: sqrt(p (1 - p) / n) / density of |y| there
        se = np.sqrt(0.9 * 0.1 / n) / (2 * stats.norm.pdf(z90) / sigma) / z90
        assert abs(c - sigma) < 4 * se, (sigma, c, se)
        inside = np.mean(np.abs(y) <= c * z90)
        assert inside >= 0.9 > np.mean(np.abs(y) <= 0.99 * c * z90)


def test_band_factor_scales_each_side_by_its_own_half_width():
    """An asymmetric band (lower half-width 1, upper 3) on observations uniform in
    [-1, 3]: every sample is inside at factor 1 and the uniform's quantile gives the 90 %
    factor 0.9 (both sides scale alike); the scores report it next to the coverage."""
    n = 10001
    y = np.linspace(-1.0, 3.0, n)[:, None]
    lo, mid, hi = np.full((n, 1), -1.0), np.zeros((n, 1)), np.full((n, 1), 3.0)
    c = band_factor(y, lo, mid, hi)[0]
    assert c == pytest.approx(0.9, abs=2.0 / n)
    # in the scores: a factor above 1 exactly where the band covers less than 90 %
    rng = np.random.default_rng(1)
    yy = rng.standard_normal((4000, 2))
    for spread in (0.3, 1.0, 2.0):
        sc = score_samples("x", yy, spread * rng.standard_normal((400, 4000, 2)),
                           np.zeros(400))
        np.testing.assert_array_equal(sc.band_factor_90 > 1, sc.coverage_90 < 0.9)
        assert "band_factor_90" in sc.to_dict()


def test_paired_difference_of_summed_lpd():
    a = {"records": {"x": -10.0, "y": -20.0, "z": -30.0}}
    b = {"records": {"x": -12.0, "y": -21.0, "z": -36.0}}
    d, se = crossval_difference(a, b)
    diffs = np.array([2.0, 1.0, 6.0])
    assert d == diffs.sum()
    assert se == pytest.approx(np.sqrt(3) * diffs.std(ddof=1))
    with pytest.raises(ConfigError, match="different records"):
        crossval_difference(a, {"records": {"x": 0.0, "y": 0.0}})


def test_crossval_cli_errors_name_the_fix(tmp_path, capsys):
    from bayesmodal.cli import main
    from bayesmodal.data import save_csv

    rec = _records(n=300)[0]
    save_csv(rec, tmp_path / "one.csv")
    assert main(["crossval", str(tmp_path / "one.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "at least 2 records" in capsys.readouterr().err
    save_csv(rec, tmp_path / "two.csv")
    assert main(["crossval", str(tmp_path / "one.csv"), str(tmp_path / "two.csv"),
                 "--per-record", "g_v", "--out", str(tmp_path / "o")]) == 2
    assert "NAME=KIND" in capsys.readouterr().err
    assert main(["crossval", str(tmp_path / "one.csv"), str(tmp_path / "two.csv"),
                 "--temperature", "hot", "--out", str(tmp_path / "o")]) == 2
    assert "give a number (e.g. 10) or 'loro'" in capsys.readouterr().err
    # a configuration's problems are named on the one line, not only their count
    (tmp_path / "bad.toml").write_text(
        '[data]\nfiles = ["one.csv", "two.csv"]\n[sampler]\nsteps = 400\nburn = 200\n'
        'prune = 100\n[crossval]\nsteps = 150\n')
    assert main(["crossval", str(tmp_path / "one.csv"), str(tmp_path / "two.csv"),
                 "--config", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "[crossval.steps]" in err and "give at least 202 steps" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_crossval_end_to_end_writes_the_issue_fields(tmp_path):
    from bayesmodal.runs.crossval import write_crossval

    recs = _records(n=400)
    spec = CrossvalSpec(n_walkers=48, n_steps=20, n_predictive=24, noise="white")
    res = crossval(recs, spec, workers=1)
    d = json.loads((write_crossval(res, tmp_path)).read_text())
    assert [r["name"] for r in d["records"]] == [e.name for e in recs]
    for r in d["records"]:
        for key in ("fit_percent", "coverage_50", "coverage_90", "width_90", "crps",
                    "band_factor_90", "coverage_90_pit", "band_factor_90_pit"):
            assert len(r[key]) == 3
        assert np.array(r["coverage_90_expected"]).shape == (3, 2)
        assert 0.0 <= r["record_pit_90"] <= 1.0 and 0.0 <= r["window_probability_90"] <= 1.0
        assert np.isfinite(r["lpd"])
    cal = d["total"]["calibration"]
    assert cal["n_records"] == len(recs) and len(cal["record_pit_90"]) == len(recs)
    assert "(calibrated)" in res.table() and "records whose coverage is outside" in res.table() \
        and "whose x90 is" in res.table()
    assert d["total"]["lpd"] == pytest.approx(sum(r["lpd"] for r in d["records"]))
    assert set(d["own_lsq"]) == {e.name for e in recs}
    assert (tmp_path / "forest.png").is_file()
    assert (tmp_path / f"heldout_{recs[0].name}.png").is_file()
    with pytest.raises(DataError, match="at least 2 records"):
        crossval(recs[:1], spec)


def test_fold_samples_with_the_configured_moves_and_pruning(monkeypatch):
    """The folds get the run's moves and burn-in step: the LuGre posterior needs the
    mode-jumping move and the pruning of stranded walkers (docs/discrepancy.md)."""
    import bayesmodal.inference.crossval as crossval_module
    from bayesmodal.inference.crossval import run_fold
    from bayesmodal.inference.moves import ModeJumpMove

    seen = {}

    class Reached(Exception):
        pass

    def fake(exps, model, likelihood, sampler, **kw):
        seen.update(vars(sampler), **kw)
        raise Reached

    monkeypatch.setattr(crossval_module, "sample_posterior", fake)
    spec = CrossvalSpec(n_steps=100, moves="de:0.8,de-jump:0.2", prune=20, noise="white")
    with pytest.raises(Reached):
        run_fold(spec, _records(n=200), 0)
    assert seen["prune"] == 20 and seen["restart"] is None
    kinds = [(type(m).__name__, w) for m, w in seen["moves"]]
    assert kinds == [("DEMove", 0.8), ("DEMove", 0.2)]
    assert seen["moves"][1][0].gamma0 == ModeJumpMove().gamma0 == 1.0
    # negative control: the default spec gives differential evolution alone, no pruning
    with pytest.raises(Reached):
        run_fold(CrossvalSpec(n_steps=100, noise="white"), _records(n=200), 0)
    assert seen["prune"] is None and len(seen["moves"]) == 1


@pytest.mark.parametrize("kw, message", [
    ({"moves": "hamiltonian"}, "unknown move"),
    ({"prune": 50}, r"\[1, burn\) = \[1, 50\)"),
    ({"prune": 10, "restart": 10}, "not both"),
])
def test_crossval_spec_rejects_bad_sampler_settings(kw, message):
    with pytest.raises(ConfigError, match=message):
        CrossvalSpec(n_steps=100, **kw)


def test_config_hands_its_moves_and_pruning_to_crossval(tmp_path):
    from bayesmodal.runs.config import parse_config

    (tmp_path / "a.csv").write_text("t,v,x1,x2,x3\n")
    cfg = parse_config(_toml('[data]\nfiles=["a.csv", "a.csv"]\n[sampler]\nsteps=400\n'
                             'burn=200\nprune=100\nmoves="de:0.8,de-jump:0.2"'),
                       base=tmp_path, check_files=False)
    spec = cfg.crossval_spec()
    assert (spec.moves, spec.prune, spec.restart, spec.burn) == (
        "de:0.8,de-jump:0.2", 100, None, 200)


def _toml(text):
    import tomllib

    return tomllib.loads(text)


@pytest.mark.parametrize("flags, joint", [([], True), (["--no-joint"], False)])
def test_crossval_cli_runs_the_joint_posterior_unless_told_not_to(tmp_path, monkeypatch,
                                                                  flags, joint):
    import bayesmodal.cli._crossval as cv
    from bayesmodal.cli import main
    from bayesmodal.data import save_csv

    seen = {}

    class Reached(BaseException):  # past the CLI's one-line error handler
        pass

    def fake(exps, spec, **kw):
        seen.update(kw)
        raise Reached

    monkeypatch.setattr(cv, "crossval", fake)
    recs = _records(n=50)
    for r in recs[:2]:
        save_csv(r, tmp_path / f"{r.name}.csv")
    with pytest.raises(Reached):
        main(["crossval", *(str(tmp_path / f"{r.name}.csv") for r in recs[:2]), "--quiet",
              "--out", str(tmp_path / "o"), *flags])
    assert seen["joint"] is joint


def test_crossval_takes_a_rig_description(tmp_path):
    """--rig reaches the folds' model (a two-cart preset: two outputs, its own names)."""
    from bayesmodal.cli import build_parser
    from bayesmodal.cli._crossval import spec_from_args
    from bayesmodal.inference.records import RecordsLikelihood
    from bayesmodal.model.rigs import load_rig
    from bayesmodal.model.system import LinearModel

    args = build_parser().parse_args(["crossval", "a.csv", "b.csv", "--rig", "ecp210-2cart"])
    spec = spec_from_args(args)
    assert spec.rig == load_rig("ecp210-2cart")
    model = LinearModel(spec.rig, spec.damping)
    t = np.arange(100) * 0.005
    from bayesmodal.data import Experiment

    exps = [Experiment(t, np.ones(100), np.zeros((100, 2)) + t[:, None], name=n)
            for n in "ab"]
    lik = RecordsLikelihood(model, exps, "ar1")
    assert lik.n_outputs == 2 and lik.names[-4:] == ("sigma_1", "sigma_2", "phi_1", "phi_2")


def test_compare_counts_left_out_records_with_calibrated_bands():
    """``bayesmodal compare`` reports, next to the summed lpd, how many left-out records
    the verdict finds consistent with a calibrated band (none without references)."""
    from bayesmodal.runs.compare import _crossval_of, _cv_cell

    def rec(name, u, f):
        return {"name": name, "lpd": -1.0, "coverage_90": [0.9], "record_pit_90": u,
                "record_band_factor_pit_90": f}

    s = {"crossval": {"total": {"lpd": -2.0, "lpd_se": 1.0},
                      "records": [rec("a", 0.5, 0.5), rec("b", 0.2, 1.0)]}}
    cv = _crossval_of(s)
    assert cv["calibrated"] == 1 and "bands calibrated on 1 of 2" in _cv_cell(cv)
    for r in s["crossval"]["records"]:
        del r["record_pit_90"]
    assert _crossval_of(s)["calibrated"] is None
    assert "calibrated" not in _cv_cell(_crossval_of(s))


def test_a_new_records_modes_are_drawn_from_the_mass_population():
    # with a population layer on m1 the interval for the next record holds the spread of
    # the records' masses; without it (tau = 0) it is the centre's
    from test_inference_records import MODEL, THETA

    from bayesmodal.inference.crossval import _estimates
    from bayesmodal.inference.record_layout import RecordLayout
    from bayesmodal.inference.records import RecordsLikelihood

    lik = RecordsLikelihood(MODEL, _records(n=300), "ar1",
                            layout=RecordLayout({"m1": "hierarchical"}))
    names = lik.names
    rng = np.random.default_rng(3)
    s = 4000
    base = dict(zip(MODEL.names, THETA, strict=True))
    draws = np.empty((s, len(names)))
    for j, nm in enumerate(names):
        key = nm.split("[")[0].removeprefix("mu_")
        draws[:, j] = base.get(key, 0.5 if nm.startswith("phi") else 1e-5)
    sd_mu = 1e-4  # relative sd of the population centre over the draws
    draws[:, names.index("mu_m1")] *= 1 + sd_mu * rng.standard_normal(s)
    j_tau = names.index("tau_m1")
    widths = {}
    for tau in (0.0, 0.05):
        draws[:, j_tau] = tau
        for new in (False, True):
            est = _estimates(lik, draws, new_record=new, rng=np.random.default_rng(0))
            om = est["omega_rad_s"]
            widths[tau, new] = np.array(om["hi"]) - np.array(om["lo"])
    assert np.allclose(widths[0.0, True], widths[0.0, False])
    # a log sd tau of m1 widens every mode's interval by about sqrt(tau^2 + sd_mu^2) /
    # sd_mu (the mode's sensitivity to m1 cancels): 500 here; half of it allows for the
    # quantiles' Monte Carlo error and the curvature of omega(m1)
    assert np.min(widths[0.05, True] / widths[0.05, False]) > 0.5 * 0.05 / sd_mu
    assert np.allclose(widths[0.05, False], widths[0.0, False])
