"""Loaders: formats, conversions, and a clear error for every kind of bad input."""

import numpy as np
import pytest
import scipy.io
from conftest import measured

from bayesmodal import DataError
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, load_experiment, save_csv


def _write_ecp_txt(path, t, xs, v):
    np.savetxt(path, np.column_stack([t, *xs, v]), delimiter="\t", fmt="%.10g")


def test_measured_mat_and_txt_agree():
    mat = measured("data_impulses.mat")
    txt = measured("data_impulses.txt")
    assert mat.n_samples == 7401 and mat.n_outputs == 3
    assert mat.dt == pytest.approx(0.005)
    # the .txt file is rounded to a few decimals of a count
    np.testing.assert_allclose(mat.y_m, txt.y_m, atol=0.1 * ECP_M_PER_COUNT)
    assert mat.sha256.startswith("9aa853de")
    assert mat.v_volt.max() == pytest.approx(3.0006)


def test_counts_conversion_and_custom_factor(tmp_path):
    t = np.arange(10) * 0.01
    p = tmp_path / "e.txt"
    _write_ecp_txt(p, t, [np.full(10, 16000.0), np.zeros(10)], np.ones(10))
    e = load_experiment(p)
    assert e.n_outputs == 2
    np.testing.assert_allclose(e.y_m[:, 0], 0.0706)
    e2 = load_experiment(p, m_per_count=1e-6)
    np.testing.assert_allclose(e2.y_m[:, 0], 0.016)


def test_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    e = Experiment(np.arange(50) * 0.002, rng.normal(size=50), rng.normal(size=(50, 4)) * 1e-3,
                   name="x")
    p = tmp_path / "x.csv"
    save_csv(e, p)
    back = load_experiment(p)
    np.testing.assert_array_equal(back.t_s, e.t_s)
    np.testing.assert_array_equal(back.y_m, e.y_m)
    np.testing.assert_array_equal(back.v_volt, e.v_volt)


def test_mat_v5_any_number_of_carts(tmp_path):
    t = np.arange(20)[:, None] * 0.01
    p = tmp_path / "m.mat"
    scipy.io.savemat(p, {"t": t, "x1": t * 0, "x2": t * 0 + 1, "v": t * 0 + 0.5})
    e = load_experiment(p)
    assert e.n_outputs == 2


BAD_TEXT = {
    "nan": ("t,v,x1\n0,0,0\n0.1,nan,0\n0.2,0,0\n", "non-finite"),
    "inf": ("t,v,x1\n0,0,0\n0.1,0,inf\n0.2,0,0\n", "non-finite"),
    "nonuniform": ("t,v,x1\n0,0,0\n0.1,0,0\n0.25,0,0\n0.3,0,0\n", "not equally spaced"),
    "decreasing": ("t,v,x1\n0,0,0\n0.2,0,0\n0.1,0,0\n", "not strictly increasing"),
    "duplicate_time": ("t,v,x1\n0,0,0\n0.1,0,0\n0.1,0,0\n0.2,0,0\n", "not strictly increasing"),
    "missing_column": ("t,x1\n0,0\n0.1,0\n0.2,0\n", r"missing column\(s\) \['v'\]"),
    "extra_column": ("t,v,x1,foo\n0,0,0,1\n0.1,0,0,1\n0.2,0,0,1\n", "unknown column"),
    "ragged": ("t,v,x1\n0,0,0\n0.1,0\n0.2,0,0\n", "line 3 has 2 columns"),
    "text_value": ("t,v,x1\n0,0,0\n0.1,abc,0\n0.2,0,0\n", "non-numeric"),
    "single_sample": ("t,v,x1\n0,0,0\n", "only 1 samples"),
    "header_only": ("t,v,x1\n", "no data rows"),
    "gap_in_outputs": ("t,v,x1,x3\n0,0,0,0\n0.1,0,0,0\n0.2,0,0,0\n", "without gaps"),
}


@pytest.mark.parametrize("case", sorted(BAD_TEXT))
def test_bad_csv_inputs_raise_clear_errors(tmp_path, case):
    text, pattern = BAD_TEXT[case]
    p = tmp_path / f"{case}.csv"
    p.write_text(text)
    with pytest.raises(DataError, match=pattern) as info:
        load_experiment(p)
    assert str(p) in str(info.value)


