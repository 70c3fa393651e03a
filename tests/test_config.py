"""Run configurations: good files parse, every bad one is refused naming the key."""

import textwrap

import pytest

from bayesmodal import ConfigError
from bayesmodal.runs.config import load_config, parse_config

GOOD = """
[data]
files = ["exp.csv"]

[model]
damping = "proportional"

[priors]
m1 = [0.5, 3.0]
g_v = { lo = 2.0, hi = 10.0, scale = "log" }

[likelihood]
noise = "white"

[sampler]
walkers = 16
steps = 200
burn = 50
thin = 2
seed = 7
moves = "de:0.8,de-snooker:0.2"

[outputs]
dir = "my-run"
"""


@pytest.fixture
def cfg_dir(tmp_path):
    (tmp_path / "exp.csv").write_text("t,v,x1,x2,x3\n0,0,0,0,0\n0.01,0,0,0,0\n0.02,0,0,0,0\n")
    return tmp_path


def test_good_config_parses(cfg_dir):
    p = cfg_dir / "good.toml"
    p.write_text(GOOD)
    c = load_config(p)
    assert c.name == "good"
    assert c.model.damping == "proportional" and c.likelihood.noise == "white"
    assert c.sampler.walkers == 16 and c.sampler.seed == 7
    assert c.model.priors["g_v"].scale == "log"
    assert c.data.files[0].endswith("exp.csv")
    # the hash ignores where the file lives and the output folder
    c2 = parse_config({**_toml(GOOD), "outputs": {"dir": "elsewhere"}}, base=cfg_dir)
    assert c2.hash() == c.hash()
    c3 = parse_config({**_toml(GOOD), "sampler": {"seed": 8}}, base=cfg_dir)
    assert c3.hash() != c.hash()


def _toml(text):
    import tomllib

    return tomllib.loads(text)


BAD = [
    # (description, toml text, key named in the message)
    ("unknown section", '[data]\nfiles=["exp.csv"]\n[samplr]\nwalkers=4', "[samplr]"),
    ("unknown key", '[data]\nfiles=["exp.csv"]\n[sampler]\nwalker=4', "[sampler.walker]"),
    ("missing data", "[sampler]\nwalkers=8", "[data.files]"),
    ("empty data list", "[data]\nfiles=[]", "[data.files]"),
    ("missing file", '[data]\nfiles=["nope.mat"]', "file not found"),
    ("wrong type walkers", '[data]\nfiles=["exp.csv"]\n[sampler]\nwalkers="many"',
     "[sampler.walkers]"),
    ("bool as int", '[data]\nfiles=["exp.csv"]\n[sampler]\nsteps=true', "[sampler.steps]"),
    ("too few walkers", '[data]\nfiles=["exp.csv"]\n[sampler]\nwalkers=2', "[sampler.walkers]"),
    ("burn beyond steps", '[data]\nfiles=["exp.csv"]\n[sampler]\nsteps=10\nburn=10',
     "[sampler.burn]"),
    ("restart after burn-in", '[data]\nfiles=["exp.csv"]\n[sampler]\nburn=100\nrestart=100',
     "[sampler.restart]"),
    ("restart not a step", '[data]\nfiles=["exp.csv"]\n[sampler]\nrestart=0.5',
     "[sampler.restart]"),
    ("prune after burn-in", '[data]\nfiles=["exp.csv"]\n[sampler]\nburn=100\nprune=100',
     "[sampler.prune]"),
    ("prune and restart", '[data]\nfiles=["exp.csv"]\n[sampler]\nprune=10\nrestart=10',
     "[sampler.prune]"),
    ("prune after the folds' burn-in",
     '[data]\nfiles=["exp.csv"]\n[sampler]\nburn=100\nprune=50\n[crossval]\nsteps=100',
     "[crossval.steps]"),
    ("unknown damping", '[data]\nfiles=["exp.csv"]\n[model]\ndamping="rayleighish"',
     "[model.damping]"),
    ("unknown noise", '[data]\nfiles=["exp.csv"]\n[likelihood]\nnoise="pink"',
     "[likelihood.noise]"),
    ("unknown move", '[data]\nfiles=["exp.csv"]\n[sampler]\nmoves="hamiltonian"',
     "[sampler.moves]"),
    ("bad move weight", '[data]\nfiles=["exp.csv"]\n[sampler]\nmoves="de:-1"',
     "[sampler.moves]"),
    ("unknown extension", '[data]\nfiles=["exp.csv"]\n[model]\nextensions=["magic"]',
     "[model.extensions]"),
    ("prior lo >= hi", '[data]\nfiles=["exp.csv"]\n[priors]\nm1=[3.0, 1.0]', "[priors.m1]"),
    ("negative mass prior", '[data]\nfiles=["exp.csv"]\n[priors]\nm2=[-1.0, 1.0]',
     "[priors.m2]"),
    ("negative damping prior", '[data]\nfiles=["exp.csv"]\n[priors]\nc1=[-1.0, 1.0]',
     "[priors.c1]"),
    ("log prior at zero", '[data]\nfiles=["exp.csv"]\n[priors]\nc2={lo=0.0, hi=1.0, scale="log"}',
     "[priors.c2]"),
    ("prior of unknown parameter", '[data]\nfiles=["exp.csv"]\n[priors]\nk9=[0.0, 1.0]',
     "[priors.k9]"),
    ("prior not numbers", '[data]\nfiles=["exp.csv"]\n[priors]\nm1=["a", "b"]', "[priors.m1]"),
    ("output escapes root", '[data]\nfiles=["exp.csv"]\n[outputs]\ndir="../../etc"',
     "[outputs.dir]"),
    ("absolute output", '[data]\nfiles=["exp.csv"]\n[outputs]\ndir="/tmp/x"', "[outputs.dir]"),
    ("negative springs", '[data]\nfiles=["exp.csv"]\n[rig]\nsprings_n_m=[774, -1, 396]',
     "[rig.springs_n_m]"),
    ("bad counts factor", '[data]\nfiles=["exp.csv"]\nm_per_count=0', "[data.m_per_count]"),
    ("unknown temperature word", '[data]\nfiles=["exp.csv"]\n[likelihood]\n'
     'temperature="auto"', "[likelihood.temperature]"),
]


