"""converged_from: the shortest prefix of a finished chain that converges and stays so."""

import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.inference.run_length import converged_from
from bayesmodal.inference.sampling import convergence_diagnostics

NAMES = ["a", "b", "c"]


def _iid(steps=2000, walkers=32, seed=3):
    return np.random.default_rng(seed).standard_normal((steps, walkers, len(NAMES)))


def test_each_prefix_is_what_the_diagnostics_of_that_shorter_chain_say():
    z = _iid()
    r = converged_from(z, NAMES, every=500)
    assert list(r.kept_steps) == [500, 1000, 1500, 2000]
    for k, rh, es in zip(r.kept_steps, r.max_rhat, r.min_ess, strict=True):
        d = convergence_diagnostics(z[:k], np.ones(z.shape[1]), NAMES)
        assert rh == d.max_rhat and es == d.min_ess


def test_independent_walkers_converge_at_the_first_checked_prefix():
    # 32 independent walkers x 100 draws: bulk ESS about 3 200, far above 400
    r = converged_from(_iid(), NAMES, every=100)
    assert r.converged.all()
    assert r.lasting == 100


def test_a_later_disagreement_moves_the_answer_past_it_not_to_the_first_crossing():
    z = _iid()
    z[200:300, :16, 0] += 3.0   # half the walkers wander off for 100 steps
    r = converged_from(z, NAMES, every=100)
    assert r.converged[0]          # the first crossing (100 steps) came before the excursion
    assert not r.converged[2]      # the prefix that ends in it is not converged
    bad = np.flatnonzero(~r.converged)
    assert r.lasting == r.kept_steps[bad[-1] + 1]
    assert r.lasting > 300 and r.converged[r.kept_steps >= r.lasting].all()


def test_negative_control_walkers_that_never_agree_never_converge():
    z = _iid()
    z[:, :16, 0] += 3.0
    r = converged_from(z, NAMES, every=250)
    assert not r.converged.any()
    assert r.lasting is None


def test_the_whole_chain_is_always_checked_and_bad_input_is_named():
    r = converged_from(_iid(steps=1050), NAMES, every=500)
    assert list(r.kept_steps) == [500, 1000, 1050]
    with pytest.raises(ConfigError, match="shape"):
        converged_from(_iid()[:, :, :2], NAMES, every=100)
    with pytest.raises(ConfigError, match="fewer than every"):
        converged_from(_iid(steps=50), NAMES, every=100)
    with pytest.raises(ConfigError, match="at least 4"):
        converged_from(_iid(), NAMES, every=1)
