"""One run description: the object a run's TOML file makes is what ``sample_posterior``,
``crossval`` and ``diagnose`` take, and what ``bayesmodal sample`` builds from its flags."""

import argparse
import textwrap

import numpy as np
import pytest

from bayesmodal import ConfigError
from bayesmodal.cli._sample import description_from_args
from bayesmodal.data import Experiment
from bayesmodal.discrepancy.diagnosis import DiagnoseSpec, diagnose
from bayesmodal.inference import LikelihoodSpec, SamplerSpec, sample_posterior
from bayesmodal.inference.crossval import CrossvalSpec, crossval
from bayesmodal.inference.moves import parse_moves
from bayesmodal.inference.priors import LogUniform, default_priors
from bayesmodal.inference.spec import RunDescription
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.config import load_config
from bayesmodal.runs.description import RunConfig
from bayesmodal.runs.prepare import prepare_run

CONFIG = """
[data]
files = ["a.csv", "b.csv"]

[model]
damping = "proportional"

[priors]
g_v = {{ lo = 2.0, hi = 12.0, scale = "log" }}

[likelihood]
noise = "{noise}"

[sampler]
walkers = 20
steps = 30
burn = 10
thin = 2
seed = 5

[crossval]
draws = 20
steps = 20

[identify]
enabled = true
null = 21
max_effects = 2
seed = 9
weights = "auto"
"""

THETA = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])   # proportional damping, Rig()


def _records(rng):
    model = LinearModel(Rig(), "proportional")
    dt = 0.005
    t = np.arange(500) * dt
    out = []
    for k, amp in enumerate((2.0, -1.5)):
        v = amp * ((t > 0.1) & (t < 0.15))
        y = simulate_linear(model, THETA, v, dt)
        y = y + 2e-5 * rng.standard_normal(y.shape)
        out.append(Experiment(t, v, y, name="ab"[k]))
    return out


def _displaced_record():
    """A pulse response that starts with the carts displaced (not at rest)."""
    model = LinearModel(Rig(), "proportional")
    dt = 0.005
    t = np.arange(400) * dt
    v = 2.0 * ((t > 0.5) & (t < 0.55))
    y = simulate_linear(model, THETA, v, dt, x0=np.r_[2e-3, 1e-3, 0.0, np.zeros(3)])
    return t, v, y


def _write_csv(path, record):
    t, v, y = record
    np.savetxt(path, np.column_stack([t, v, y]), delimiter=",", header="t,v,x1,x2,x3",
               comments="")


@pytest.fixture
def described(tmp_path):
    def make(noise="white"):
        for name in ("a.csv", "b.csv"):
            (tmp_path / name).write_text("t,v,x1,x2,x3\n0,0,0,0,0\n")
        p = tmp_path / f"run-{noise}.toml"
        p.write_text(CONFIG.format(noise=noise))
        return load_config(p)
    return make


def test_sample_posterior_takes_the_description(described):
    """The description gives the same chain as its sections spelt out, with its [priors]
    and seed; a prior it does not override stays the default."""
    cfg = described()
    assert isinstance(cfg, RunDescription)
    exps = _records(np.random.default_rng(0))
    a = sample_posterior(exps, cfg, warn=False)
    model = LinearModel(Rig(), "proportional")
    priors = default_priors(model, noise="white").replace(
        {"g_v": LogUniform(2.0, 12.0)})
    b = sample_posterior(exps, model, LikelihoodSpec(noise="white"),
                         SamplerSpec(n_walkers=20, n_steps=30, burn=10, thin=2,
                                     moves=parse_moves("de"), warn=False),
                         priors=priors, rng=5)
    np.testing.assert_array_equal(a.chain, b.chain)
    i = a.priors.names.index("g_v")
    assert (a.priors.priors[i].lo, a.priors.priors[i].hi) == (2.0, 12.0)
    # negative control: without the override the prior, and so the chain, differ
    c = sample_posterior(exps, model, LikelihoodSpec(noise="white"),
                         SamplerSpec(n_walkers=20, n_steps=30, burn=10, thin=2,
                                     moves=parse_moves("de"), warn=False), rng=5)
    assert c.priors.priors[i] != a.priors.priors[i]
    assert not np.array_equal(c.chain, a.chain)


def test_a_setting_by_name_replaces_the_descriptions(described):
    cfg = described()
    exps = _records(np.random.default_rng(0))
    run = sample_posterior(exps, cfg, n_steps=24, burn=8, warn=False)
    assert run.chain.shape[0] == 24
    with pytest.raises(TypeError, match="run description"):
        sample_posterior(exps, {"noise": "white"})


