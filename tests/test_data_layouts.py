"""Lab files as they come: column maps, scale factors, header rows, rounded or jittered time.

The records are generated here (never taken from the shared data): a two-cart rig
simulated with the package's linear model, written the way a microcontroller logger
writes it (MATLAB variables ``time, enc1, enc2, target_v`` and a struct of run
parameters; positions in encoder counts; the input in converter units of 4096 per 5 V;
timestamps rounded to whole milliseconds), and as text files with header rows.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.io

from bayesmodal import ConfigError, DataError
from bayesmodal.data import ECP_M_PER_COUNT, ReadOptions, load_experiment
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.reading import parse_columns, parse_scale
from bayesmodal.timebase import regularise_time

DT = 0.00442  # s, an ECP servo period; not a whole number of milliseconds
N = 1500
V_PER_UNIT = 5 / 4096
TWO_CARTS = LinearModel(Rig((800.0, 450.0)), "proportional")
THETA_2 = np.array([6.0, 1.6, 1.4, 1.0, 2e-4])  # g_v, m1, m2, ca, cb
MAP = {"t": "time", "v": "target_v", "x1": "enc1", "x2": "enc2"}


def two_cart_record(n: int = N, dt: float = DT, volts: float = 1.5):
    """True time (s), input (V) and positions (m) of one step on the two-cart rig."""
    t = np.arange(n) * dt
    v = np.where(t >= 0.1, volts, 0.0)
    y = simulate_linear(TWO_CARTS, THETA_2, v, dt)
    return t, v, y


def logger_mat(path, *, round_ms: bool = True, counts: bool = True, struct: bool = True):
    """Write the record as the microcontroller logger does; return the true record."""
    t, v, y = two_cart_record()
    units = np.round(v / V_PER_UNIT)
    enc = np.round(y / ECP_M_PER_COUNT) if counts else y
    variables = {"time": np.round(t, 3) if round_ms else t, "enc1": enc[:, 0],
                 "enc2": enc[:, 1], "target_v": units}
    if struct:
        variables["run"] = {"gain": 2.5, "operator": "lab 3", "controller": {"kp": 0.1}}
    scipy.io.savemat(path, variables)
    return t, v, y


def _load(path, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        e = load_experiment(path, **kw)
    return e, [str(w.message) for w in caught]


# ------------------------------------------------------------------ the record
def test_logger_mat_is_read_with_a_column_map_and_scales(tmp_path):
    p = tmp_path / "rec.mat"
    t, v, y = logger_mat(p)
    e, warned = _load(p, options=ReadOptions(columns=MAP, input_scale=V_PER_UNIT))
    assert e.n_outputs == 2 and e.n_samples == N
    # the only loss is the rounding to whole counts and converter units
    np.testing.assert_allclose(e.y_m, y, rtol=0, atol=0.5 * ECP_M_PER_COUNT * (1 + 1e-9))
    np.testing.assert_allclose(e.v_volt, v, rtol=0, atol=0.5 * V_PER_UNIT * (1 + 1e-9))
    # time: rounded to 1 ms, put back on the grid; the fitted grid's error is of order
    # q / sqrt(N) in offset and q / N^1.5 in step (q = 1 ms)
    assert len(warned) == 1 and "rounded to 0.001 s" in warned[0], warned
    assert "at most" in warned[0] and "% of a step" in warned[0]
    q = 1e-3
    assert abs(e.dt - DT) < 4 * q * np.sqrt(12 / N**3)
    np.testing.assert_allclose(e.t_s, t, rtol=0, atol=4 * q / np.sqrt(N))


def test_struct_fields_are_columns_and_text_fields_are_named(tmp_path):
    p = tmp_path / "nested.mat"
    t, v, y = two_cart_record()
    scipy.io.savemat(p, {"log": {"time": t, "enc1": y[:, 0] / ECP_M_PER_COUNT,
                                 "enc2": y[:, 1] / ECP_M_PER_COUNT, "u": v, "note": "x"}})
    cols = {"t": "log.time", "v": "log.u", "x1": "log.enc1", "x2": "log.enc2"}
    e, warned = _load(p, options=ReadOptions(columns=cols))
    assert warned == []
    np.testing.assert_allclose(e.y_m, y, rtol=1e-12, atol=1e-15)
    with pytest.raises(DataError, match=r"variable 'log.note' is text.*available: log.time"):
        load_experiment(p, options=ReadOptions(columns={**cols, "v": "log.note"}))
    with pytest.raises(DataError, match=r"column 'volts' \(for v\) not found.*log.enc2"):
        load_experiment(p, options=ReadOptions(columns={**cols, "v": "volts"}))


def test_without_a_map_the_error_names_the_fix_and_the_variables(tmp_path):
    p = tmp_path / "rec.mat"
    logger_mat(p)
    with pytest.raises(DataError, match=r"missing column\(s\) \['t', 'v', 'x1'\].*--columns "
                       r"t=NAME.*available: time, enc1, enc2, target_v, run.gain"):
        load_experiment(p)


def test_mat_v73_struct_fields(tmp_path):
    h5py = pytest.importorskip("h5py")
    t, v, y = two_cart_record(n=300)
    p = tmp_path / "v73.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        g = f.create_group("log")
        g["time"], g["u"] = t[None], v[None]
        g["enc1"], g["enc2"] = (y[:, 0] / ECP_M_PER_COUNT)[None], (y[:, 1] / ECP_M_PER_COUNT)[None]
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: test".ljust(116, b" "))
    cols = {"t": "log.time", "v": "log.u", "x1": "log.enc1", "x2": "log.enc2"}
    e = load_experiment(p, options=ReadOptions(columns=cols))
    np.testing.assert_allclose(e.y_m, y, rtol=1e-12, atol=1e-15)


# ------------------------------------------------------------------ text files
def _text(path, header_lines, table, fmt="%.6f", sep="\t"):
    body = "\n".join(sep.join(fmt % x for x in row) for row in table)
    path.write_text("\n".join(header_lines) + ("\n" if header_lines else "") + body + "\n")


def _counts_table(with_index=True):
    t, v, y = two_cart_record()
    cols = [t, y[:, 0] / ECP_M_PER_COUNT, y[:, 1] / ECP_M_PER_COUNT, v]
    if with_index:
        cols = [np.arange(N, dtype=float)] + cols
    return t, v, y, np.column_stack(cols)


def test_text_with_header_rows_by_name(tmp_path):
    t, v, y, table = _counts_table()
    p = tmp_path / "ecp.txt"
    _text(p, ["; exported by the lab software", "; run 7",
              "Sample\tTime\tEncoder 1 Pos\tEncoder 2 Pos\tCommanded Voltage"], table)
    cols = {"t": "Time", "x1": "Encoder 1 Pos", "x2": "Encoder 2 Pos", "v": "Commanded Voltage"}
    e, warned = _load(p, options=ReadOptions(columns=cols))
    assert warned == []
    np.testing.assert_allclose(e.y_m, y, rtol=0, atol=1e-6 * ECP_M_PER_COUNT)
    np.testing.assert_allclose(e.t_s, t, rtol=0, atol=1e-6)
    # without a map: refused, naming the header and the fix
    with pytest.raises(DataError, match=r"does not name the columns t, x1..xn, v; map .*"
                       r"--columns.*Encoder 1 Pos \(3\)"):
        load_experiment(p)


def test_text_whose_header_words_do_not_split_into_columns_by_number(tmp_path):
    t, v, y, table = _counts_table()
    p = tmp_path / "ecp.txt"
    _text(p, ["Sample Time Encoder 1 Pos Encoder 2 Pos Commanded Voltage"], table, sep=" ")
    with pytest.raises(DataError, match="columns 1..5 by number"):
        load_experiment(p, options=ReadOptions(columns={"t": "Time", "x1": "3", "x2": "4",
                                                        "v": "5"}))
    e = load_experiment(p, options=ReadOptions(columns={"t": "2", "x1": "3", "x2": "4",
                                                        "v": "5"}))
    np.testing.assert_allclose(e.y_m, y, rtol=0, atol=1e-6 * ECP_M_PER_COUNT)
    with pytest.raises(DataError, match="column number 6 is out of range"):
        load_experiment(p, options=ReadOptions(columns={"t": "2", "x1": "6", "v": "5"}))


def test_text_header_with_the_standard_names_needs_no_map(tmp_path):
    t, v, y, table = _counts_table(with_index=False)
    p = tmp_path / "std.txt"
    _text(p, ["t x1 x2 v"], table, sep=" ")
    e = load_experiment(p)
    np.testing.assert_allclose(e.y_m, y, rtol=0, atol=1e-6 * ECP_M_PER_COUNT)


def test_csv_with_several_header_rows_and_a_map(tmp_path):
    t, v, y = two_cart_record(n=400)
    p = tmp_path / "lab.csv"
    table = np.column_stack([v, t, y])
    rows = ["# rig B, run 4", "u (V), time (s), cart 1 (m), cart 2 (m)"]
    rows += [",".join(repr(float(x)) for x in row) for row in table]
    p.write_text("\n".join(rows) + "\n")
    cols = {"t": "time (s)", "v": "u (V)", "x1": "cart 1 (m)", "x2": "cart 2 (m)"}
    e = load_experiment(p, options=ReadOptions(columns=cols))
    np.testing.assert_array_equal(e.y_m, y)
    np.testing.assert_array_equal(e.v_volt, v)


def test_sample_index_as_time_is_refused_with_the_fix(tmp_path):
    t, v, y, table = _counts_table()
    p = tmp_path / "indexed.txt"
    _text(p, [], table)  # header-less: Sample, Time, x1, x2, v
    with pytest.raises(DataError, match=r"the time column 't' counts samples \(0, 1, 2, ...\)"
                       r".*--columns t=NAME"):
        load_experiment(p)
    e = load_experiment(p, options=ReadOptions(columns={"t": "2", "x1": "3", "x2": "4",
                                                        "v": "5"}))
    np.testing.assert_allclose(e.t_s, t, rtol=0, atol=1e-6)


def test_time_in_milliseconds(tmp_path):
    t, v, y, table = _counts_table(with_index=False)
    table[:, 0] *= 1000.0
    p = tmp_path / "ms.txt"
    _text(p, [], table)
    with pytest.raises(DataError, match=r"sample interval 4.42 s is implausible.*"
                       r"--time-scale 1/1000"):
        load_experiment(p)
    e = load_experiment(p, options=ReadOptions(time_scale=parse_scale("1/1000")))
    np.testing.assert_allclose(e.t_s, t, rtol=0, atol=1e-9)


def test_converter_units_are_refused_without_a_scale(tmp_path):
    p = tmp_path / "rec.mat"
    logger_mat(p, round_ms=False)
    with pytest.raises(DataError, match=r"input up to 1229 V is far beyond.*"
                       r"--input-scale 5/4096"):
        load_experiment(p, options=ReadOptions(columns=MAP))


@pytest.mark.parametrize("factor,fix", [(1e3, "in mm\\? give --m-per-count 0.001"),
                                        (1 / ECP_M_PER_COUNT, "in encoder counts\\? give "
                                                              "--m-per-count")])
def test_outputs_in_mm_or_counts_in_a_csv(tmp_path, factor, fix):
    t, v, y = two_cart_record(n=400)
    p = tmp_path / "wrong_units.csv"
    table = np.column_stack([t, v, y * factor])
    rows = ["t,v,x1,x2"] + [",".join(repr(float(x)) for x in row) for row in table]
    p.write_text("\n".join(rows) + "\n")
    with pytest.raises(DataError, match=f"implausible for the rig.*{fix}"):
        load_experiment(p)
    e = load_experiment(p, options=ReadOptions(m_per_count=1 / factor))
    np.testing.assert_allclose(e.y_m, y, rtol=1e-12, atol=1e-15)


def test_metres_in_a_counts_file_are_refused(tmp_path):
    p = tmp_path / "metres.mat"
    logger_mat(p, counts=False, round_ms=False)
    with pytest.raises(DataError, match="below one encoder count.*--m-per-count 1"):
        load_experiment(p, options=ReadOptions(columns=MAP, input_scale=V_PER_UNIT))


def test_number_of_outputs_is_checked(tmp_path):
    t, v, y = two_cart_record(n=300)
    p = tmp_path / "two.mat"
    scipy.io.savemat(p, {"t": t, "v": v, "x1": y[:, 0] / ECP_M_PER_COUNT,
                         "x2": y[:, 1] / ECP_M_PER_COUNT})
    assert load_experiment(p, options=ReadOptions(n_outputs=2)).n_outputs == 2
    with pytest.raises(DataError, match="2 outputs, but 3 were expected"):
        load_experiment(p, options=ReadOptions(n_outputs=3))


# ------------------------------------------------------------------ the time base
def test_rounded_timestamps_are_within_half_a_quantum_of_the_fitted_grid():
    rng = np.random.default_rng(3)
    t0, n, q = 0.0123, 3000, 1e-3
    true = t0 + np.arange(n) * DT
    r = regularise_time(np.round(true / q) * q)
    assert r.kind == "rounded" and r.quantum_s == pytest.approx(q)
    assert r.max_shift_s <= 0.5 * q * (1 + 4 / np.sqrt(n))
    np.testing.assert_allclose(r.t_s, true, rtol=0, atol=4 * q / np.sqrt(n))
    # jitter: independent, uniform within +-0.3 dt; the fitted step's standard error is
    # sigma sqrt(12 / n^3) with sigma = 0.3 dt / sqrt(3)
    jit = true + rng.uniform(-0.3, 0.3, n) * DT
    r = regularise_time(jit)
    assert r.kind == "jitter"
    assert abs(r.dt - DT) < 4 * (0.3 * DT / np.sqrt(3)) * np.sqrt(12 / n**3)
    assert r.max_shift_s < 0.3 * DT * 1.05


@pytest.mark.parametrize("case", ["gap", "drift", "rate_change"])
def test_irregular_sampling_is_not_regularised(case, tmp_path):
    rng = np.random.default_rng(4)
    n = 2000
    k = np.arange(n)
    if case == "gap":  # one sample missing
        t = np.delete(np.arange(n + 1) * DT, 700)
    elif case == "drift":  # each step jitters: the clock drifts (a random walk)
        t = np.cumsum(DT * (1 + 0.05 * rng.standard_normal(n)))
    else:
        t = np.where(k < n // 2, k * DT, (n // 2) * DT + (k - n // 2) * 1.02 * DT)
    assert regularise_time(t).kind == "irregular"
    p = tmp_path / f"{case}.csv"
    y = np.zeros((n, 1))
    y[n // 2:] = 1e-3
    rows = ["t,v,x1"] + [f"{float(a)!r},1.0,{float(b)!r}" for a, b in zip(t, y[:, 0], strict=True)]
    p.write_text("\n".join(rows) + "\n")
    with pytest.raises(DataError, match="time steps are not equally spaced"):
        load_experiment(p)


# ------------------------------------------------------------------ the options
def test_parse_scale_and_columns():
    assert parse_scale("5/4096") == 5 / 4096
    assert parse_scale(" 1e-3 ") == 1e-3
    for bad in ("five", "1/0", "-2", "0", "nan", "inf"):
        with pytest.raises(ConfigError):
            parse_scale(bad, "--input-scale")
    assert parse_columns("t=time,v=target_v,x1=enc1,x2=enc2") == MAP
    assert parse_columns("t = Time , x1 = Encoder 1 Pos, v=5") == {
        "t": "Time", "x1": "Encoder 1 Pos", "v": "5"}
    for bad, msg in (("t=time,v=u", r"role\(s\) \['x1'\] missing"),
                     ("t=time,v=u,x2=e", "without gaps"),
                     ("t=time,v=u,x1=e,y=f", "unknown role 'y'"),
                     ("t=time,v=u,x1=e,t=s", "given twice"),
                     ("t=time,v,x1=e", "is not ROLE=COLUMN"),
                     ("t=,v=u,x1=e", "names no column")):
        with pytest.raises(ConfigError, match=msg):
            parse_columns(bad)
    with pytest.raises(ConfigError, match="names 2 outputs but n_outputs is 3"):
        ReadOptions(columns=MAP, n_outputs=3)
    assert ReadOptions(columns=MAP) == ReadOptions(columns=MAP)  # hashable, comparable
    hash(ReadOptions(columns=MAP))