@pytest.mark.parametrize("desc,text,key", BAD, ids=[b[0] for b in BAD])
def test_bad_configs_are_refused_naming_the_key(cfg_dir, desc, text, key):
    p = cfg_dir / "bad.toml"
    p.write_text(textwrap.dedent(text))
    with pytest.raises(ConfigError) as info:
        load_config(p)
    msg = str(info.value)
    assert key in msg
    assert str(p) in msg


def test_all_problems_reported_at_once(cfg_dir):
    p = cfg_dir / "many.toml"
    p.write_text('[data]\nfiles=["exp.csv"]\n[sampler]\nwalkers=1\nseed=-3\n[oops]\nx=1\n')
    with pytest.raises(ConfigError, match="3 problem") as info:
        load_config(p)
    for key in ("[sampler.walkers]", "[sampler.seed]", "[oops]"):
        assert key in str(info.value)


def test_broken_toml_and_missing_file(cfg_dir):
    p = cfg_dir / "broken.toml"
    p.write_text("[data\nfiles = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(p)
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(cfg_dir / "absent.toml")


def test_calibrated_temperature_is_accepted(cfg_dir):
    c = parse_config({**_toml(GOOD), "likelihood": {"noise": "ar1", "temperature": "loro"}},
                     base=cfg_dir)
    assert c.likelihood.temperature == "loro"
    assert c.crossval_spec().temperature == 1.0  # each calibration study sets its own
    fixed = parse_config({**_toml(GOOD), "likelihood": {"noise": "ar1", "temperature": 1}},
                         base=cfg_dir)
    assert c.hash() != fixed.hash()


def test_snooker_runs_hash_apart_from_the_released_move(cfg_dir, monkeypatch):
    """A configuration naming the snooker move hashes with the corrected move's revision,
    so a run sampled with emcee 3.1.6's contracting move (same TOML) does not resume; a
    configuration without it keeps its hash."""
    import bayesmodal.runs.description as description

    snooker = parse_config(_toml(GOOD), base=cfg_dir)
    assert "de-snooker" in snooker.sampler.moves
    de = parse_config({**_toml(GOOD), "sampler": {**_toml(GOOD)["sampler"], "moves": "de"}},
                      base=cfg_dir)
    now = snooker.hash(), de.hash()
    monkeypatch.setattr(description, "MOVE_REVISIONS", {})
    assert snooker.hash() != now[0]
    assert de.hash() == now[1]


def test_lugre_runs_hash_apart_from_the_eight_substep_kernel(cfg_dir, monkeypatch):
    """A configuration with LuGre friction hashes with the kernel's revision (4 sub-steps
    since 25 Nov 2026), in the run configuration and in the sampler's own hash, so a run
    sampled with 8 sub-steps does not resume into the new target; others keep theirs."""
    import bayesmodal.runs.config as config
    from bayesmodal.model.effects import get_extension

    def cfg(exts):
        model = {**_toml(GOOD)["model"], "damping": "free", "extensions": exts}
        return parse_config({**_toml(GOOD), "model": model}, base=cfg_dir)

    lugre, coulomb = cfg(["lugre_friction", "input_offset"]), cfg(["coulomb_friction"])
    now = lugre.hash(), coulomb.hash()
    assert config.extension_revisions(get_extension("lugre_friction+input_offset").name) == {
        "lugre_friction": "n_sub=4"}
    assert config.extension_revisions(get_extension("coulomb_friction").name) == {}
    import bayesmodal.model.effects as effects  # the registry owns the revisions

    monkeypatch.setattr(effects, "EXTENSION_REVISIONS", {})
    assert lugre.hash() != now[0]
    assert coulomb.hash() == now[1]


def test_the_description_has_one_section_per_table(cfg_dir):
    """Each key of the file lands in the section of its table under its own name, and the
    flat form (``config.json``) reads back into the same description."""
    from dataclasses import fields

    from bayesmodal.runs.description import FLAT_NAMES, SECTIONS, RunConfig

    c = parse_config(_toml(GOOD), base=cfg_dir)
    assert c.sampler.walkers == _toml(GOOD)["sampler"]["walkers"]
    assert c.model.priors["g_v"].scale == _toml(GOOD)["priors"]["g_v"]["scale"]
    # every section field has exactly one flat name, and every flat name one field
    section_fields = {(s, f.name) for s, cls in SECTIONS.items() for f in fields(cls)}
    assert sorted(FLAT_NAMES.values()) == sorted(section_fields)
    flat = c.to_dict()
    flat["priors"] = c.model.priors  # config.json holds them as tables; rerun reads them
    back = RunConfig.from_flat(flat)
    assert back == c and back.hash() == c.hash()


def test_a_section_of_the_wrong_type_is_refused(cfg_dir):
    """Negative control: a flat keyword or a plain table where a section belongs."""
    from bayesmodal.runs.description import RunConfig

    c = parse_config(_toml(GOOD), base=cfg_dir)
    with pytest.raises(ConfigError, match="RunConfig.sampler must be a SamplerSection"):
        RunConfig(name="x", source="y", data=c.data, sampler={"walkers": 8})
    with pytest.raises(TypeError, match="unknown field"):
        RunConfig.from_flat({**c.to_dict(), "walker": 8})
