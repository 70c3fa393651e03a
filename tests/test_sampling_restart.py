"""``sample_posterior(restart=...)``: re-centring the ensemble on its best walker.

The restart is checked for what it promises: every walker sits next to the best one of
step ``restart`` right after it (and not without it: the negative control), the same seed
gives the same chain, a run killed before, at or after the restart resumes to the chain
of the uninterrupted run, and bad values are refused before any work.
"""

import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.data import Experiment
from bayesmodal.inference import sample_posterior
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.checkpoint import AtomicCheckpoint

MODEL = LinearModel(Rig(), "proportional")
THETA = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])
KW = dict(noise="white", n_walkers=18, n_steps=60, burn=30, restart=20, refine=False)


@pytest.fixture(scope="module")
def exp():
    dt = 0.005
    t = np.arange(500) * dt
    v = 3.0 * (t < 0.05)
    y = simulate_linear(MODEL, THETA, v, dt)
    y = y + 2e-5 * np.random.default_rng(3).standard_normal(y.shape)
    return Experiment(t, v, y, name="restart-toy")


@pytest.fixture(scope="module")
def reference(exp):
    return sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                            **KW)


def _centre_t(run):
    """Largest |t| of the step-20 walkers' mean against the best walker of step 19."""
    best = run.priors.to_sampling(run.chain[19, np.argmax(run.log_prob[19])])
    z = run.priors.to_sampling(run.chain[20])
    return float(np.max(np.abs(z.mean(axis=0) - best) / (z.std(axis=0, ddof=1)
                                                             / np.sqrt(len(z)))))


def test_walkers_gather_at_the_best_one(exp, reference):
    r = reference
    best = r.chain[19, np.argmax(r.log_prob[19])]
    # right after the restart the ensemble is a small ball (scale 1e-2 in log units for
    # the positive parameters) around the best walker of step 20
    after = r.priors.to_sampling(r.chain[20])
    assert np.all(np.abs(after - r.priors.to_sampling(best)) < 0.2)
    # negative control: without the restart the ensemble keeps its spread
    plain = sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                             **{**KW, "restart": None})
    np.testing.assert_array_equal(plain.chain[:20], r.chain[:20])
    # the new ball is centred on the best walker: the walkers' mean lies at it within the
    # mean's standard error (t with 17 degrees of freedom, 9 coordinates: |t| >= 4 has
    # probability < 1 %)
    assert _centre_t(r) < 4
    # negative control, whatever the moves: without the restart the walkers whose step-20
    # proposal was rejected still sit where they were at step 19 (acceptance < 1); with it
    # every walker was drawn anew in the ball, so none does (the walkers' spread or centre
    # alone does not tell: 20 steps from a small start ball keep the ensemble near it)
    unchanged = [int(np.sum(np.all(x.chain[20] == x.chain[19], axis=1))) for x in (r, plain)]
    assert unchanged[0] == 0 < unchanged[1], unchanged
    assert r.config["restart"] == 20 and "restart" not in plain.config
    assert r.config["config_hash"] != plain.config["config_hash"]


def test_same_seed_same_chain(exp, reference):
    again = sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                             **KW)
    np.testing.assert_array_equal(again.chain, reference.chain)
    np.testing.assert_array_equal(again.log_prob, reference.log_prob)


class _Killed(Exception):
    pass


class _DyingCheckpoint(AtomicCheckpoint):
    """Writes every step and dies (like a killed process) once it holds ``k`` steps."""

    def __init__(self, path, k):
        super().__init__(path, every_s=0.0)
        self.k = k

    def save_step(self, state, accepted):
        super().save_step(state, accepted)
        if self.iteration == self.k:
            raise _Killed


@pytest.mark.parametrize("k", [10, 20, 21, 45])
def test_resume_across_the_restart(exp, reference, tmp_path, k):
    path = tmp_path / "chain.h5"
    with pytest.raises(_Killed):
        sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, init_scale=1e-2,
                         backend=_DyingCheckpoint(path, k), **KW)
    assert AtomicCheckpoint(path).iteration == k
    resumed = sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA,
                               init_scale=1e-2, backend=AtomicCheckpoint(path), **KW)
    np.testing.assert_array_equal(resumed.chain, reference.chain)


@pytest.mark.parametrize("bad", [0, 30, 45, -1, 2.5, True, "20"])
def test_bad_restart_is_refused(exp, bad):
    with pytest.raises(ConfigError, match="restart"):
        sample_posterior(exp, MODEL, rng=5, warn=False, start=THETA, **{**KW, "restart": bad})
