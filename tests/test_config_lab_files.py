"""Run configurations read lab files as the command line does: ``[data] columns``,
``input_scale``, ``time_scale`` (and ``m_per_count``, or the rig's sensor scale) give the
records, and the fit, of ``--columns``, ``--input-scale``, ``--time-scale``."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import warnings

import numpy as np
import pytest
from test_data_layouts import MAP, V_PER_UNIT, logger_mat

from bayesmodal._errors import ConfigError
from bayesmodal.model.rigs import load_rig, rig_to_toml
from bayesmodal.runs.config import load_config, parse_config

CONFIG = """\
[data]
files = ["rec.mat"]
columns = {{ t = "time", v = "target_v", x1 = "enc1", x2 = "enc2" }}
input_scale = "{scale}"

[rig]
file = "two.toml"

[model]
damping = "proportional"
"""


def _quiet(fn, *a, **kw):
    """Call with the loader's warning (timestamps rounded to 1 ms) recorded, not raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*a, **kw)
    return out, [str(w.message) for w in caught]


def _cli_json(argv):
    from bayesmodal.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        code, _ = _quiet(main, argv)
    assert code == 0
    return json.loads(buf.getvalue())


@pytest.fixture
def lab(tmp_path):
    logger_mat(tmp_path / "rec.mat")   # two carts, counts, 4096 units per 5 V, 1 ms time
    rig = load_rig("ecp210-2cart")
    (tmp_path / "two.toml").write_text(rig_to_toml(rig))
    return tmp_path


def test_run_config_reads_a_lab_file_like_the_command_line(lab):
    from bayesmodal.cli._common import add_reader_arguments, add_rig_argument, load_args
    from bayesmodal.fit import fit_lsq
    from bayesmodal.runs import prepare_run

    (lab / "cfg.toml").write_text(CONFIG.format(scale="5/4096"))
    cfg = load_config(lab / "cfg.toml")
    assert cfg.data.columns == MAP and cfg.data.input_scale == V_PER_UNIT
    prep, warned_cfg = _quiet(prepare_run, cfg)
    # the command line's reading of the same file
    p = argparse.ArgumentParser()
    p.add_argument("data", nargs="+")
    add_reader_arguments(p)
    add_rig_argument(p)
    argv = [str(lab / "rec.mat"), "--columns", "t=time,v=target_v,x1=enc1,x2=enc2",
            "--input-scale", "5/4096", "--rig", str(lab / "two.toml")]
    (cli_exp,), warned_cli = _quiet(load_args, p.parse_args(argv))
    (cfg_exp,) = prep.experiments
    for a, b in ((cfg_exp.t_s, cli_exp.t_s), (cfg_exp.v_volt, cli_exp.v_volt),
                 (cfg_exp.y_m, cli_exp.y_m)):
        assert np.array_equal(a, b)
    assert warned_cfg == warned_cli and any("rounded to 0.001 s" in w for w in warned_cli)
    # and the fit: `bayesmodal lsq` on the command line, fit_lsq on the prepared run
    out = _cli_json(["lsq", *argv, "--damping", "proportional", "--json"])
    res, _ = _quiet(fit_lsq, list(prep.experiments), prep.model)
    assert out["parameters"] == res.params
    # negative control: without the input scale the volts are converter units
    (lab / "cfg.toml").write_text(CONFIG.format(scale="1"))
    with pytest.raises(ConfigError, match=r"\[data.files\].*input up to .* V is far beyond"):
        _quiet(prepare_run, load_config(lab / "cfg.toml"))


def test_lab_file_keys_leave_the_hash_alone_at_their_defaults():
    base = {"data": {"files": ["a.csv"]}}
    plain = parse_config(base, check_files=False)
    written = parse_config({"data": {"files": ["a.csv"], "input_scale": 1, "time_scale": "1"}},
                           check_files=False)
    assert written.hash() == plain.hash() and plain.data.columns is None
    mapped = parse_config({"data": {**base["data"], "columns": MAP}}, check_files=False)
    scaled = parse_config({"data": {**base["data"], "input_scale": "5/4096"}},
                          check_files=False)
    assert len({plain.hash(), mapped.hash(), scaled.hash()}) == 3
    assert mapped.to_dict()["columns"] == MAP   # recorded in config.json
    # the time base: "auto" is the default (same hash), another one is a new run
    auto = parse_config({"data": {**base["data"], "time_base": "auto"}}, check_files=False)
    grid = parse_config({"data": {**base["data"], "time_base": "grid"}}, check_files=False)
    assert auto.hash() == plain.hash() != grid.hash()
    assert grid.data.read_options().time_base == "grid"
    assert plain.data.read_options().time_base == "auto"


