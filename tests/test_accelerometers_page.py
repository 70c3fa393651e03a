"""docs/accelerometers.md says true things about the records it uses.

The records ``data/accel_hammer.csv`` and ``data/accel_sweep.csv`` are made by
``data/make_accel_examples.py`` from the rig of ``data/accel_rig.toml``; tests/test_docs.py
runs the page's commands, this file checks what the page claims about them.
"""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

from bayesmodal.data import load_experiment, options_for_rig
from bayesmodal.fit import fit_lsq
from bayesmodal.modal import state_space_modes
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.system import LinearModel
from bayesmodal.reading import ReadOptions

Z_BOUND = 3.5  # as tests/test_ema_record_frf.py: four quantities, each |z| < 3.5

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "accelerometers.md"
RIG = REPO / "data" / "accel_rig.toml"


def _maker():
    spec = importlib.util.spec_from_file_location("make_accel_examples",
                                                  REPO / "data" / "make_accel_examples.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _read(name):
    rig = load_rig(RIG)
    path = REPO / "data" / name
    return rig, load_experiment(path, options=options_for_rig(ReadOptions(), rig, path))


def test_page_shows_lines_of_the_rig_file():
    shown = re.search(r"^```toml\n(.*?)^```$", PAGE.read_text(encoding="utf-8"),
                      re.M | re.S).group(1)
    rig_text = RIG.read_text(encoding="utf-8")
    for line in shown.splitlines():
        assert line in rig_text, line


@pytest.mark.parametrize("name, make", [("accel_hammer.csv", "hammer"),
                                        ("accel_sweep.csv", "sweep")])
def test_records_are_what_the_script_makes(name, make):
    """Equal to the script's output within one logger step (the simulation's round-off
    may move a value across a step boundary on another machine)."""
    mod = _maker()
    made = getattr(mod, make)()
    _, e = _read(name)
    np.testing.assert_allclose(e.t_s, made.t_s, atol=1e-12)
    assert np.max(np.abs(e.v_volt - made.v_volt)) <= mod.STEP_FORCE * 1.000001
    assert np.max(np.abs(e.y_m - made.y_m)) <= mod.STEP_ACC * 1.000001
    # (the file keeps 6 digits of values on the logger's steps)
    assert np.mean(np.isclose(e.y_m, made.y_m, rtol=1e-6, atol=1e-12)) > 0.99


def test_quoted_truth_and_fit():
    mod = _maker()
    rig, e = _read("accel_hammer.csv")
    model = LinearModel(rig, "free")
    truth = np.array([mod.TRUE[n] for n in model.names])
    modes = state_space_modes(model, truth)
    np.testing.assert_allclose(modes.omega_rad_s, [11.45, 33.82], atol=0.005)
    np.testing.assert_allclose(modes.zeta, [0.0341, 0.0168], atol=0.00005)
    res = fit_lsq(e, model)
    rel = np.abs(res.theta - truth) / truth
    assert np.all(rel[:2] < 2e-4) and np.all(rel[2:] < 1e-2)
    z = (res.theta - truth) / res.stderr
    assert abs(z[1]) == pytest.approx(7.6, abs=0.05)
    assert abs(rel[1] * 100) == pytest.approx(0.016, abs=0.0005)


def test_ema_command_reads_the_rigs_sensor_kinds(tmp_path, capsys):
    """``bayesmodal ema --rig``: the hammer test's impact FRF in the rig's form and units
    (accelerance per newton) and the accelerance fitted in the sampled-data basis; without
    the rig the file is read as volts and positions, and its 55 N hits are refused as a
    voltage (the control)."""
    from bayesmodal.cli import main

    mod = _maker()
    path = tmp_path / "accel_hammer.csv"
    mod.write(mod.hammer(), path)
    path = str(path)
    args = ["ema", path, "--method", "multimode", "--n-modes", "2", "--band", "5", "60"]
    assert main(args + ["--rig", str(RIG)]) == 0
    out = capsys.readouterr().out
    assert "impact FRF in m/s^2/N (H1, 3 average(s))" in out and "sampled-data basis" in out
    assert main(args) == 2
    assert "beyond the rig's +-10 V command" in capsys.readouterr().err


def _ema_json(capsys, *extra):
    from bayesmodal.cli import main

    path = str(REPO / "data" / "accel_hammer.csv")
    assert main(["ema", path, "--rig", str(RIG), "--method", "multimode", "--json",
                 *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_ema_command_on_the_hammer_test_within_its_stated_errors(capsys):
    """The command of docs/ema.md and section 5 of the page: ``--frf auto`` takes the
    impact estimate, and omega and zeta of both modes lie within ``Z_BOUND`` stated errors
    of the rig's eigenvalues (the bound of tests/test_ema_record_frf.py); ``--frf welch``
    on the same file is the control, zeta_1 about twice the truth, as docs/ema.md
    quotes it (to the printed digits)."""
    mod = _maker()
    rig, _ = _read("accel_hammer.csv")
    model = LinearModel(rig, "free")
    modes = state_space_modes(model, np.array([mod.TRUE[n] for n in model.names]))
    truth = np.r_[modes.omega_rad_s, modes.zeta]
    auto = _ema_json(capsys)
    assert auto["frf_method"] == "impact" and auto["frf_units"] == "m/s^2/N"
    est = np.r_[auto["omega_rad_s"], auto["zeta"]]
    se = np.r_[auto["omega_se_rad_s"], auto["zeta_se"]]
    assert np.max(np.abs(est - truth) / se) < Z_BOUND
    assert auto["zeta"][0] == pytest.approx(0.0341, abs=5e-5)
    welch = _ema_json(capsys, "--frf", "welch")
    assert welch["frf_method"] == "welch"
    assert (welch["zeta"][0] - truth[2]) / welch["zeta_se"][0] > Z_BOUND
    assert welch["zeta"][0] == pytest.approx(0.0665, abs=5e-5)
    assert welch["zeta_se"][0] == pytest.approx(0.0022, abs=5e-5)
