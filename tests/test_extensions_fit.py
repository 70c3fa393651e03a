"""Multi-start least squares of an extended model (``fit_extension_lsq(n_starts=...)``)."""

from __future__ import annotations

import numpy as np
import pytest
from hidden_effects import make

from bayesmodal.extensions import EXTENSIONS, fit_extension_lsq
from bayesmodal.extensions.fit import extension_residuals
from bayesmodal.fit import fit_lsq
from bayesmodal.system import LinearModel, Rig

RIG = Rig()


@pytest.fixture(scope="module")
def record():
    # friction on one cart, reference simulator, noise and quantisation
    return make("coulomb_friction", seed=8, n_samples=1000).experiment


def _candidates(ext, lin, e, scales, n):
    grid = ext.start_grid(RIG)
    starts = []
    for f in scales:
        th = np.array(lin.theta)
        th[1 + RIG.n_carts :] *= f
        starts.append(th)
    cands = np.concatenate([np.repeat(starts, len(grid), axis=0),
                            np.tile(grid, (len(starts), 1))], axis=1)
    cands = cands[ext.valid(RIG, cands)]
    r = extension_residuals(ext, RIG, cands, [e])
    return cands[np.argsort(np.sum(r**2, axis=1))[:n]]


def test_multistart_returns_the_best_of_its_local_fits(record):
    """n_starts = 2 equals the better of the two single fits from its two best candidates,
    and the default (one start, linear dampers) is the single fit from the best
    candidate."""
    ext = EXTENSIONS["coulomb_friction"]
    lin = fit_lsq(record, LinearModel(RIG, "free"))
    scales = (1.0, 0.3)
    multi = fit_extension_lsq(record, ext, RIG, linear=lin, n_starts=2, damper_scales=scales,
                              max_nfev=15)
    singles = [fit_extension_lsq(record, ext, RIG, theta0=c, linear=lin, max_nfev=15)
               for c in _candidates(ext, lin, record, scales, 2)]
    best = min(singles, key=lambda f: f.cost)
    assert multi.cost == pytest.approx(best.cost, rel=1e-12)
    np.testing.assert_array_equal(multi.theta, best.theta)
    assert multi.n_evaluations == sum(f.n_evaluations for f in singles)
    default = fit_extension_lsq(record, ext, RIG, linear=lin, max_nfev=15)
    first = fit_extension_lsq(record, ext, RIG, linear=lin, max_nfev=15,
                              theta0=_candidates(ext, lin, record, (1.0,), 1)[0])
    np.testing.assert_array_equal(default.theta, first.theta)


def test_experiment_weights_scale_each_records_share_of_the_cost(record):
    """Weight 0 on a second record gives the fit on the first alone and equal weights of 2
    the unweighted fit with twice its cost (up to the optimiser's rounding: 1e-4 in the
    estimate, 1e-5 in the cost); weight 1 on both (the negative control) moves the
    estimate by more than 1 %."""
    from bayesmodal._errors import ConfigError

    ext = EXTENSIONS["coulomb_friction"]
    other = make("coulomb_friction", seed=9, n_samples=1000).experiment
    lin = fit_lsq(record, LinearModel(RIG, "free"))
    opts = {"linear": lin, "max_nfev": 15}
    alone = fit_extension_lsq(record, ext, RIG, **opts)
    zero = fit_extension_lsq([record, other], ext, RIG, weights=(1.0, 0.0), **opts)
    np.testing.assert_allclose(zero.theta, alone.theta, rtol=1e-4, atol=1e-6)
    assert zero.cost == pytest.approx(alone.cost, rel=1e-5)
    both = fit_extension_lsq([record, other], ext, RIG, **opts)
    doubled = fit_extension_lsq([record, other], ext, RIG, weights=(2.0, 2.0), **opts)
    np.testing.assert_allclose(doubled.theta, both.theta, rtol=1e-4, atol=1e-6)  # at bounds
    assert doubled.cost == pytest.approx(2 * both.cost, rel=1e-5)
    assert np.max(np.abs(both.theta - alone.theta) / np.abs(alone.theta).clip(1e-3)) > 1e-2
    for bad in ((1.0,), (1.0, -0.5), (1.0, np.nan), (0.0, 0.0)):
        with pytest.raises(ConfigError, match="weights"):
            fit_extension_lsq([record, other], ext, RIG, weights=bad, **opts)
