"""One parser for the noise model's name (``bayesmodal.inference.noise_spec``)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest

from bayesmodal import ConfigError, DataError
from bayesmodal.inference import likelihood, priors
from bayesmodal.inference.noise import (
    AR1Noise,
    ARpNoise,
    IntegratedAR1Noise,
    ProcessNoise,
    WhiteNoise,
)
from bayesmodal.inference.noise_choice import resolve_noise
from bayesmodal.inference.noise_spec import (
    NOISE_KINDS,
    NOISE_MODELS,
    NoiseSpec,
    accepted_noise,
    parse_noise,
)

PACKAGE = Path(__file__).resolve().parents[1] / "bayesmodal"

ACCEPTED = ["white", "ar1", "iar1", "process", "ar:auto", "ar4", "ar12", "ar0", "ar01",
            "ar(2,3,1)", "ar(4)", "ar(02,3)", " AR1 ", "Ar 4", "ar( 2, 3 )", "WHITE"]
REJECTED = ["pink", "arma", "ar", "ar()", "ar(1,)", "ar(,1)", "ar:4", "ar-1", "ar1.5",
            "auto", "ar:auto2", "iar2", "", "ar(1;2)"]


def _old_rule(text: str) -> bool:
    """What ``resolve_noise`` and the run configuration accepted before the parser (their
    regular expressions, on the lower-case text without spaces)."""
    t = text.strip().lower().replace(" ", "")
    return t in ("ar1", "white", "iar1", "process", "ar:auto") or bool(
        re.fullmatch(r"ar\d+|ar\(\d+(,\d+)*\)", t))


@pytest.mark.parametrize("text", ACCEPTED + REJECTED)
def test_accepts_what_was_accepted(text):
    assert _old_rule(text) == (text in ACCEPTED)   # the lists above are right
    if text in ACCEPTED:
        assert isinstance(parse_noise(text), NoiseSpec)
    else:
        with pytest.raises(ConfigError, match=r"^noise model .*: use 'white', 'ar1'"):
            parse_noise(text)


@pytest.mark.parametrize("text", ACCEPTED)
def test_name_round_trips(text):
    spec = parse_noise(text)
    assert parse_noise(spec.name) == spec
    assert spec.name == spec.name.strip().lower().replace(" ", "")
    assert parse_noise(spec) is spec


def test_kinds_and_orders():
    assert parse_noise("ar1") == NoiseSpec("ar1")                 # AR(1), not AR(p=1)
    assert parse_noise("ar01") == NoiseSpec("arp", (1,))
    assert parse_noise("ar01").name == "ar01"
    assert parse_noise("ar4") == NoiseSpec("arp", (4,), per_output=False)
    assert parse_noise("ar(2,3,1)") == NoiseSpec("arp", (2, 3, 1), per_output=True)
    assert parse_noise("ar(2, 3)").name == "ar(2,3)"
    assert [parse_noise(t).one_record for t in ("white", "ar1", "ar4", "iar1", "process")] \
        == [True, True, False, False, False]


@pytest.mark.parametrize("text, cls, n_params", [
    ("white", WhiteNoise, 3), ("ar1", AR1Noise, 6), ("iar1", IntegratedAR1Noise, 6),
    ("ar2", ARpNoise, 9), ("ar(1,2,3)", ARpNoise, 9), ("ar01", ARpNoise, 6),
    ("process", ProcessNoise, None)])
def test_spec_builds_the_noise_model(text, cls, n_params):
    model = resolve_noise(text, 3)
    assert type(model) is cls
    assert model == parse_noise(text).model(3)
    if n_params is not None:
        assert len(model.names(3)) == n_params


def test_spec_errors():
    with pytest.raises(DataError, match="one order per output"):
        parse_noise("ar(2,3)").model(3)
    with pytest.raises(ConfigError, match="choose_noise"):
        parse_noise("ar:auto").model(3)
    # every kind of the registry is named in the error message, as written there
    with pytest.raises(ConfigError) as info:
        parse_noise("pink")
    for k in NOISE_KINDS:
        assert k.syntax in str(info.value)


def test_noise_models_defined_once():
    assert NOISE_MODELS == ("ar1", "white")
    assert likelihood.NOISE_MODELS is NOISE_MODELS
    assigned = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = getattr(node, "targets", None) or [getattr(node, "target", None)]
            if isinstance(node, ast.Assign | ast.AnnAssign) and any(
                    isinstance(t, ast.Name) and t.id == "NOISE_MODELS" for t in targets):
                assigned.append(path.name)
    assert assigned == ["noise_spec.py"]


def test_noise_names_follow_the_models():
    assert priors.noise_names(2, "ar1") == ("sigma_1", "sigma_2", "phi_1", "phi_2")
    assert priors.noise_names(2, "white") == ("sigma_1", "sigma_2")
    with pytest.raises(ConfigError, match="noise must be 'ar1' or 'white', got 'ar4'"):
        priors.noise_names(2, "ar4")


def test_run_configuration_uses_the_parser(tmp_path):
    from bayesmodal.runs.config import load_config

    def cfg(noise):
        (tmp_path / "exp.csv").write_text("t,v,x1,x2,x3\n0,0,0,0,0\n", encoding="utf-8")
        p = tmp_path / "run.toml"
        p.write_text(f'[data]\nfiles=["exp.csv"]\n[likelihood]\nnoise="{noise}"\n',
                     encoding="utf-8")
        return load_config(p)

    assert cfg("ar1").layout is None                  # the single-record likelihood
    assert cfg("ar(2,3,1)").layout is not None        # the several-record likelihood
    assert cfg("ar:auto").likelihood.noise == "ar:auto"  # stored as written: hashes unchanged
    # the message lists what the parser accepts, from the registry (accepted_noise)
    with pytest.raises(ConfigError) as bad:
        cfg("arma")
    want = f"[likelihood.noise] must be one of {accepted_noise()}, got 'arma'"
    assert want in str(bad.value)


def test_a_spelling_takes_the_path_of_its_canonical_name():
    # " AR1" is AR(1) noise in the single-record likelihood, exactly as "ar1"
    from bayesmodal.data import Experiment
    from bayesmodal.inference import sample_posterior
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig

    model = LinearModel(Rig(), "proportional")
    t = np.arange(300) * 0.005
    v = 3.0 * (t < 0.05)
    y = simulate_linear(model, [6.2, 1.5, 1.4, 1.1, 1.5, 1e-4], v, 0.005)
    y = y + 1e-5 * np.random.default_rng(1).standard_normal(y.shape)
    # (refine=False: the posterior-mode refinement would take seconds and is not the point)
    runs = [sample_posterior(Experiment(t, v, y), model, noise=n, n_steps=4, n_walkers=32,
                             refine=False, rng=3, warn=False) for n in ("ar1", " AR1")]
    assert type(runs[0].likelihood) is type(runs[1].likelihood) is likelihood.Likelihood
    np.testing.assert_array_equal(runs[0].chain, runs[1].chain)
