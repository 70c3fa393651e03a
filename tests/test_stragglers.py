"""Walkers stranded far below the others are moved onto them (``prune``), and only they.

The cut is the chi-square tail of a Gaussian posterior's log density beyond its median
(closed form for two parameters: ``-ln(2 p)``); a stationary ensemble loses no walker
(negative control);
after ``sample_posterior(prune=...)`` no walker is below the cut where the same chain
without it still has some, a run survives a resume across the pruning step, and bad
values are refused.
"""

import numpy as np
import pytest
from scipy.stats import chi2
from test_sampling_restart import (
    MODEL,
    THETA,
    _DyingCheckpoint,
    _Killed,
    exp,  # noqa: F401  (fixture)
)

from bayesmodal._errors import ConfigError
from bayesmodal.inference import sample_posterior
from bayesmodal.inference.stragglers import JITTER, STRAGGLER_P, prune_stragglers
from bayesmodal.runs.checkpoint import AtomicCheckpoint

KW = dict(noise="white", n_walkers=18, n_steps=60, burn=30, prune=20, refine=False)


def test_cut_is_the_chi_square_quantile():
    z = np.zeros((6, 2)) + np.arange(6)[:, None]
    r = prune_stragglers(z, np.zeros(6), rng=0)
    # two degrees of freedom: chi2 quantile -2 ln p, median 2 ln 2, so the cut is
    # -ln(2 p) nats
    assert r.cut == pytest.approx(-np.log(2 * STRAGGLER_P), rel=1e-12)
    assert r.moved.size == 0
    np.testing.assert_array_equal(r.z, z)


def test_stationary_ensemble_keeps_every_walker_and_stragglers_are_moved():
    rng = np.random.default_rng(4)
    P, W = 26, 400
    z = rng.standard_normal((W, P))
    lp = -0.5 * np.sum(z**2, axis=1)     # a Gaussian posterior at stationarity
    r = prune_stragglers(z, lp, rng=1)
    # each walker falls below the cut with probability < 1e-6: 400 of them, none moved
    assert r.moved.size == 0
    stranded = [3, 17, 250]
    z2, lp2 = z.copy(), lp.copy()
    z2[stranded] += 40.0
    lp2[stranded] = np.median(lp) - (chi2.isf(STRAGGLER_P, P) - chi2.median(P)) / 2 - 1.0
    lp2[5] = -np.inf                                          # outside the support
    r = prune_stragglers(z2, lp2, rng=1)
    assert sorted(r.moved.tolist()) == sorted(stranded + [5])
    good = np.setdiff1d(np.arange(W), r.moved)
    for i in r.moved:
        # next to a good walker (within the jitter times the ensemble's largest spread)
        d = np.linalg.norm(z[good] - r.z[i], axis=1)
        assert d.min() <= JITTER * 2 * np.ptp(z[good], axis=0).max() * np.sqrt(P)
        assert d.min() > 0                                    # walkers stay distinct
    np.testing.assert_array_equal(r.z[good], z2[good])


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="fewer than 3"):
        prune_stragglers(np.eye(4), np.array([0.0, 0.0, -1e6, -1e6]))
    with pytest.raises(ValueError, match="n_walkers"):
        prune_stragglers(np.eye(4), np.zeros(3))
    with pytest.raises(ValueError, match="p must"):
        prune_stragglers(np.eye(4), np.zeros(4), p=1.5)


@pytest.fixture(scope="module")
def reference(exp):  # noqa: F811
    return sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                            **KW)


def test_stragglers_of_the_burn_in_join_the_others(exp, reference):  # noqa: F811
    """Twenty steps from a wide start ball leave walkers far below the others; right after
    the pruning none is (negative control: the same chain without it still has them)."""
    r = reference
    plain = sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                             **{**KW, "prune": None})
    np.testing.assert_array_equal(r.chain[:20], plain.chain[:20])
    cut = (chi2.isf(STRAGGLER_P, r.priors.n_params) - chi2.median(r.priors.n_params)) / 2
    floor = np.median(r.log_prob[19]) - cut
    below = [int(np.sum(x.log_prob[20] < floor)) for x in (r, plain)]
    assert below[0] == 0 < below[1], below
    assert r.config["prune"] == 20 and "prune" not in plain.config
    assert r.config["config_hash"] != plain.config["config_hash"]


@pytest.mark.parametrize("k", [10, 20, 21, 45])
def test_resume_across_the_pruning(exp, reference, tmp_path, k):  # noqa: F811
    path = tmp_path / "chain.h5"
    with pytest.raises(_Killed):
        sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                         backend=_DyingCheckpoint(path, k), **KW)
    resumed = sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA,
                               init_scale=1e-2, backend=AtomicCheckpoint(path), **KW)
    np.testing.assert_array_equal(resumed.chain, reference.chain)


@pytest.mark.parametrize("bad", [0, 30, 45, -1, 2.5, True, "20"])
def test_bad_prune_is_refused(exp, bad):  # noqa: F811
    with pytest.raises(ConfigError, match="prune"):
        sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, **{**KW, "prune": bad})
    with pytest.raises(ConfigError, match="restart or prune"):
        sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA,
                         **{**KW, "restart": 20})