def test_the_command_line_builds_the_description_of_the_file(described):
    """``bayesmodal sample``'s flags make the object the TOML file makes (same hash)."""
    cfg = described("ar1")
    args = argparse.Namespace(data=list(cfg.data.files), rig=None, per_record="none",
                              noise_scale="none", noise="ar1", initial_state="rest",
                              walkers=20, steps=30, burn=10, thin=2, seed=5, init="ball",
                              threads=1)
    flags = description_from_args(args, Rig(), "proportional")
    # the file also sets priors, [crossval] and [identify]: take those from it
    from dataclasses import replace
    same = replace(flags, model=replace(flags.model, priors=cfg.model.priors),
                   crossval=cfg.crossval, identify=cfg.identify)
    assert same.hash() == cfg.hash()
    assert flags.likelihood_spec() == cfg.likelihood_spec()
    assert flags.sampler_spec().n_walkers == cfg.sampler_spec().n_walkers
    # negative control: another seed on the command line is another run
    other = description_from_args(argparse.Namespace(**{**vars(args), "seed": 6}), Rig(),
                                  "proportional")
    assert replace(other, model=same.model, crossval=cfg.crossval,
                   identify=cfg.identify).hash() != cfg.hash()


def test_crossval_reads_the_descriptions_study(described):
    cfg = described()
    spec = cfg.crossval_spec()
    assert isinstance(spec, CrossvalSpec)
    assert (spec.n_steps, spec.n_predictive, spec.n_walkers) == (20, 20, 20)
    exps = _records(np.random.default_rng(1))
    res = crossval(exps, cfg, workers=1, joint=False)
    assert res.spec == spec
    assert [f.heldout for f in res.folds] == ["a", "b"]
    with pytest.raises(TypeError, match="CrossvalSpec or a run description"):
        crossval(exps, "de")


def test_diagnose_reads_the_identify_table(described):
    """``diagnose(records, description)`` takes the [identify] diagnosis options, its rig
    and its seed; ``weights = "auto"`` is resolved against the training records."""
    cfg = described()
    one, two = cfg.diagnose_spec(1), cfg.diagnose_spec(2)
    assert isinstance(one, DiagnoseSpec)
    assert (one.n_null, one.max_effects, one.posterior) == (21, 2, True)
    assert (one.weights, two.weights) == (None, "spread")   # one record: plain sum
    assert cfg.diagnosis_seed == 9
    assert "end_stop" in one.candidates   # Rig() has one drive: its end stop is tried
    with pytest.raises(TypeError, match="DiagnoseSpec or a run description"):
        diagnose(_records(np.random.default_rng(2)), "coulomb_friction")


@pytest.mark.parametrize("value, ok", [("estimate", True), ("free", False)])
def test_initial_state_is_a_likelihood_key(tmp_path, value, ok):
    (tmp_path / "a.csv").write_text("t,v,x1,x2,x3\n0,0,0,0,0\n")
    p = tmp_path / "r.toml"
    p.write_text(textwrap.dedent(f"""
        [data]
        files = ["a.csv"]
        [likelihood]
        noise = "white"
        initial_state = "{value}"
        [sampler]
        walkers = 40
        """))
    if ok:
        cfg = load_config(p)
        assert cfg.likelihood_spec().initial_state == value
        rest = RunConfig.from_flat({**cfg.to_dict(), "initial_state": "rest",
                                    "priors": cfg.model.priors})
        assert cfg.hash() != rest.hash()
        # a run samples each record's initial positions and velocities
        _write_csv(tmp_path / "a.csv", _displaced_record())
        prep = prepare_run(cfg)
        states = {f"{q}{i}_0" for q in "xv" for i in (1, 2, 3)}
        assert states <= set(prep.priors.names)
        assert not states & set(prepare_run(rest).priors.names)   # negative control
    else:
        with pytest.raises(ConfigError, match="likelihood.initial_state"):
            load_config(p)


def test_identify_options_without_enabled_are_refused(described, tmp_path):
    """Negative control of the table above: its options alone would be ignored."""
    text = CONFIG.format(noise="white").replace("enabled = true\n", "")
    for name in ("a.csv", "b.csv"):
        (tmp_path / name).write_text("t,v,x1,x2,x3\n0,0,0,0,0\n")
    p = tmp_path / "off.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match="identify.enabled"):
        load_config(p)
