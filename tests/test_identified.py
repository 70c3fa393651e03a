"""The identifiability verdict of a least-squares fit (``bayesmodal.identified``).

Records are simulated with the package's own simulator from a known truth: a normal
record must be identified (the negative control), the same record with its drive reversed
(simulated with the input negated, read with the normal sign) must not, and ``bayesmodal
lsq`` must then exit non-zero with one line naming the cause and the fix, still printing
the whole result with ``--json``.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import run_cli as _cli

from bayesmodal.data import Experiment, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.identified import MAX_RELATIVE_STDERR, identify
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

#: g_v, m1..m3, c1..c3, c12, c23 (N/V, kg, N s/m): near the report's Table 3
THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
DT = 0.005
N = 2000
#: encoder noise, m: a tenth of a count
NOISE_M = 0.1 * 0.0706 / 16000


def _record(sign: float = 1.0, seed: int = 38) -> Experiment:
    """A 0.5 V square wave of period 4 s and the carts' response to ``sign`` times it."""
    t = np.arange(N) * DT
    v = 0.5 * ((t % 4.0) < 2.0)
    model = LinearModel(Rig(), "free")
    y = simulate_linear(model, THETA, sign * v, DT)
    y = y + NOISE_M * np.random.default_rng(seed).standard_normal(y.shape)
    return Experiment(t, v, y, name="reversed" if sign < 0 else "normal")


@pytest.fixture(scope="module")
def fits():
    model = LinearModel(Rig(), "free")
    return {k: fit_lsq(_record(s), model) for k, s in (("normal", 1.0), ("reversed", -1.0))}


def test_a_normal_record_is_identified(fits):
    res = fits["normal"]
    verdict = res.identification
    assert verdict.identified, verdict.problems
    assert verdict.reason == "" and verdict.problems == ()
    assert verdict.rank == res.jac_singular_values.size == res.model.n_params
    # the negative control recovers the truth within its own standard errors
    assert np.all(np.abs(res.theta - THETA) < 4 * res.stderr + 1e-12)


def test_a_reversed_drive_is_not_identified(fits):
    verdict = fits["reversed"].identification
    assert not verdict.identified
    assert verdict.reason.startswith("the drive gain g_v is indistinguishable from its "
                                     "bound 0 (zero within one standard error")
    assert "--input-scale -1" in verdict.reason
    assert verdict.relative_stderr[0] >= MAX_RELATIVE_STDERR
    # the misfit is named too
    assert any("explains less than the record's mean" in p for p in verdict.problems)
    assert verdict.min_fit_percent < 0


def test_each_rule_alone(fits):
    res = fits["normal"]
    s = res.jac_singular_values
    # a zero singular value: rank-deficient
    v = identify(replace(res, jac_singular_values=np.r_[s[:-1], 0.0]), ["rec"])
    assert not v.identified and v.rank == s.size - 1
    assert v.reason.startswith(f"the Jacobian is rank-deficient (rank {s.size - 1} of "
                               f"{s.size}")
    # a standard error that is not finite (a closed-loop record's c1 = 1.9e19 +- nan)
    cov = res.cov.copy()
    cov[4, 4] = np.nan
    v = identify(replace(res, cov=cov))
    assert not v.identified and v.reason.startswith("no finite standard error for c1 (")
    # a damper whose standard error is beyond the Jacobian's resolution
    cov = res.cov.copy()
    cov[5, 5] = (1e9 * res.theta[5]) ** 2
    v = identify(replace(res, cov=cov))
    assert not v.identified and "for c2 = " in v.reason
    # a damper poorly determined but finite is a legitimate answer
    cov[5, 5] = (2 * res.theta[5]) ** 2
    assert identify(replace(res, cov=cov)).identified
    # a fit below 0 % on one cart of one record
    fp = res.fit_percent.copy()
    fp[0, 2] = -3.0
    v = identify(replace(res, fit_percent=fp), ["rec"])
    assert not v.identified and "fit -3.0 % on output 3 of rec" in v.reason


def test_lsq_refuses_a_reversed_drive_with_one_line(tmp_path):
    path = tmp_path / "rev.csv"
    save_csv(_record(-1.0), path)
    code, out, err = _cli(["lsq", str(path)])
    assert code == 2 and out == ""
    # the reader's guess (a warning, docs/reading.md), then the verdict: one error line
    assert len(err) == 2, err
    assert err[0].startswith(f"bayesmodal lsq: warning: {path}: the carts move against the "
                             "input")
    errors = err[1:]
    assert errors[0].startswith(f"bayesmodal lsq: error: {path}: not identified: the drive "
                                "gain g_v is indistinguishable from its bound 0")
    assert "--input-scale -1" in errors[0]
    # --json: the result is still printed, with the verdict
    code, out, err = _cli(["lsq", str(path), "--json"])
    assert code == 2
    js = json.loads(out)
    assert js["identified"] is False and js["reason"] in errors[0]
    assert js["parameters"]["g_v"] < js["stderr"]["g_v"]


def test_lsq_json_of_a_normal_record_says_identified(tmp_path):
    path = tmp_path / "ok.csv"
    save_csv(_record(1.0), path)
    code, out, err = _cli(["lsq", str(path), "--json"])
    assert code == 0, err
    js = json.loads(out)
    assert js["identified"] is True and js["reason"] == "" and js["problems"] == []


@pytest.mark.parametrize("command", [
    ["sample", "--steps", "10", "--walkers", "32"],
    ["diagnose", "--no-posterior", "--null", "19"],
])
def test_sample_and_diagnose_refuse_a_reversed_drive_before_any_work(command, tmp_path):
    """The posterior and the diagnosis start from the linear fit: on a record it does not
    identify they stop at once with one line (no sampling, no null calibration), where a
    posterior around g_v = 0 or a search for effects behind a reversed drive would be a
    wrong answer with exit 0."""
    path = tmp_path / "rev.csv"
    save_csv(_record(-1.0), path)
    code, out, err = _cli([command[0], str(path), *command[1:]])
    errors = [e for e in err if ": error: " in e]
    assert code == 2 and out == "" and len(errors) == 1, err
    assert errors[0].startswith(f"bayesmodal {command[0]}: error: {path}: not identified: "
                                "the linear least-squares fit")
    assert "--input-scale -1" in errors[0]
    assert not list(tmp_path.glob("*.nc")) and not list(tmp_path.glob("*.h5"))


def test_require_identified_passes_a_normal_fit(fits):
    from bayesmodal.identified import require_identified

    # negative control: an identified fit goes through, a reversed one does not
    require_identified(fits["normal"], [_record(1.0)], "the posterior")
    with pytest.raises(ValueError, match="not identified: the linear least-squares fit the "
                                         "posterior starts from"):
        require_identified(fits["reversed"], [_record(-1.0)], "the posterior")


def test_a_singular_covariance_alone_does_not_stop_the_analyses(fits):
    """On records with strong dry friction the linear fit's J^T J is singular (dampers on
    their bound): its standard errors are not finite, which ``lsq`` reports, but the
    posterior and the diagnosis may start from it; a drive gain at 0 stops them."""
    from bayesmodal.identified import require_identified

    res = fits["normal"]
    singular = replace(res, cov=np.full_like(res.cov, np.nan))
    v = identify(singular)
    assert not v.identified and v.rules[0] == "stderr" and len(v.rules) == len(v.problems)
    require_identified(singular, [_record(1.0)], "the diagnosis")
    assert "bound" in identify(fits["reversed"]).rules