def test_rest_offset_reaches_the_reader_and_the_hash():
    base = {"data": {"files": ["a.csv"]}}
    plain = parse_config(base, check_files=False)
    none = parse_config({"data": {**base["data"], "rest_offset": "none", "release": "none"}},
                        check_files=False)
    initial = parse_config({"data": {**base["data"], "rest_offset": "initial"}},
                           check_files=False)
    # the default leaves the hash alone; another value is another run
    assert none.hash() == plain.hash() != initial.hash()
    assert initial.data.read_options().rest_offset == "initial"
    assert plain.data.read_options().rest_offset == "none"
    assert initial.to_dict()["rest_offset"] == "initial"   # recorded in config.json


def test_a_run_reads_a_record_with_its_rest_offset_removed(tmp_path):
    from bayesmodal.data import Experiment, save_csv
    from bayesmodal.runs import prepare_run

    t = np.arange(400) * 0.005
    v = 0.5 * (t >= 0.5)
    y = 1e-3 * (1 - np.exp(-np.clip(t - 0.5, 0, None) / 0.1))[:, None] * [1.0, 0.6, 0.3]
    offset = np.array([2e-4, -1e-4, 5e-5])
    save_csv(Experiment(t, v, y + offset), tmp_path / "rec.csv")
    cfg_text = '[data]\nfiles = ["rec.csv"]\nrest_offset = "{}"\n'
    (tmp_path / "cfg.toml").write_text(cfg_text.format("initial"))
    prep, _ = _quiet(prepare_run, load_config(tmp_path / "cfg.toml"))
    np.testing.assert_allclose(prep.experiments[0].y_m, y, atol=1e-15)
    # negative control: without the key the offset stays, and the run refuses the
    # record with the key that removes it
    (tmp_path / "cfg.toml").write_text(cfg_text.format("none"))
    with pytest.raises(ConfigError, match=r"\[data.files\] .*rec.csv: before the first "
                       r"input the carts rest with output 1 at 0.2 mm, not at 0 where a run "
                       r"starts every record; .*set rest_offset = \"initial\" in \[data\]"):
        _quiet(prepare_run, load_config(tmp_path / "cfg.toml"))


def test_rig_sensor_scale_is_the_default_counts_scale():
    rig = load_rig("ecp210-2cart")
    d = {"carts": [{"name": c.name} for c in rig.carts]}
    d["springs"] = [{"between": [s.a, s.b], "stiffness_n_m": s.stiffness_n_m}
                    for s in rig.springs]
    d["drive"] = {"carts": ["1"]}
    d["sensors"] = [{"cart": c.name, "unit": "count", "m_per_unit": 2.5e-6}
                    for c in rig.carts]
    cfg = parse_config({"data": {"files": ["a.mat"]}, "rig": d}, check_files=False)
    assert cfg.data.m_per_count == 2.5e-6
    explicit = parse_config({"data": {"files": ["a.mat"], "m_per_count": 1e-6}, "rig": d},
                            check_files=False)
    assert explicit.data.m_per_count == 1e-6


@pytest.mark.parametrize(("data", "key", "match"), [
    ({"columns": {"t": "time", "v": "u"}}, "data.columns", r"role\(s\) \['x1'\] missing"),
    ({"columns": {"t": "time", "v": "u", "x1": 1.5}}, "data.columns.x1",
     "column name or a 1-based column number"),
    ({"columns": {"q": "time", "t": "a", "v": "u", "x1": "e"}}, "data.columns",
     "unknown role 'q'"),
    ({"input_scale": "5/0"}, "data.input_scale", "not a number or fraction"),
    ({"time_scale": -1}, "data.time_scale", "must be finite and > 0"),
    ({"input_scale": True}, "data.input_scale", "not a number or fraction"),
    ({"time_base": "uniform"}, "data.time_base", "must be one of auto, stamps, grid"),
    ({"rest_offset": "first"}, "data.rest_offset", "must be one of none, initial, final"),
    ({"rest_offset": 1}, "data.rest_offset", "must be str, got 1"),
    ({"release": "auto"}, "data.release", "needs its initial state estimated, and a run "
     "starts every record from rest; fit it with `bayesmodal lsq`"),
    ({"release": "yes"}, "data.release", "must be 'none' in a run"),
])
def test_bad_lab_file_keys_name_the_key_and_the_fix(data, key, match):
    with pytest.raises(ConfigError, match=match) as info:
        parse_config({"data": {"files": ["a.csv"], **data}}, source="cfg.toml",
                     check_files=False)
    lines = str(info.value).splitlines()
    assert len(lines) == 2 and lines[1].startswith(f"cfg.toml: [{key}] ")
