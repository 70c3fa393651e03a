"""The two sections of a posterior run (``LikelihoodSpec``, ``SamplerSpec``) and
``sample_posterior``'s way of taking them: as objects or setting by setting."""

from __future__ import annotations

import inspect
from dataclasses import fields

import numpy as np
import pytest
from test_inference_sampling import _synthetic

from bayesmodal._errors import ConfigError
from bayesmodal.inference import LikelihoodSpec, SamplerSpec, sample_posterior
from bayesmodal.inference.spec import with_settings


def test_sample_posterior_takes_at_most_eight_parameters():
    params = [p for p in inspect.signature(sample_posterior).parameters.values()
              if p.kind is not inspect.Parameter.VAR_KEYWORD]
    assert len(params) <= 8


def test_the_sections_hold_every_setting_once():
    lik = {f.name for f in fields(LikelihoodSpec)}
    smp = {f.name for f in fields(SamplerSpec)}
    assert not lik & smp
    assert {"noise", "extension", "layout", "temperature", "initial_state"} == lik
    assert {"n_walkers", "n_steps", "burn", "thin", "moves", "init", "restart",
            "prune", "threads"} <= smp


def test_settings_by_name_go_to_their_section_and_an_unknown_name_is_refused():
    lik, smp = with_settings(LikelihoodSpec(noise="white"), SamplerSpec(n_steps=100),
                             {"n_walkers": 40, "temperature": 2.0})
    assert (lik.noise, lik.temperature, smp.n_steps, smp.n_walkers) == ("white", 2.0, 100,
                                                                         40)
    with pytest.raises(TypeError, match=r"unknown setting\(s\) \['n_walker'\]"):
        with_settings(None, None, {"n_walker": 40})


@pytest.mark.parametrize("kw, match", [
    (dict(n_steps=1), r"n_steps must be >= 2"),
    (dict(n_steps=10, burn=10), r"burn must be in \[0, n_steps\)"),
    (dict(thin=0), r"thin must be >= 1"),
    (dict(init="prior"), r"init must be 'ball' or 'laplace'"),
    (dict(burn=100, restart=100), r"restart must be in \[1, burn\)"),
    (dict(burn=100, restart=10, prune=20), r"give restart or prune, not both"),
])
def test_a_sampler_section_is_checked_when_built(kw, match):
    with pytest.raises(ConfigError, match=match):
        SamplerSpec(**kw)


def test_a_likelihood_section_is_checked_when_built():
    with pytest.raises(ConfigError, match=r"temperature must be > 0"):
        LikelihoodSpec(temperature=0.0)
    with pytest.raises(ConfigError, match=r"initial_state must be one of"):
        LikelihoodSpec(initial_state="moving")


def test_objects_and_settings_give_the_same_chain():
    """The two ways of describing one run sample the same chain, bit for bit; a setting
    given by name replaces the one in the object."""
    model, exp = _synthetic(n=400, seed=3)
    a = sample_posterior(exp, model, LikelihoodSpec(noise="white"),
                         SamplerSpec(n_walkers=18, n_steps=30, warn=False), rng=4)
    b = sample_posterior(exp, model, noise="white", n_walkers=18, n_steps=30, warn=False,
                         rng=4)
    c = sample_posterior(exp, model, LikelihoodSpec(noise="ar1"),
                         SamplerSpec(n_walkers=18, n_steps=30, warn=False), noise="white",
                         rng=4)
    assert np.array_equal(a.chain, b.chain) and np.array_equal(a.chain, c.chain)
    assert a.config["config_hash"] == b.config["config_hash"]
    # negative control: another seed, another chain
    d = sample_posterior(exp, model, noise="white", n_walkers=18, n_steps=30, warn=False,
                         rng=5)
    assert not np.array_equal(a.chain, d.chain)
