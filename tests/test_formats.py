"""Instrument files: UFF/UNV dataset 58 time records and TDMS channels.

Files are written by ``tests/instrument_writers.py`` (pyuff's and npTDMS's own writers)
from a record simulated with a known truth and seeded noise; ``bayesmodal lsq FILE`` must
read and fit each with one command line and recover the truth within the fit's own
standard errors.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys

import numpy as np
import pytest
from instrument_writers import write_tdms, write_uff58

from bayesmodal import DataError
from bayesmodal.cli import main
from bayesmodal.data import load_experiment
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import ReadOptions

pytest.importorskip("pyuff")
pytest.importorskip("nptdms")

THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])
DT = 0.01
N = 1200
#: noise of the positions, m (a few encoder counts)
SIGMA_M = 2e-5
#: standard errors within which estimates must fall
K_SE = 4.0


def _truth(seed=38):
    t = np.arange(N) * DT
    v = 0.5 * ((t % 4.0) < 2.0)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, DT)
    rng = np.random.default_rng(seed)
    return v, y + SIGMA_M * rng.standard_normal(y.shape)


def _lsq(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["lsq", *argv, "--json"])
    assert code == 0, err.getvalue()
    assert err.getvalue() == ""
    return json.loads(out.getvalue())


def _recovered(js):
    assert js["identified"] is True, js["reason"]
    names = list(js["parameters"])
    theta = np.array([js["parameters"][n] for n in names])
    se = np.array([js["stderr"][n] for n in names])
    assert np.all(np.abs(theta - THETA) < K_SE * se), (theta - THETA) / se


def test_uff58_lsq_recovers_the_truth(tmp_path):
    # one output in each unit, the second measured along -X
    v, y = _truth()
    path = write_uff58(tmp_path / "rec.uff", DT, v, y, units=("mm", "m", "counts"),
                       directions=(1, -1, 1))
    e = load_experiment(path)
    assert e.n_outputs == 3 and e.n_samples == N and e.dt == pytest.approx(DT)
    np.testing.assert_allclose(e.y_m, y, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(e.v_volt, v)
    _recovered(_lsq(str(path)))


def test_binary_unv_is_read_like_ascii(tmp_path):
    v, y = _truth()
    path = write_uff58(tmp_path / "rec.unv", DT, v, y, units=("mm",) * 3, binary=1)
    np.testing.assert_allclose(load_experiment(path).y_m, y, rtol=1e-6, atol=1e-12)


def test_tdms_lsq_recovers_the_truth(tmp_path):
    v, y = _truth(seed=39)
    path = write_tdms(tmp_path / "rec.tdms", DT, v, y, units=("mm", "mm", "m"))
    e = load_experiment(path)
    np.testing.assert_allclose(e.y_m, y, rtol=1e-12, atol=1e-15)
    assert e.dt == pytest.approx(DT)
    _recovered(_lsq(str(path)))


def test_uff_channels_by_name_and_node(tmp_path):
    v, y = _truth()
    path = write_uff58(tmp_path / "rec.uff", DT, v, y, units=("mm",) * 3,
                       names=("left", "middle", "right"))
    # the time axis is the records' abscissa: t names no channel
    opts = ReadOptions(columns={"t": "time", "v": "drive", "x1": "3:1", "x2": "left"})
    e = load_experiment(path, options=opts)
    np.testing.assert_allclose(e.y_m, y[:, [2, 0]], rtol=1e-9, atol=1e-12)
    with pytest.raises(DataError, match=r"channel 'centre' \(for x1\) not found; name the "
                       r"channels with --columns .*channels: left \(1:1\) \[mm\], middle \(2:1\) "
                       r"\[mm\], right \(3:1\) \[mm\], drive \(100:1\) \[V\]$"):
        load_experiment(path, options=ReadOptions(
            columns={"t": "time", "v": "drive", "x1": "centre"}))


def test_tdms_time_channel_and_column_map(tmp_path):
    v, y = _truth()
    path = write_tdms(tmp_path / "rec.tdms", DT, v, y, units=("m",) * 3, time_channel=True,
                      names=("enc_a", "enc_b", "enc_c"))
    e = load_experiment(path, options=ReadOptions(
        columns={"t": "Time", "v": "rig/drive", "x1": "enc_c", "x2": "enc_a"}))
    np.testing.assert_allclose(e.y_m, y[:, [2, 0]], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(e.t_s, np.arange(N) * DT, rtol=1e-12, atol=1e-12)


def test_frequency_responses_are_not_time_records(tmp_path):
    v, y = _truth()
    path = write_uff58(tmp_path / "frf.uff", DT, v[:50], y[:50], units=("mm",) * 3,
                       func_type=4)
    with pytest.raises(DataError, match=r"frf.uff: dataset 58 records of function type 4 "
                       r"\(frequency response function\), none a time response"):
        load_experiment(path)


def test_a_missing_library_names_the_extra(tmp_path, monkeypatch):
    v, y = _truth()
    uff = write_uff58(tmp_path / "rec.uff", DT, v[:50], y[:50], units=("mm",) * 3)
    tdms = write_tdms(tmp_path / "rec.tdms", DT, v[:50], y[:50], units=("mm",) * 3)
    monkeypatch.setitem(sys.modules, "pyuff", None)
    monkeypatch.setitem(sys.modules, "nptdms", None)
    with pytest.raises(DataError, match=r"rec.uff: reading .uff files needs the optional "
                       r"library pyuff: pip install 'bayesmodal\[uff\]'$"):
        load_experiment(uff)
    with pytest.raises(DataError, match=r"pip install 'bayesmodal\[tdms\]'$"):
        load_experiment(tdms)


def test_not_a_tdms_file(tmp_path):
    path = tmp_path / "rec.tdms"
    path.write_text("t,v,x1\n0,0,0\n")
    with pytest.raises(DataError, match=r"rec.tdms: not a TDMS file \(no TDSm lead-in\)"):
        load_experiment(path)


def test_an_output_without_a_unit_needs_a_scale(tmp_path):
    v, y = _truth()
    path = write_tdms(tmp_path / "rec.tdms", DT, v[:100], y[:100], units=("mm",) * 3,
                      label_outputs=False)
    opts = ReadOptions(columns={"t": "time", "v": "drive", "x1": "cart1"})
    with pytest.raises(DataError, match=r"output channel 'cart1' has the unit 'none', not a "
                       r"length or counts; give metres per unit with --m-per-count"):
        load_experiment(path, options=opts)
    e = load_experiment(path, options=ReadOptions(columns=opts.columns, m_per_count=1e-3))
    np.testing.assert_allclose(e.y_m[:, 0], y[:100, 0], rtol=1e-12, atol=1e-15)


def test_a_scale_that_contradicts_the_unit_is_refused(tmp_path):
    v, y = _truth()
    path = write_tdms(tmp_path / "rec.tdms", DT, v[:100], y[:100], units=("mm",) * 3)
    with pytest.raises(DataError, match=r"channel 'cart1' is in mm, but --m-per-count says "
                       r"1 m per unit"):
        load_experiment(path, options=ReadOptions(m_per_count=1))
