"""The snooker move leaves the posterior invariant (emcee 3.1.6's does not).

A correlated 12-dimensional Gaussian, the walkers started at stationarity: after the
chain the marginal variances must still be the target's.  The tolerance is the Monte
Carlo error of a variance from the chain's own effective sample size.
"""

import emcee
import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.inference.moves import (
    MOVES,
    ModeJumpMove,
    SnookerMove,
    default_moves,
    parse_moves,
)
from bayesmodal.runs import config

NDIM, WALKERS, STEPS = 12, 40, 2500


def _target(seed=0):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((NDIM, NDIM)))
    cov = q @ np.diag(np.logspace(0, -4, NDIM)) @ q.T
    return cov, np.linalg.inv(cov)


def _variance_ratio(moves, seed=1):
    """Mean over dimensions of (chain variance / target variance) and its standard error."""
    cov, prec = _target()
    rng = np.random.default_rng(seed)
    p0 = (np.linalg.cholesky(cov) @ rng.standard_normal((NDIM, WALKERS))).T

    def logp(x):
        return -0.5 * np.einsum("ij,jk,ik->i", x, prec, x)

    s = emcee.EnsembleSampler(WALKERS, NDIM, logp, moves=moves, vectorize=True)
    state = emcee.State(p0, random_state=np.random.RandomState(seed).get_state())
    s.run_mcmc(state, STEPS)
    chain = s.get_chain()
    ratio = chain.reshape(-1, NDIM).var(axis=0) / np.diag(cov)
    tau = emcee.autocorr.integrated_time(chain, quiet=True)
    ess = chain.shape[0] * chain.shape[1] / tau
    # var of a sample variance of a Gaussian: 2 s^4 / ESS; the mean over dimensions is
    # bounded by the largest single standard error (dimensions are not independent)
    se = np.sqrt(2.0 / ess).max()
    return float(ratio.mean()), float(se)


def test_corrected_snooker_keeps_the_variance():
    r, se = _variance_ratio([(emcee.moves.DEMove(), 0.8), (SnookerMove(), 0.2)])
    assert abs(r - 1.0) < 4 * se, (r, se)


def test_snooker_alone_keeps_the_variance():
    r, se = _variance_ratio(SnookerMove())
    assert abs(r - 1.0) < 4 * se, (r, se)


def test_mode_jumps_keep_the_variance():
    r, se = _variance_ratio([(emcee.moves.DEMove(), 0.9), (ModeJumpMove(), 0.1)])
    assert abs(r - 1.0) < 4 * se, (r, se)


def _share_in_second_mode(moves, seed=2):
    """Two equal Gaussians 40 sd apart in 6 dimensions, 36 walkers started in the first and
    4 in the second: the share of the kept draws in the second mode, and its Monte Carlo
    standard error (binomial, with the effective sample size of the mode indicator)."""
    ndim, walkers, steps, sep = 6, 40, 3000, 40.0
    centre = np.zeros(ndim)
    centre[0] = sep

    def logp(x):
        a = -0.5 * np.sum(x**2, axis=1)
        b = -0.5 * np.sum((x - centre) ** 2, axis=1)
        return np.logaddexp(a, b)

    rng = np.random.default_rng(seed)
    p0 = rng.standard_normal((walkers, ndim))
    p0[:4] += centre
    s = emcee.EnsembleSampler(walkers, ndim, logp, moves=moves, vectorize=True)
    s.run_mcmc(emcee.State(p0, random_state=np.random.RandomState(seed).get_state()), steps)
    ind = (s.get_chain()[steps // 2 :, :, 0] > sep / 2).astype(float)
    share = float(ind.mean())
    if 0.0 < share < 1.0 and np.ptp(ind, axis=0).all():
        tau = float(emcee.autocorr.integrated_time(ind[:, :, None], quiet=True)[0])
    else:  # no walker ever changed mode: the share is its starting value
        tau = float(ind.shape[0])
    se = np.sqrt(max(share * (1 - share), 1e-12) / (ind.size / tau))
    return share, se


def test_mode_jumps_give_two_equal_modes_equal_shares():
    """ter Braak's gamma = 1 step moves walkers between modes: the draws split 50/50
    between two equal Gaussians, within their Monte Carlo error; the ordinary step alone
    keeps the start's 10 % (negative control)."""
    share, se = _share_in_second_mode([(emcee.moves.DEMove(), 0.8), (ModeJumpMove(), 0.2)])
    assert abs(share - 0.5) < 4 * se, (share, se)
    # the ordinary step proposes points between the modes (e^-100 below them): no walker
    # crosses, the share stays at the start's 4 of 40
    share0, _ = _share_in_second_mode(default_moves())
    assert share0 < 0.5 - 4 * se, (share0, se)


@pytest.mark.skipif(emcee.__version__ != "3.1.6",
                    reason="negative control for emcee 3.1.6's DESnookerMove")
def test_emcee_316_snooker_contracts_the_posterior():
    """Negative control: the released move shrinks the variances (the bug SnookerMove fixes)."""
    r, se = _variance_ratio([(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)])
    assert r < 1.0 - 4 * se, (r, se)


def test_default_and_configured_moves_use_the_corrected_snooker():
    # the default is differential evolution alone, in the API and in a run configuration
    assert [type(m).__name__ for m, _ in default_moves()] == ["DEMove"]
    configured = config.SamplerSection.__dataclass_fields__["moves"].default
    assert configured == "de"
    assert [type(m).__name__ for m, _ in parse_moves(configured)] == ["DEMove"]
    assert [type(m).__name__ for m, _ in parse_moves("de:0.8, de-snooker:0.2")] == [
        "DEMove", "SnookerMove"]
    assert set(config.MOVES) == set(MOVES)
    # the run configuration's own check: names and positive weights
    for bad in ("de:heavy", "de:0", "de:0.8,snooker:0.2"):
        with pytest.raises(ConfigError, match=r"\[sampler.moves\]"):
            parse_moves(bad)
        assert config.move_spec(bad)[1]
    assert config.move_spec("de:0.8, de-snooker:0.2") == (
        [("de", 0.8), ("de-snooker", 0.2)], [])