def test_other_bad_files(tmp_path):
    empty = tmp_path / "empty.txt"
    empty.write_text("")
    with pytest.raises(DataError, match="empty"):
        load_experiment(empty)
    with pytest.raises(DataError, match="no such file"):
        load_experiment(tmp_path / "nope.mat")
    odd = tmp_path / "data.xlsx"
    odd.write_bytes(b"PK\x03\x04")
    with pytest.raises(DataError, match="unknown format 'xlsx'"):
        load_experiment(odd)
    garbage = tmp_path / "g.mat"
    garbage.write_bytes(np.random.default_rng(0).bytes(4000))
    with pytest.raises(DataError, match="not a readable MATLAB"):
        load_experiment(garbage)
    trunc = tmp_path / "t.mat"
    trunc.write_bytes(b"MATLAB 5.0 MAT-file")
    with pytest.raises(DataError, match="truncated"):
        load_experiment(trunc)
    binary = tmp_path / "b.txt"
    binary.write_bytes(b"\xff\xfe\x00\x81" * 100)
    with pytest.raises(DataError, match="not a text file"):
        load_experiment(binary)
    big = tmp_path / "big.csv"
    big.write_text("t,v,x1\n" + "0,0,0\n" * 100)
    with pytest.raises(DataError, match="size limit of 100 bytes.*BAYESMODAL_MAX_BYTES"):
        load_experiment(big, max_bytes=100)


def test_mat_with_unexpected_variables_and_unequal_lengths(tmp_path):
    p = tmp_path / "u.mat"
    scipy.io.savemat(p, {"time": np.arange(5.0), "pos": np.zeros(5)})
    with pytest.raises(DataError, match="missing column"):
        load_experiment(p)
    q = tmp_path / "q.mat"
    scipy.io.savemat(q, {"t": np.arange(5.0) * 0.1, "x1": np.zeros(4), "v": np.zeros(5)})
    with pytest.raises(DataError, match="unequal column lengths"):
        load_experiment(q)


def test_mat_v73_hdf5_is_read(tmp_path):
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "v73.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        t = np.arange(30) * 0.01
        f["t"] = t[None]
        f["x1"] = np.ones((1, 30)) * 100
        f["v"] = np.zeros((1, 30))
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: test".ljust(116, b" "))
    e = load_experiment(p)
    np.testing.assert_allclose(e.y_m[:, 0], 100 * ECP_M_PER_COUNT)


def test_counts_in_csv_are_refused_with_the_fix(tmp_path):
    p = tmp_path / "counts.csv"
    p.write_text("t,v,x1\n0,0,0\n0.01,1,2000\n0.02,1,4000\n")
    with pytest.raises(DataError, match="encoder counts.*--m-per-count"):
        load_experiment(p)


def test_experiment_validation_direct():
    with pytest.raises(DataError, match="unequal lengths"):
        Experiment(np.arange(5.0), np.zeros(4), np.zeros((5, 1)))
    e = Experiment(np.arange(5.0), np.zeros(5), np.zeros(5))
    assert e.y_m.shape == (5, 1)
    with pytest.raises(ValueError):
        e.y_m[0, 0] = 1.0  # read-only


# ---------------------------------------------------------------- data root
@pytest.fixture
def data_tree(tmp_path):
    """``tmp/data/ecp210-3dof/rec.csv`` and a config folder elsewhere."""
    ds = tmp_path / "data" / "ecp210-3dof"
    ds.mkdir(parents=True)
    (ds / "rec.csv").write_text("t,v,x1,x2,x3\n0,0,0,0,0\n0.01,1,0,0,0\n0.02,0,0,0,0\n")
    (tmp_path / "cfg").mkdir()
    return tmp_path


@pytest.mark.parametrize("env", ["data", "data/ecp210-3dof"])
def test_data_root_may_be_the_parent_or_the_data_set_folder(data_tree, monkeypatch, env):
    from bayesmodal.data import find_data
    from bayesmodal.runs.config import parse_config

    monkeypatch.setenv("BAYESMODAL_DATA", str(data_tree / env))
    expected = data_tree / "data" / "ecp210-3dof" / "rec.csv"
    assert find_data("ecp210-3dof/rec.csv") == expected
    cfg = parse_config({"data": {"files": ["ecp210-3dof/rec.csv"]}}, base=data_tree / "cfg")
    assert cfg.data.files == (str(expected.resolve()),)
    from bayesmodal.reproduce import default_data_dir  # `bayesmodal report`'s folder

    assert default_data_dir() == data_tree / "data" / "ecp210-3dof"


def test_data_root_elsewhere_finds_nothing(data_tree, monkeypatch):
    # negative control: a root that holds neither the data set nor its files
    from bayesmodal import ConfigError
    from bayesmodal.data import find_data
    from bayesmodal.runs.config import parse_config

    monkeypatch.setenv("BAYESMODAL_DATA", str(data_tree / "cfg"))
    assert find_data("ecp210-3dof/rec.csv") is None
    with pytest.raises(ConfigError, match="file not found"):
        parse_config({"data": {"files": ["ecp210-3dof/rec.csv"]}}, base=data_tree / "cfg")
