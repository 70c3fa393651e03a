"""The ECP Executive's "export raw data" text files, read with no column map.

Files are written by ``tests/ecp_export_writer.py`` (independent of the reader) from a
record simulated at the Executive's sample period of 8.854 ms: times printed to 1 ms,
positions in whole counts, the control effort in volts.  ``bayesmodal lsq FILE`` must
read and fit it with no option and recover the truth within the fit's standard errors.
"""

from __future__ import annotations

import contextlib
import io
import json
import warnings

import numpy as np
import pytest
from conftest import run_cli as _cli
from ecp_export_writer import ECP_DT, M_PER_COUNT, write_export

from bayesmodal import DataError
from bayesmodal.cli import main
from bayesmodal.data import load_experiment
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
N = 1200
#: standard errors within which estimates must fall
K_SE = 4.0


def _truth():
    t = np.arange(N) * ECP_DT
    v = 0.5 * ((t % 4.0) < 2.0)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, ECP_DT)
    return t, v, y


def _load(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        e = load_experiment(path)
    return e, [str(w.message) for w in caught]


@pytest.mark.parametrize("commanded", [True, False])
def test_export_is_read_without_a_column_map(tmp_path, commanded):
    t, v, y = _truth()
    path = write_export(tmp_path / "export.txt", v, y, commanded=commanded)
    assert path.read_text().startswith(" Sample   Time")
    e, warned = _load(path)
    assert e.n_outputs == 3 and e.n_samples == N
    np.testing.assert_array_equal(e.v_volt, np.round(v, 4))
    # whole counts: within half a count of the truth
    assert np.max(np.abs(e.y_m - y)) <= 0.5 * M_PER_COUNT * (1 + 1e-9)
    # the period from the sample index: the slope of a line through N times rounded to
    # q = 1 ms (uniform errors of variance q^2 / 12) has the standard error below
    q = 1e-3
    k = np.arange(N)
    se_dt = np.sqrt(q**2 / 12 / np.sum((k - k.mean()) ** 2))
    assert abs(e.dt - ECP_DT) < K_SE * se_dt
    assert len(warned) == 1, warned
    assert warned[0].startswith(f"{path}: ECP Executive export: times printed to 0.001 s; "
                                "the sample period 0.00885")
    assert "recovered from the Sample index by a linear fit" in warned[0]


def test_lsq_fits_an_export_with_one_command_line(tmp_path):
    t, v, y = _truth()
    path = write_export(tmp_path / "export.txt", v, y)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings():
        warnings.simplefilter("always")
        code = main(["lsq", str(path), "--json"])
    lines = err.getvalue().splitlines()
    assert code == 0, lines
    assert len(lines) == 1 and lines[0].startswith("bayesmodal lsq: warning: ")
    js = json.loads(out.getvalue())
    assert js["identified"] is True
    names = list(js["parameters"])
    theta = np.array([js["parameters"][n] for n in names])
    se = np.array([js["stderr"][n] for n in names])
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se


def test_a_ragged_export_names_the_line(tmp_path):
    t, v, y = _truth()
    path = write_export(tmp_path / "cut.txt", v[:50], y[:50])
    lines = path.read_text().splitlines()
    lines[10] = lines[10].rsplit(" ", 1)[0]  # the control effort cut off
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"cut.txt: line 11 has 6 values, the header names 7 "
                       r"columns \(Sample, Time, Commanded Pos, Encoder 1 Pos"):
        load_experiment(path)


def test_an_export_read_with_a_column_map(tmp_path):
    t, v, y = _truth()
    path = write_export(tmp_path / "export.txt", v, y)
    from bayesmodal.reading import ReadOptions

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = load_experiment(path, options=ReadOptions(columns={
            "t": "Time", "v": "Control Effort", "x1": "Encoder 3 Pos"}))
    assert e.n_outputs == 1
    assert np.max(np.abs(e.y_m[:, 0] - y[:, 2])) <= 0.5 * M_PER_COUNT * (1 + 1e-9)
    assert abs(e.dt - ECP_DT) < 1e-6


#: The torsional plant's encoders: 16 000 counts per revolution, rad per count.
RAD_PER_COUNT = 2 * np.pi / 16000

#: A torsional truth: g_v N m/V, disk inertias kg m^2, dampers N m s/rad (free damping).
THETA_TORSION = np.array([0.12, 0.0025, 0.0023, 0.0021, 0.004, 0.003, 0.005, 0.0, 0.0])

TORSION_RIG = f"""\
name = "three disks on torsion shafts, the third shaft to the frame"
[[carts]]
name = "1"
mass = "nominal"
mass_kg = 0.002
[[carts]]
name = "2"
mass = "nominal"
mass_kg = 0.002
[[carts]]
name = "3"
mass = "nominal"
mass_kg = 0.002
[[springs]]
between = ["1", "2"]
stiffness_n_m = 2.7
[[springs]]
between = ["2", "3"]
stiffness_n_m = 2.6
[[springs]]
between = ["3", "frame"]
stiffness_n_m = 2.5
[drive]
carts = ["1"]
{"".join(f'[[sensors]]{chr(10)}cart = "{i}"{chr(10)}unit = "count"{chr(10)}'
         f'm_per_unit = {RAD_PER_COUNT!r}{chr(10)}' for i in (1, 2, 3))}"""


def test_a_torsional_export_is_read_the_same_way(tmp_path):
    # the torsional plant's export has the same columns; only the encoders count angle:
    # the rig's rad per count (or --m-per-count) converts them, and the model's
    # "masses" and "springs" are the disks' inertias and the shafts' stiffnesses (the
    # inertias nominal at 0.002 kg m^2: the fit's default start of 1 kg is a rectilinear
    # cart's)
    from bayesmodal.model.rigs import load_rig

    rig_path = tmp_path / "torsion.toml"
    rig_path.write_text(TORSION_RIG)
    model = LinearModel(load_rig(str(rig_path)), "free")
    t = np.arange(N) * ECP_DT
    v = 0.5 * ((t % 4.0) < 2.0)
    y = simulate_linear(model, THETA_TORSION, v, ECP_DT)   # rad
    path = write_export(tmp_path / "torsion.txt", v, y, per_count=RAD_PER_COUNT)
    code, out, err = _cli(["lsq", str(path), "--rig", str(rig_path), "--json"])
    assert code == 0 and len(err) == 1 and "ECP Executive export" in err[0], err
    js = json.loads(out)
    assert js["identified"] is True
    theta = np.array(list(js["parameters"].values()))
    se = np.array(list(js["stderr"].values()))
    assert np.all(np.abs(theta - THETA_TORSION) < K_SE * se), (theta - THETA_TORSION) / se
    # the same export read with the rectilinear default (m per count) is not in radians
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the rounded times
        e = load_experiment(path)
    assert np.max(np.abs(e.y_m)) < 0.02 * np.max(np.abs(y))
