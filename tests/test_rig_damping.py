"""A rig description that declares its damping model (``[dampers] proportional = true``):
the same fit as ``--damping proportional``, and one-line errors for contradictions."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from bayesmodal._errors import ConfigError, ModelError
from bayesmodal.data import Experiment, save_csv
from bayesmodal.model.rigs import load_rig, rig_from_dict, rig_from_toml, rig_to_dict, rig_to_toml
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel

TWO = load_rig("ecp210-2cart")


def _declared(value: bool) -> dict:
    d = rig_to_dict(TWO)
    d["dampers"] = {"proportional": value}
    return d


def _record(tmp_path):
    model = LinearModel(TWO, "proportional")
    dt, n = 0.005, 800
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = model.as_vector({"g_v": 6.2, "m1": 1.5, "m2": 1.45, "ca": 1.2, "cb": 1e-3})
    y = simulate_linear(model, theta, v, dt)
    y = y + 1e-5 * np.random.default_rng(3).standard_normal(y.shape)
    save_csv(Experiment(t, v, y, name="two"), tmp_path / "two.csv")
    return tmp_path / "two.csv"


def _lsq(argv) -> tuple[int, dict | None]:
    from bayesmodal.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv)
    return code, json.loads(buf.getvalue()) if code == 0 else None


def test_declared_proportional_is_the_damping_option(tmp_path):
    rig = rig_from_dict(_declared(True))
    assert rig.damping == "proportional" and TWO.damping is None
    # the matrices of the declared rig are those of the plain rig with the option
    theta = np.array([6.2, 1.5, 1.45, 1.2, 1e-3])
    for a, b in zip(LinearModel(rig, "proportional").matrices(theta),
                    LinearModel(TWO, "proportional").matrices(theta), strict=True):
        assert np.array_equal(a, b)
    # round trip through TOML keeps the declaration
    assert rig_from_toml(rig_to_toml(rig)) == rig
    assert rig_from_toml(rig_to_toml(rig_from_dict(_declared(False)))).damping == "free"
    # the CLI: declared in the file, no --damping, gives the --damping proportional fit
    data = _record(tmp_path)
    (tmp_path / "prop.toml").write_text(rig_to_toml(rig))
    (tmp_path / "plain.toml").write_text(rig_to_toml(TWO))
    code, declared = _lsq(["lsq", str(data), "--rig", str(tmp_path / "prop.toml"), "--json"])
    assert code == 0
    code, option = _lsq(["lsq", str(data), "--rig", str(tmp_path / "plain.toml"),
                         "--damping", "proportional", "--json"])
    assert code == 0
    assert declared == option and declared["damping"] == "proportional"
    # negative control: the plain rig without the option fits the free model
    code, free = _lsq(["lsq", str(data), "--rig", str(tmp_path / "plain.toml"), "--json"])
    assert code == 0 and free["damping"] == "free" and set(free["parameters"]) != set(
        declared["parameters"])


def test_contradictory_declarations_give_one_line_errors(tmp_path, capsys):
    both = _declared(True)
    both["dampers"]["ground"] = ["1"]
    with pytest.raises(ModelError, match="contradicts the listed dampers") as info:
        rig_from_dict(both, where="my_rig.toml")
    assert "\n" not in str(info.value) and str(info.value).startswith("my_rig.toml: ")
    with pytest.raises(ModelError, match="must be true or false"):
        rig_from_dict({**_declared(True), "dampers": {"proportional": "yes"}})
    rig = rig_from_dict(_declared(True))
    with pytest.raises(ModelError, match=r"declares proportional damping \(\[dampers\] "
                       r"proportional = true\) but free") as info:
        LinearModel(rig, "free")
    assert "\n" not in str(info.value)
    # on the command line: --damping free against the file, exit status 2, one line
    data = _record(tmp_path)
    (tmp_path / "prop.toml").write_text(rig_to_toml(rig))
    code, _ = _lsq(["lsq", str(data), "--rig", str(tmp_path / "prop.toml"),
                    "--damping", "free"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "declares proportional damping" in err and "\n" not in err
    # and in a run configuration
    from bayesmodal.runs.config import parse_config

    base = {"data": {"files": ["x.csv"]}, "rig": _declared(True)}
    assert parse_config(base, check_files=False).model.damping == "proportional"
    with pytest.raises(ConfigError, match=r"\[model.damping\] 'free' contradicts"):
        parse_config({**base, "model": {"damping": "free"}}, check_files=False)
    assert parse_config({**base, "model": {"damping": "proportional"}},
                        check_files=False).model.damping == "proportional"


def test_an_undeclared_rig_keeps_its_config_hash():
    from bayesmodal.runs.config import parse_config

    base = {"data": {"files": ["x.csv"]}}
    plain = parse_config({**base, "rig": rig_to_dict(TWO)}, check_files=False)
    assert "proportional" not in plain.model.rig["dampers"]
    assert plain.model.damping == "free"
    declared = parse_config({**base, "rig": _declared(False)}, check_files=False)
    assert declared.hash() != plain.hash()   # a declaration is part of the description
