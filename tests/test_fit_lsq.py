"""The one least-squares fitter, ``fit_lsq``, recovers a known truth in each of its cases.

- the linear model on noisy records: within 4 of its own Gauss-Newton standard errors;
- the linear model with the initial state of a free decay estimated: the same;
- a model with effects on two noise-free records, weighted: at the truth to the precision
  of a forward-difference search (relative 1e-6; a smooth effect, motor lag);
- per-record drive gains on noise-free records: each record's gain the same way.

Each has a negative control: a wrong truth is far outside the same tolerance, or a model
without the cause (no effect, a shared gain) does not reach it.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import ConfigError, ModelError
from bayesmodal.data import Experiment
from bayesmodal.fit import ExtensionFit, LSQOptions, LSQResult, fit_extension_lsq, fit_lsq
from bayesmodal.model.effects import get_extension
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

RIG = Rig()
MODEL = LinearModel(RIG, "free")
N, DT, SIGMA_M = 1500, 0.005, 1e-5
T = np.arange(N) * DT
TRUTH = np.array([6.0, 2.6, 2.4, 2.3, 3.0, 1.5, 1.2, 0.2, 0.3])
#: An impulse pair and a chirp, V.
V_IMP = 3.0 * ((T > 0.1) & (T < 0.15)) - 2.0 * ((T > 4.0) & (T < 4.05))
V_SWEEP = 0.8 * np.sin(2 * np.pi * (0.5 + 0.4 * T) * T)
#: Noise-free searches stop within this relative distance of the truth (measured 6e-9 for
#: the motor lag, whose forward differences step 1e-3 in its scaled coordinate, and 1e-12
#: for the gains; the stopping tolerances are 1e-10).
RTOL_NOISE_FREE = 1e-6
#: A start 30 % from the truth (``default_start`` is the fitter's business, not this file's).
START = TRUTH * 1.3


def _noisy(theta, v, seed, x0=None, name="r"):
    rng = np.random.default_rng(seed)
    y = simulate_linear(MODEL, theta, v, DT, x0) + SIGMA_M * rng.standard_normal((N, 3))
    return Experiment(T, v, y, name=name)


def _z(res, truth):
    return np.abs(res.theta - truth) / res.stderr


def test_linear_within_its_standard_errors():
    recs = [_noisy(TRUTH, V_IMP, 1, name="imp"), _noisy(TRUTH, V_SWEEP, 2, name="sweep")]
    res = fit_lsq(recs, MODEL, theta0=START)
    assert isinstance(res, LSQResult) and res.extension is None
    assert np.all(np.isfinite(res.stderr))
    assert np.all(_z(res, TRUTH) < 4), _z(res, TRUTH)
    # negative control: a truth 2 % away in one mass is many standard errors off
    wrong = TRUTH * np.r_[1, 1.02, np.ones(7)]
    assert np.max(_z(res, wrong)) > 20


def test_estimated_initial_state_within_its_standard_errors():
    x0 = np.r_[0.01, 0.0, -0.005, 0.0, 0.0, 0.0]
    recs = [_noisy(TRUTH, V_IMP, 3, name="imp"), _noisy(TRUTH, 0 * V_IMP, 4, x0, "decay")]
    res = fit_lsq(recs, MODEL, theta0=START, initial_state="estimate")
    assert np.all(_z(res, TRUTH) < 4), _z(res, TRUTH)
    assert res.x0.shape == (2, 6)
    assert np.allclose(res.x0[1, :3], x0[:3], atol=5 * SIGMA_M)
    # negative controls: a wrong gain is many standard errors off, and so is an initial
    # displacement 20 % smaller on the same noise-level scale
    assert np.max(_z(res, TRUTH * np.r_[1.02, np.ones(8)])) > 20
    assert not np.allclose(res.x0[1, :3], 0.8 * x0[:3], atol=5 * SIGMA_M)


def test_extended_model_weighted_reaches_the_truth():
    ext = get_extension("motor_lag")
    theta = np.r_[TRUTH, 0.02]
    recs = [Experiment(T, v, ext.simulate(RIG, theta, v, DT), name=n)
            for v, n in ((V_IMP, "imp"), (V_SWEEP, "sweep"))]
    res = fit_lsq(recs, RIG, extension=ext, weights="spread",
                  linear=fit_lsq(recs, RIG, theta0=START))
    assert isinstance(res, ExtensionFit) and res.extension is ext
    assert res.names == ext.names(RIG) and res.weights.shape == (2,)
    assert np.allclose(res.theta, theta, rtol=RTOL_NOISE_FREE), res.theta / theta - 1
    # the old name is the same fit
    old = fit_extension_lsq(recs, ext, RIG, weights="spread", linear=res.linear)
    assert np.array_equal(old.theta, res.theta) and old.cost == res.cost
    # negative control: the linear model alone misses the truth by far more
    assert not np.allclose(res.linear.theta, TRUTH, rtol=100 * RTOL_NOISE_FREE)
    assert res.linear.cost > 1e4 * res.cost


def test_per_record_gains_reach_the_truth():
    gains = (6.0, 6.6)
    recs = [Experiment(T, v, simulate_linear(MODEL, np.r_[g, TRUTH[1:]], v, DT), name=n)
            for g, v, n in zip(gains, (V_IMP, V_SWEEP), ("imp", "sweep"), strict=True)]
    opts = LSQOptions(per_record=("g_v",))
    res = fit_lsq(recs, RIG, opts, theta0=START, max_nfev=200)
    want = np.array([np.r_[g, TRUTH[1:]] for g in gains])
    assert res.theta_records.shape == (2, 9) and res.per_record == ("g_v",)
    assert np.allclose(res.theta_records, want, rtol=RTOL_NOISE_FREE)
    # the vector of a new record: the gains' geometric mean
    assert res.theta[0] == pytest.approx(np.sqrt(gains[0] * gains[1]))
    # negative control: one shared gain cannot fit both records
    shared = fit_lsq(recs, RIG, theta0=START, max_nfev=200)
    assert not np.allclose(shared.theta[0], gains, rtol=100 * RTOL_NOISE_FREE)
    assert shared.cost > 1e4 * res.cost


def test_options_refuse_what_does_not_fit_together():
    with pytest.raises(ConfigError, match="search must be one of"):
        LSQOptions(search="anneal")
    with pytest.raises(ConfigError, match="search='global' is for a model with effects"):
        LSQOptions(search="global")
    with pytest.raises(ConfigError, match="initial_state='estimate' is for the linear"):
        LSQOptions(extension=get_extension("motor_lag"), initial_state="estimate")
    with pytest.raises(ModelError, match="free-damping linear model"):
        fit_lsq([], LinearModel(RIG, "proportional"), extension=get_extension("motor_lag"))
