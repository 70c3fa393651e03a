"""``DiagnoseSpec``: the settings of a diagnosis in one checked object, and ``diagnose``'s
way of taking it (as an object or setting by setting)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.data import Experiment
from bayesmodal.discrepancy.diagnosis import DiagnoseSpec, diagnose
from bayesmodal.discrepancy.diagnosis.spec import with_diagnose_settings
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig


def test_diagnose_takes_at_most_eight_parameters():
    params = [p for p in inspect.signature(diagnose).parameters.values()
              if p.kind is not inspect.Parameter.VAR_KEYWORD]
    assert len(params) <= 8


@pytest.mark.parametrize("kw, match", [
    (dict(candidates=["pink_friction"]), r"unknown candidate extension\(s\) \['pink_friction'\]"),
    (dict(candidates=[]), r"unknown candidate extension"),
    (dict(weights="equal"), r"weights must be None or one of"),
    (dict(quantum_m=-1.0), r"quantum_m must be finite and >= 0"),
    (dict(n_starts=0), r"n_starts must be a positive integer"),
    (dict(max_effects=True), r"max_effects must be a positive integer"),
])
def test_a_spec_is_checked_when_built(kw, match):
    with pytest.raises(ConfigError, match=match):
        DiagnoseSpec(**kw)


def test_settings_by_name_replace_the_spec_and_an_unknown_name_is_refused():
    spec = with_diagnose_settings(DiagnoseSpec(n_null=80), {"alpha": 0.1})
    assert (spec.n_null, spec.alpha) == (80, 0.1)
    assert DiagnoseSpec(candidates=["backlash"]).candidates == ("backlash",)
    with pytest.raises(TypeError, match=r"unknown setting\(s\) \['n_nul'\]"):
        diagnose([], n_nul=10)


def _linear_record(seed=0):
    """A record of the linear model with white noise: nothing for a diagnosis to find."""
    model = LinearModel(Rig(), "free")
    theta = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
    t = np.arange(1500) * 0.005
    v = 3.0 * ((t > 0.5) & (t < 0.55)) - 3.0 * ((t > 4.0) & (t < 4.05))
    y = simulate_linear(model, theta, v, 0.005)
    y = y + 2e-6 * np.random.default_rng(seed).standard_normal(y.shape)
    return Experiment(t, v, y, name="linear")


def test_an_object_and_settings_by_name_give_the_same_diagnosis():
    rec = _linear_record()
    a = diagnose(rec, DiagnoseSpec(n_null=19, posterior=False, max_effects=1), rng=3)
    b = diagnose(rec, n_null=19, posterior=False, max_effects=1, rng=3)
    assert a.as_dict() == b.as_dict()
    # negative control: another null calibration gives another threshold
    c = diagnose(rec, n_null=19, posterior=False, max_effects=1, rng=4)
    assert c.threshold != a.threshold


def test_the_diagnosis_plots_are_one_per_diagnostic_and_record(tmp_path):
    """``plots.diagnosis.write_plots``: the residuals and every diagnostic of each training
    record, and the fit before and after of every record, each a non-empty PNG."""
    from bayesmodal.discrepancy.diagnosis.null import run_diagnostics
    from bayesmodal.plots.diagnosis import write_plots

    rec = _linear_record()
    d = diagnose(rec, n_null=19, posterior=False, max_effects=1, rng=3)
    out = write_plots(d, [rec], tmp_path)
    lin = d.detail["linear"]
    n_diag = len(run_diagnostics(rec, lin.model, lin.theta, quantum_m=0.0))
    assert len(out) == 1 + n_diag + 1 and len(set(out)) == len(out)
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in out)
