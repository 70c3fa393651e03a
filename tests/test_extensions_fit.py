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
