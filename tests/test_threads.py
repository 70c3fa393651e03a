"""Threads evaluating a half-ensemble: the same numbers, the same chain, bad values refused.

``bayesmodal.inference.threads`` cuts a batch of walkers into blocks evaluated by copies
of the log posterior in threads.  Its promise is exactness: a walker's value does not
depend on the block it is in, so a threaded run is the serial run bit for bit (compared
with ``np.array_equal``, no tolerance).  Negative control: a log posterior whose value
does depend on the batch (it subtracts the batch mean) differs when cut into blocks, so
the equality checks can fail.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hidden_effects import make

from bayesmodal._errors import ConfigError
from bayesmodal.inference import (
    Likelihood,
    ThreadedLogPosterior,
    default_priors,
    resolve_threads,
    sample_posterior,
)
from bayesmodal.inference.sampling import LogPosterior
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.config import parse_config

N_SAMPLES = 1500


@pytest.fixture(scope="module")
def friction():
    return make("coulomb_friction", seed=8, n_samples=N_SAMPLES)


def _log_post(data, extension):
    model = LinearModel(Rig(), "free")
    lik = Likelihood(model, [data.experiment], "ar1", extension=extension)
    return LogPosterior(lik, default_priors(model, noise="ar1", extension=extension))


def _friction_start(data):
    """The truth, with the carts without friction at Fc 0.05 N, Fs 0.1 N (inside the
    priors, static above kinetic)."""
    ext = np.maximum(data.theta_extension, np.repeat([0.05, 0.1], 3))
    return np.r_[data.theta_linear, ext]


def _walkers(log_post, centre, n, rng):
    """``n`` sampling-coordinate points scattered around ``centre`` (physical)."""
    z0 = log_post.priors.to_sampling(np.asarray(centre, dtype=float)[None])[0]
    return z0 + 0.005 * rng.standard_normal((n, z0.size))


@pytest.mark.parametrize("extension", [None, "coulomb_friction"])
@pytest.mark.parametrize("threads", [2, 3])
def test_blocks_give_the_serial_values_bit_for_bit(friction, extension, threads):
    lp = _log_post(friction, extension)
    mech = friction.theta_linear if extension is None else _friction_start(friction)
    centre = np.r_[mech, np.full(3, 1e-5), np.full(3, 0.5)]
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 14):  # fewer rows than threads, uneven blocks, a half-ensemble
        z = _walkers(lp, centre, n, rng)
        serial = lp(z)
        with ThreadedLogPosterior(lp, threads) as tp:
            assert np.array_equal(tp(z), serial)
            assert np.array_equal(tp(z), serial)  # buffers reused by a second call
        assert np.all(np.isfinite(serial))  # values, not -inf everywhere


class _BatchDependent:
    """A log posterior that is not per walker: the negative control."""

    likelihood = priors = None
    temperature = 1.0

    def __call__(self, z):
        z = np.atleast_2d(z)
        v = -np.sum((z - z.mean(axis=0)) ** 2, axis=1)
        return np.column_stack([v, v])


def test_negative_control_a_batch_dependent_target_differs_in_blocks():
    z = np.random.default_rng(1).standard_normal((8, 3))
    with ThreadedLogPosterior(_BatchDependent(), 2) as tp:
        assert not np.array_equal(tp(z), _BatchDependent()(z))


def test_threaded_chain_is_the_serial_chain(friction):
    """A whole emcee run with 2 threads is the run with one, bit for bit (extension)."""
    kw = dict(noise="ar1", n_walkers=44, n_steps=12, burn=4, rng=5, warn=False,
              extension="coulomb_friction", refine=False,
              start=_friction_start(friction))
    model = LinearModel(Rig(), "free")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = sample_posterior(friction.experiment, model, threads=1, **kw)
        two = sample_posterior(friction.experiment, model, threads=2, **kw)
    assert np.array_equal(one.chain, two.chain)
    assert np.array_equal(one.log_prob, two.log_prob)
    assert one.config["config_hash"] == two.config["config_hash"]


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "many", "", None])
def test_bad_thread_counts_are_refused_in_one_line(bad):
    with pytest.raises(ConfigError, match="threads must be a positive integer or 'auto'"):
        resolve_threads(bad)


def test_auto_and_digits():
    assert resolve_threads("auto") >= 1
    assert resolve_threads(" AUTO ") == resolve_threads("auto")
    assert resolve_threads("2") == 2 and resolve_threads(np.int64(3)) == 3


def test_config_threads_parse_and_leave_the_hash_alone():
    base = {"data": {"files": ["a.csv"]}}
    plain = parse_config(base, check_files=False)
    two = parse_config({**base, "sampler": {"threads": 2}}, check_files=False)
    auto = parse_config({**base, "sampler": {"threads": "auto"}}, check_files=False)
    assert plain.sampler.threads == 1 and two.sampler.threads == 2 and auto.sampler.threads >= 1
    assert plain.hash() == two.hash() == auto.hash()
    with pytest.raises(ConfigError, match=r"\[sampler.threads\].*positive integer"):
        parse_config({**base, "sampler": {"threads": 0}}, check_files=False)
