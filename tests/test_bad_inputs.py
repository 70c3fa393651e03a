"""Every public entry point against every kind of bad input file.

The cases below are data: each bad input (:data:`INPUTS`) is tried on each entry point it
applies to (:data:`ENTRIES`: the loader, ``bayesmodal lsq``, ``sample``, ``ema``,
``diagnose``, ``run`` and ``batch``).  An error must be one line naming the file and the
problem, with a non-zero exit code, no traceback, nothing on stdout and no output folder
left behind; a warning (implausible amplitude) must be one line and the result is still
given.  ``docs/bad_inputs.md`` is generated from the same cases
(``python docs/make_bad_inputs_table.py``) and :func:`test_docs_table_is_in_sync` checks
that the committed table is what the cases produce: each row of the table is a test here.
"""

from __future__ import annotations

import io
import json
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from conftest import run_cli as _cli
from ecp_export_writer import ECP_DT, write_export

from bayesmodal import DataError
from bayesmodal.data import MAX_FILE_BYTES, Experiment, load_experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

TABLE = Path(__file__).resolve().parents[1] / "docs" / "bad_inputs.md"
THETA = [6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0]
N = 400
DT = 0.005


# ---------------------------------------------------------------- the inputs
def _record(n: int = N):
    """A plausible 3-cart record: a 3 V pulse and the simulated response, m."""
    t = np.arange(n) * DT
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, DT)
    return t, v, y


def _csv_text(t, v, y, header="t,v,x1,x2,x3") -> str:
    rows = [header] + [",".join(f"{x:.10g}" for x in (a, b, *c)) for a, b, c in zip(t, v, y,
                                                                                    strict=True)]
    return "\n".join(rows) + "\n"


def _write(name: str, text: str | bytes):
    def make(folder: Path) -> str:
        p = folder / name
        if isinstance(text, bytes):
            p.write_bytes(text)
        else:
            p.write_text(text)
        return name

    return make


def _csv(name: str, edit: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple] | None = None,
         header: str = "t,v,x1,x2,x3", lines: Callable[[list[str]], list[str]] | None = None):
    def make(folder: Path) -> str:
        t, v, y = _record()
        if edit is not None:
            t, v, y = edit(t.copy(), v.copy(), y.copy())
        text = _csv_text(t, v, y, header)
        if lines is not None:
            text = "\n".join(lines(text.splitlines())) + "\n"
        (folder / name).write_text(text)
        return name

    return make


def _field(line: str, i: int, value: str) -> str:
    parts = line.split(",")
    parts[i] = value
    return ",".join(parts)


def _set(arr, idx, value):
    arr[idx] = value
    return arr


def _mat_bytes(**variables) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, variables)
    return buf.getvalue()


def _ecp_mat(name: str, cut: float | None = None, **changes):
    def make(folder: Path) -> str:
        t, v, y = _record()
        counts = y / (0.0706 / 16000)
        variables = {"t": t[:, None], "x1": counts[:, :1], "x2": counts[:, 1:2],
                     "x3": counts[:, 2:], "v": v[:, None]}
        variables.update(changes)
        variables = {k: val for k, val in variables.items() if val is not None}
        data = _mat_bytes(**variables)
        (folder / name).write_bytes(data if cut is None else data[: int(len(data) * cut)])
        return name

    return make


def _mat73(name: str, *, corrupt: bool = False, extra_group: bool = False):
    def make(folder: Path) -> str:
        import h5py

        p = folder / name
        t, v, y = _record()
        counts = y / (0.0706 / 16000)
        with h5py.File(p, "w", userblock_size=512) as f:
            f["t"] = t[None]
            for i in range(3):
                f[f"x{i + 1}"] = counts[:, i][None]
            f["v"] = v[None]
            if extra_group:
                f.create_group("settings")["gain"] = np.ones((1, 1))
        with open(p, "r+b") as fh:
            fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(116, b" "))
        if corrupt:
            data = p.read_bytes()
            p.write_bytes(data[:600] + np.random.default_rng(1).bytes(2000))
        return name

    return make


def _logger_mat(name: str, *, counts: bool = True, **changes):
    """A microcontroller logger's record: variables time, enc1..enc3 (counts), target_v
    (converter units of 4096 per 5 V) and a struct of run parameters."""

    def make(folder: Path) -> str:
        t, v, y = _record()
        enc = np.round(y / (0.0706 / 16000)) if counts else y
        variables = {"time": t, "enc1": enc[:, 0], "enc2": enc[:, 1], "enc3": enc[:, 2],
                     "target_v": np.round(v * 4096 / 5),
                     "run": {"gain": 2.5, "operator": "lab 3"}}
        variables.update(changes)
        (folder / name).write_bytes(_mat_bytes(**variables))
        return name

    return make


def _ecp_text(name: str, *, header: tuple[str, ...] = (), index: bool = False,
              time_scale: float = 1.0, time=None):
    """An ECP-style text record in counts, optionally with header rows and a leading
    sample-index column."""

    def make(folder: Path) -> str:
        t, v, y = _record()
        t = t * time_scale if time is None else time(t)
        cols = [t, *(y / (0.0706 / 16000)).T, v]
        if index:
            cols = [np.arange(t.size, dtype=float)] + cols
        body = "\n".join("\t".join(f"{x:.10g}" for x in row) for row in np.column_stack(cols))
        (folder / name).write_text("\n".join([*header, body]) + "\n")
        return name

    return make


_LOGGER_MAP = ("--columns", "t=time,v=target_v,x1=enc1,x2=enc2,x3=enc3")


def _reversed(name: str):
    """A 5 s record of a 0.5 V square wave whose carts were driven by minus the input."""

    def make(folder: Path) -> str:
        t = np.arange(1000) * DT
        v = 0.5 * ((t % 4.0) < 2.0)
        y = simulate_linear(LinearModel(Rig(), "free"), THETA, -v, DT)
        (folder / name).write_text(_csv_text(t, v, y))
        return name

    return make


def _export(name: str, *, cut: bool = False):
    """An ECP Executive export (times printed to 1 ms at 8.854 ms steps, whole counts);
    ``cut``: its eleventh line lost its last value."""

    def make(folder: Path) -> str:
        t = np.arange(N) * ECP_DT
        v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
        y = simulate_linear(LinearModel(Rig(), "free"), THETA, v, ECP_DT)
        p = write_export(folder / name, v, y)
        if cut:
            lines = p.read_text().splitlines()
            lines[10] = lines[10].rsplit(" ", 1)[0]
            p.write_text("\n".join(lines) + "\n")
        return name

    return make


def _instrument(name: str, **kw):
    """A UFF dataset 58 or TDMS file (by the suffix of ``name``) of a pulse response in mm,
    written by pyuff's or npTDMS's own writer; ``kw`` go to the writer."""

    def make(folder: Path) -> str:
        from instrument_writers import write_tdms, write_uff58

        t, v, y = _record()
        write = write_tdms if name.endswith(".tdms") else write_uff58
        write(folder / name, DT, v, y, units=("mm",) * 3, **kw)
        return name

    return make


def _closed_loop(name: str):
    """A PID loop on cart 1 exported by the ECP Executive (``tests/closed_loop_writer.py``),
    at a servo period of 8 ms (printed exactly: no warning about the times)."""

    def make(folder: Path) -> str:
        from closed_loop_writer import write_closed_loop

        write_closed_loop(folder / name, N, dt=0.008)
        return name

    return make


def _sparse(name: str, size: int):
    def make(folder: Path) -> str:
        p = folder / name
        with open(p, "wb") as fh:
            fh.write(b"t,v,x1,x2,x3\n")
            fh.truncate(size)  # a sparse file: no disk space, but stat() says `size`
        return name

    return make


def _folder(name: str):
    def make(folder: Path) -> str:
        (folder / name).mkdir()
        return name

    return make


def _nothing(name: str):
    def make(folder: Path) -> str:
        return name

    return make


CLI = ("lsq", "sample", "ema", "diagnose", "run", "batch")
ALL = ("load_experiment", *CLI)


@dataclass(frozen=True)
class BadInput:
    """One bad input file.

    Attributes
    ----------
    key : str
        Short identifier (test id).
    what : str
        The input, for the table.
    make : callable
        ``make(folder) -> file name``: writes the file into ``folder``.
    pattern : str
        Regular expression the message must contain.
    entries : tuple of str
        Entry points it is tried on.
    warn : bool
        A warning (the result is still given), not an error.
    patterns : dict
        Entry point -> pattern, where it differs from ``pattern``.
    args : tuple of str
        Reader options given with the input (``--columns ...``); the loader gets the
        ``ReadOptions`` they parse to.
    """

    key: str
    what: str
    make: Callable[[Path], str]
    pattern: str
    entries: tuple[str, ...] = ALL
    warn: bool = False
    patterns: dict = field(default_factory=dict)
    args: tuple[str, ...] = ()


_GARBAGE = np.random.default_rng(0).bytes(4096)
_LIMIT = MAX_FILE_BYTES

INPUTS = [
    BadInput("missing", "a path that does not exist", _nothing("nope.csv"), "no such file",
             patterns={"run": "file not found", "batch": "file not found"}),
    BadInput("directory", "a folder named like a data file", _folder("folder.csv"),
             "not a regular file",
             patterns={"run": "file not found", "batch": "file not found"}),
    BadInput("unknown_format", "a spreadsheet (`.xlsx`)", _write("sheet.xlsx", b"PK\x03\x04"),
             "unknown format 'xlsx'"),
    BadInput("empty_csv", "empty CSV (0 bytes)", _write("empty.csv", ""), "file is empty"),
    BadInput("empty_mat", "empty `.mat` (0 bytes)", _write("empty.mat", b""), "file is empty"),
    BadInput("header_only", "CSV header without rows", _write("header.csv", "t,v,x1,x2,x3\n"),
             "no data rows"),
    BadInput("truncated_csv", "CSV cut in the middle of a row",
             _csv("cut.csv", lines=lambda ls: ls[:-1] + [ls[-1][:9]]),
             r"line 401 has \d columns, expected 5 \(truncated or ragged file\)"),
    BadInput("truncated_mat", "MATLAB v5 file cut at half its length",
             _ecp_mat("cut.mat", cut=0.5), "not a readable MATLAB v5 file .truncated or corrupt"),
    BadInput("truncated_mat_header", "`.mat` shorter than its 128-byte header",
             _write("stub.mat", b"MATLAB 5.0 MAT-file"), r"truncated \.mat file"),
    BadInput("garbage_csv", "4 kB of random bytes named `.csv`", _write("noise.csv", _GARBAGE),
             "not a text file"),
    BadInput("garbage_txt", "4 kB of random bytes named `.txt`", _write("noise.txt", _GARBAGE),
             "not a text file"),
    BadInput("garbage_mat", "4 kB of random bytes named `.mat`", _write("noise.mat", _GARBAGE),
             "not a readable MATLAB v5 file"),
    BadInput("huge", f"CSV of {3 * _LIMIT // 2 // 2**20} MiB (sparse), over the "
             f"{_LIMIT // 2**20} MiB limit", _sparse("huge.csv", 3 * _LIMIT // 2),
             f"over the size limit of {_LIMIT} bytes; raise it with .*BAYESMODAL_MAX_BYTES"),
    BadInput("text_value", "a word where a number belongs",
             _csv("word.csv", lines=lambda ls: ls[:5] + [_field(ls[5], 1, "abc")] + ls[6:]),
             "line 6: non-numeric value"),
    BadInput("nan", "NaN in an output", _csv("nan.csv", lambda t, v, y: (t, v, _set(y, (50, 1),
                                                                                   np.nan))),
             r"y has 1 non-finite value\(s\) \(NaN or inf\), first at index \(50, 1\)"),
    BadInput("inf", "inf in the input voltage",
             _csv("inf.csv", lambda t, v, y: (t, _set(v, 7, np.inf), y)),
             r"v has 1 non-finite value\(s\)"),
    BadInput("nonuniform", "one time step 1.5 times the others",
             _csv("gap.csv", lambda t, v, y: (np.r_[t[:200], t[200:] + DT / 2], v, y)),
             "time steps are not equally spaced"),
    BadInput("decreasing", "time running backwards", _csv("back.csv", lambda t, v, y: (t[::-1],
                                                                                      v, y)),
             "time is not strictly increasing at sample 1"),
    BadInput("duplicate_time", "a duplicated time stamp",
             _csv("dup.csv", lambda t, v, y: (_set(t, 101, t[100]), v, y)),
             r"not strictly increasing at sample 101 .*duplicated or decreasing"),
    BadInput("ragged", "CSV with a short row in the middle",
             _csv("ragged.csv", lines=lambda ls: ls[:10] + [ls[10].rsplit(",", 1)[0]] + ls[11:]),
             "line 11 has 4 columns, expected 5"),
    BadInput("unequal_mat", "`.mat` whose x1 is shorter than t",
             _ecp_mat("short.mat", x1=np.zeros((N - 10, 1))), "unequal column lengths"),
    BadInput("missing_column", "CSV without the input column v",
             _csv("nov.csv", header="t,x1,x2,x3,x4"),
             r"missing column\(s\) \['v'\]"),
    BadInput("extra_column", "CSV with an extra column F",
             _csv("extra.csv", lambda t, v, y: (t, v, np.column_stack([y, y[:, 0]])),
                  header="t,v,x1,x2,x3,F"), r"unknown column\(s\) \['F'\]"),
    BadInput("txt_two_columns", "ECP `.txt` with two columns",
             _write("two.txt", "0 0\n0.005 1\n0.01 0\n"), "2 column.s.; an ECP .txt file needs"),
    BadInput("single_sample", "a single sample", _csv("one.csv", lambda t, v, y: (t[:1], v[:1],
                                                                                 y[:1])),
             "only 1 samples; need at least 3"),
    BadInput("zero_input", "input voltage all zeros",
             _csv("still.csv", lambda t, v, y: (t, v * 0, y)),
             "the input is all zeros; nothing is identifiable",
             entries=CLI),
    BadInput("zero_outputs", "outputs all zero (no cart moves)",
             _csv("stuck.csv", lambda t, v, y: (t, v, y * 0)),
             r"every output is constant \(no cart ever moves\); nothing is identifiable",
             entries=CLI),
    BadInput("counts_csv", "CSV outputs in encoder counts, not metres",
             _csv("counts.csv", lambda t, v, y: (t, v, y / (0.0706 / 16000))),
             r"implausible for the rig .* are the outputs in encoder counts\? give "
             r"--m-per-count 4.4125e-06"),
    BadInput("mm_csv", "CSV outputs in mm, not metres",
             _csv("mm.csv", lambda t, v, y: (t, v, y * 1e3)),
             r"implausible for the rig .* are the outputs in mm\? give --m-per-count 0.001"),
    BadInput("metres_mat", "ECP `.mat` holding metres where counts belong",
             _ecp_mat("metres.mat", **{f"x{i + 1}": _record()[2][:, i:i + 1]
                                       for i in range(3)}),
             r"below one encoder count; if they are already in metres give --m-per-count 1"),
    BadInput("logger_mat_no_map", "logger `.mat` (time, enc1..enc3, target_v, a struct) "
             "without a column map", _logger_mat("logger.mat"),
             r"missing column\(s\) \['t', 'v', 'x1'\].*map the file's columns with "
             r"--columns t=NAME.*available: time, enc1"),
    BadInput("logger_mat_wrong_name", "logger `.mat`, column map naming a variable it lacks",
             _logger_mat("logger.mat"), r"column 'enc4' \(for x3\) not found",
             entries=("load_experiment", "lsq", "ema", "run"),
             args=("--columns", "t=time,v=target_v,x1=enc1,x2=enc2,x3=enc4",
                   "--input-scale", "5/4096")),
    BadInput("logger_mat_text_field", "logger `.mat`, column map naming a text struct field",
             _logger_mat("logger.mat"), r"variable 'run.operator' is text, not a real numeric",
             entries=("load_experiment", "lsq", "ema", "run"),
             args=("--columns", "t=time,v=run.operator,x1=enc1,x2=enc2,x3=enc3")),
    BadInput("logger_mat_converter_units", "logger `.mat` read without --input-scale "
             "(input in converter units)", _logger_mat("logger.mat"),
             r"input up to 2458 V is far beyond the rig's \+-10 V command.*--input-scale 5/4096",
             entries=("load_experiment", "lsq", "ema", "run"), args=_LOGGER_MAP),
    BadInput("txt_header_no_map", "`.txt` with header rows `Sample Time Encoder 1 Pos "
             "... Motor Voltage`, no column map",
             _ecp_text("header.txt", header=("; exported", "Sample\tTime\tEncoder 1 Pos\t"
                                             "Encoder 2 Pos\tEncoder 3 Pos\tMotor Voltage"),
                       index=True),
             r"header 'Sample\\tTime.*does not name the columns t, x1..xn, v.*--columns.*"
             r"Time \(2\)"),
    BadInput("txt_column_number", "ECP `.txt`, column map with a column number beyond the "
             "last", _ecp_text("header.txt", header=("Sample Time Encoder 1 Pos Encoder 2 Pos "
                                                     "Encoder 3 Pos Control Effort",),
                               index=True),
             "column number 9 is out of range: the file has 6 columns",
             entries=("load_experiment", "lsq", "ema", "run"),
             args=("--columns", "t=2,x1=3,x2=4,x3=5,v=9")),
    BadInput("txt_sample_index", "header-less `.txt` whose first column is a sample index",
             _ecp_text("indexed.txt", index=True),
             r"the time column 't' counts samples \(0, 1, 2, ...\), it is not a time in "
             r"seconds; map the time column with --columns t=NAME"),
    BadInput("txt_time_ms", "ECP `.txt` with time in milliseconds",
             _ecp_text("ms.txt", time_scale=1e3),
             r"sample interval 5 s is implausible .*--time-scale 1/1000"),
    BadInput("rounded_time", "timestamps rounded to whole milliseconds (4.5 ms steps)",
             _ecp_text("rounded.txt", time=lambda t: np.round(np.arange(t.size) * 0.0045, 3)),
             r"timestamps are rounded to 0.001 s; regularised to a uniform step of 0.004\d+ s, "
             r"moving samples by at most 0.000\d+ s \(1\d % of a step\)",
             entries=("load_experiment", "lsq"), warn=True),
    BadInput("jittered_time", "timestamps jittering by up to 30 % of a step (kept)",
             _ecp_text("jitter.txt", time=lambda t: t + DT * np.random.default_rng(2).uniform(
                 -0.3, 0.3, t.size)),
             r"timestamps are not uniform: steps 0.00\d+ to 0.00\d+ s \(median 0.005\d* s\), "
             r"stamps -0.001\d* to \+0.001\d* s from a uniform step of 0.005\d* s; kept as "
             r"recorded: the linear model is simulated on them step by step",
             entries=("load_experiment", "lsq"), warn=True),
    BadInput("mat_struct", "`.mat` holding one struct `data`",
             _write("struct.mat", _mat_bytes(data={"t": np.arange(5.0), "x": np.zeros(5)})),
             r"missing column\(s\) \['t', 'v', 'x1'\].*found data \(struct\)"),
    BadInput("mat_extra_variable", "`.mat` with t, x1..x3, v and a variable `notes`",
             _ecp_mat("notes.mat", notes=np.arange(3.0)),
             r"unexpected variable\(s\) \['notes'\]"),
    BadInput("mat_text_variable", "`.mat` whose v is text",
             _ecp_mat("text.mat", v="volts"), r"variable\(s\) \['v'\] must be real numeric"),
    BadInput("mat_nan", "`.mat` with NaN in t", _ecp_mat("nan.mat", t=np.full((N, 1), np.nan)),
             r"t has \d+ non-finite value"),
    BadInput("mat73_extra", "MATLAB v7.3 (HDF5) file with a struct `settings` besides "
             "t, x1..x3, v", _mat73("v73.mat", extra_group=True),
             r"unexpected variable\(s\) \['settings'\]"),
    BadInput("mat73_corrupt", "MATLAB v7.3 (HDF5) file with its data overwritten by noise",
             _mat73("v73bad.mat", corrupt=True),
             r"not a readable MATLAB v7.3 \(HDF5\) file"),
    BadInput("ecp_export", "ECP Executive export (`[` rows `;`, times printed to 1 ms at "
             "8.854 ms steps)", _export("export.txt"),
             r"ECP Executive export: times printed to 0.001 s; the sample period 0.00885\d* s "
             r"is recovered from the Sample index by a linear fit",
             entries=("load_experiment", "lsq"), warn=True),
    BadInput("ecp_export_ragged", "ECP Executive export with a row cut short",
             _export("cut.txt", cut=True),
             r"line 11 has 6 values, the header names 7 columns \(Sample, Time, Commanded "
             r"Pos, .*truncated or ragged export", entries=("load_experiment", "lsq")),
    BadInput("uff_frf", "UFF file of frequency response functions (dataset 58 type 4)",
             _instrument("frf.uff", func_type=4),
             r"dataset 58 records of function type 4 \(frequency response function\), none "
             r"a time response \(type 1\); bayesmodal reads time records",
             entries=("load_experiment", "lsq")),
    BadInput("tdms_garbage", "4 kB of random bytes named `.tdms`",
             _write("noise.tdms", _GARBAGE), r"not a TDMS file \(no TDSm lead-in\)",
             entries=("load_experiment", "lsq")),
    BadInput("tdms_no_unit", "TDMS outputs without a unit label",
             _instrument("bare.tdms", label_outputs=False),
             r"no displacement channel \(a length unit such as m or mm, or counts\); name "
             r"the channels with --columns", entries=("load_experiment", "lsq")),
    BadInput("tdms_no_unit_mapped", "TDMS outputs without a unit label, mapped by name",
             _instrument("bare.tdms", label_outputs=False),
             r"output channel 'cart1' has the unit 'none', not a length or counts; give "
             r"metres per unit with --m-per-count", entries=("load_experiment", "lsq"),
             args=("--columns", "t=time,v=drive,x1=cart1,x2=cart2,x3=cart3")),
    BadInput("window_outside", "a time window after the record's end",
             _csv("short.csv"), r"t_start = 30 s is outside the record; the record spans 0 to "
             r"1.995 s \(step 0.005 s\)", entries=("load_experiment", "lsq", "run"),
             args=("--t-start", "30")),
    BadInput("window_in_motion", "a time window that starts while the carts swing",
             _csv("swing.csv"), r"the window starts at t = 0.3 s with output 1 at -?\d.* mm, "
             r"not at rest; .*where the carts rest at 0 with no input",
             entries=("lsq", "run"), args=("--t-start", "0.3"),
             patterns={"lsq": r"fit it with --initial-state estimate, or start the window"}),
    BadInput("release_driven", "a driven record (a 3 V pulse) read as a hand release",
             _csv("driven.csv"), r"the input is not zero \(up to 3 V\); --release auto is "
             r"for a cart released by hand with no input", entries=("load_experiment", "lsq"),
             args=("--release", "auto")),
    BadInput("rest_offset_no_rest", "a record whose input starts at its third sample, read "
             "with the rest before the input removed",
             _csv("early.csv", lambda t, v, y: (t, np.roll(v, -18), y)),
             r"the input starts at sample 3; --rest-offset initial needs at least 10 samples "
             r"at rest before it", entries=("load_experiment", "lsq"),
             args=("--rest-offset", "initial")),
    BadInput("rest_offset_left_in", "encoders not zeroed at rest (outputs 0.3 mm off 0 "
             "before the first input)",
             _csv("offset.csv", lambda t, v, y: (t, v, y + 3e-4)),
             r"before the first input the carts rest with output 1 at 0.3 mm, not at 0 "
             r"where (the model starts|a run starts every record); an encoder not zeroed "
             r"at rest", entries=("lsq", "sample", "diagnose", "run", "batch"),
             patterns={"run": r"rest_offset = \"initial\" in \[data\]",
                       "batch": r"rest_offset = \"initial\" in \[data\]"}),
    BadInput("reversed_drive", "a drive wired the other way round (+V moves the carts to "
             "negative counts)", _reversed("reversed.csv"),
             r"the carts move against the input: below 0.5 Hz.* give --input-scale -1",
             entries=("load_experiment",), warn=True),
    BadInput("unrelated_input", "an input column from another run (its pulse 1.4 s after "
             "the carts moved)",
             _csv("late.csv", lambda t, v, y: (t, np.roll(v, 280), y)),
             r"not identified: no finite standard error for g_v, .*the data do not "
             r"determine them; check that the input column is the motor command in volts",
             entries=("lsq",)),
    BadInput("closed_loop_reference", "a closed-loop ECP export (a PID's effort drove the "
             "carts, 8 ms servo period) read with the commanded position as its input",
             _closed_loop("pid.txt"),
             r"not identified: .*in a closed-loop record the control effort, 'Control "
             r"Effort' of an ECP export, not the commanded position",
             entries=("lsq",),
             args=("--columns", "t=Time,v=Commanded Pos,x1=Encoder 1 Pos,x2=Encoder 2 Pos,"
                   "x3=Encoder 3 Pos", "--input-scale", "1/800")),
    BadInput("two_carts", "a 2-cart record for the 3-cart model",
             _csv("two.csv", lambda t, v, y: (t, v, y[:, :2]), header="t,v,x1,x2"),
             "2 outputs but the rig has 3 carts",
             entries=("lsq", "sample", "diagnose", "run", "batch"),
             patterns={"run": r"\[rig.springs_n_m\] 3 springs make 3 carts, but two.csv has 2",
                       "batch": r"\[rig.springs_n_m\] 3 springs make 3 carts, but two.csv has 2",
                       "diagnose": "2 outputs but the rig has 3 carts"}),
]


#: ``bayesmodal diagnose`` rows (the command was built in parallel; set False to leave it out).
INCLUDE_DIAGNOSE = True


def _have_diagnose() -> bool:
    if not INCLUDE_DIAGNOSE:
        return False
    try:
        import bayesmodal.cli._diagnose  # noqa: F401
    except ImportError:
        return False
    return True


def _entries() -> tuple[str, ...]:
    return ALL if _have_diagnose() else tuple(e for e in ALL if e != "diagnose")


CASES = [(e, b) for b in INPUTS for e in b.entries if e in _entries()]

RUN_CONFIG = """\
[data]
files = ["{name}"]

[sampler]
walkers = 30
steps = 20
burn = 5

[outputs]
plots = false
report = false
ema = false
predictive_draws = 0
"""


# ---------------------------------------------------------------- running a case
@dataclass(frozen=True)
class Outcome:
    """What a user sees: exit code (or exception type), stdout, stderr lines."""

    code: int | str
    out: str
    err: list[str]
    message: str
    new_files: list[str]


def _normalise(text: str, folder: Path) -> str:
    for f in (str(folder.resolve()), str(folder)):
        text = text.replace(f + os.sep, "").replace(f, ".")
    return text


def _listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _read_options(args: tuple[str, ...]):
    """The ReadOptions the command line makes of reader arguments."""
    import argparse

    from bayesmodal.cli._common import add_reader_arguments, reader_options

    parser = argparse.ArgumentParser()
    add_reader_arguments(parser)
    return reader_options(parser.parse_args(list(args)))


def _config_data(args: tuple[str, ...]) -> str:
    """The ``[data]`` keys of a run configuration that say what the reader options say."""
    lines = []
    for opt, val in zip(args[::2], args[1::2], strict=True):
        key = opt.lstrip("-").replace("-", "_")
        if key == "columns":
            pairs = (item.split("=", 1) for item in val.split(","))
            lines.append("columns = { " + ", ".join(f'{r} = "{c}"' for r, c in pairs) + " }")
        elif key in ("m_per_count", "t_start", "t_end"):   # a number in the configuration
            from bayesmodal.reading import parse_scale

            lines.append(f"{key} = {parse_scale(val, signed=True)!r}")
        else:   # a number or fraction, as on the command line
            lines.append(f'{key} = "{val}"')
    return "".join(ln + "\n" for ln in lines)


def run_case(entry: str, bad: BadInput, folder: Path) -> Outcome:
    """Try ``bad`` on ``entry`` inside ``folder`` (the working directory)."""
    folder = Path(folder).resolve()
    old = Path.cwd()
    os.chdir(folder)
    try:
        name = bad.make(folder)
        before = _listing(folder)
        if entry == "load_experiment":
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    load_experiment(name, options=_read_options(bad.args))
                    code, msg = 0, ""
                except DataError as exc:
                    code, msg = "DataError", f"DataError: {exc}"
            warned = [f"{w.category.__name__}: {w.message}" for w in caught]
            err = warned
            if not msg and warned:
                msg = warned[0]
            out = ""
        elif entry in ("lsq", "ema", "diagnose"):
            # ema: a band, as the default band needs a longer record than these
            extra = {"diagnose": ["--no-posterior", "--null", "0"],
                     "ema": ["--band", "5", "60"]}.get(entry, [])
            code, out, err = _cli([entry, name, *extra, *bad.args])
            msg = err[0] if err else ""
        elif entry == "sample":
            code, out, err = _cli(["sample", name, "--out", "sampled", "--steps", "20",
                                   "--walkers", "32", "--quiet", "--no-plots", *bad.args])
            msg = err[0] if err else ""
        elif entry == "run":
            Path("cfg.toml").write_text(RUN_CONFIG.format(name=name).replace(
                "[sampler]", _config_data(bad.args) + "\n[sampler]", 1))
            before = _listing(folder)
            code, out, err = _cli(["run", "cfg.toml", "--out", "run-out", "--quiet"])
            msg = err[0] if err else ""
        else:  # pragma: no cover
            raise ValueError(entry)
        new = sorted(_listing(folder) - before)
    finally:
        os.chdir(old)
    return Outcome(code, _normalise(out, folder), [_normalise(e, folder) for e in err],
                   _normalise(msg, folder).replace("\n", " "), new)


def run_batch_cases(folder: Path) -> dict[str, Outcome]:
    """All ``batch`` cases in one ``bayesmodal batch`` call (two worker processes): each
    input in its own sub-folder with its own ``cfg.toml`` and ``[outputs] dir``."""
    folder = Path(folder).resolve()
    bads = [b for e, b in CASES if e == "batch"]
    configs = []
    for bad in bads:
        sub = folder / bad.key
        sub.mkdir()
        old = Path.cwd()
        os.chdir(sub)
        try:
            name = bad.make(sub)
        finally:
            os.chdir(old)
        text = RUN_CONFIG.format(name=name).replace("[outputs]\n",
                                                    f'[outputs]\ndir = "{bad.key}"\n')
        (sub / "cfg.toml").write_text(text)
        configs.append(str(sub / "cfg.toml"))
    before = _listing(folder)
    code, out, err = _cli(["batch", *configs, "--out-root", str(folder / "batch-out"),
                           "--workers", "2", "--quiet", "--json"])
    items = json.loads(out)["runs"]
    new = sorted(_listing(folder) - before - {"batch-out", os.path.join("batch-out",
                                                                          "batch.json")})
    res = {}
    for bad, item in zip(bads, items, strict=True):
        msg = f"error: {item['error']}" if item.get("error") else ""
        msg = _normalise(_normalise(msg, folder / bad.key), folder)
        res[_case_id("batch", bad)] = Outcome(code, "", err, msg.replace("\n", " "), new)
    return res


_OUTCOMES: dict[str, Outcome] = {}


def _case_id(entry: str, bad: BadInput) -> str:
    return f"{entry}-{bad.key}"


def outcome(entry: str, bad: BadInput, folder: Path) -> Outcome:
    """The outcome of a case, computed once per session (``batch``: all at once)."""
    key = _case_id(entry, bad)
    if key not in _OUTCOMES:
        # the default size limit, whatever the environment says
        saved = os.environ.pop("BAYESMODAL_MAX_BYTES", None)
        try:
            if entry == "batch":
                _OUTCOMES.update(run_batch_cases(folder))
            else:
                _OUTCOMES[key] = run_case(entry, bad, folder)
        finally:
            if saved is not None:
                os.environ["BAYESMODAL_MAX_BYTES"] = saved
    return _OUTCOMES[key]


# ---------------------------------------------------------------- the tests
@pytest.fixture(scope="module")
def batch_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("batch")


@pytest.mark.parametrize("entry,bad", CASES, ids=[_case_id(e, b) for e, b in CASES])
def test_bad_input(entry, bad, tmp_path, batch_folder):
    res = outcome(entry, bad, batch_folder if entry == "batch" else tmp_path)
    pattern = bad.patterns.get(entry, bad.pattern)
    assert re.search(pattern, res.message), (pattern, res)
    assert "Traceback" not in "\n".join(res.err)
    assert res.message.count("\n") == 0
    if entry == "load_experiment":
        if bad.warn:
            assert res.code == 0 and len(res.err) == 1 and res.err[0].startswith("UserWarning")
        else:
            assert res.code == "DataError"
        return
    if entry == "batch":
        # the failing run is reported in the table and batch.json; exit code 1; no run
        # folder is made
        assert res.code == 1, res
        assert res.message.startswith("error: ConfigError: cfg.toml: [")
        assert "[data.files]" in res.message or "[rig.springs_n_m]" in res.message
        assert res.new_files == [], res.new_files
        return
    if bad.warn:
        # a warning on one line; the result is still printed
        assert res.code == 0, res
        assert res.err and all(e.startswith(f"bayesmodal {entry}: warning: ") for e in res.err)
        assert res.out.strip()
        return
    assert res.code == 2, res
    assert len(res.err) == 1, res.err
    assert res.err[0].startswith(f"bayesmodal {entry}: error: ")
    assert res.out == ""  # never a partial result
    assert res.new_files == [], res.new_files  # no output folder left behind
    if entry == "run":
        assert "cfg.toml: [data.files]" in res.message or "[rig.springs_n_m]" in res.message


@pytest.mark.parametrize("entry,bad", CASES, ids=[_case_id(e, b) for e, b in CASES])
def test_message_names_the_file(entry, bad, tmp_path, batch_folder):
    res = outcome(entry, bad, batch_folder if entry == "batch" else tmp_path)
    probe = tmp_path / "probe"
    probe.mkdir()
    old = Path.cwd()
    os.chdir(probe)
    try:
        name = bad.make(probe)
    finally:
        os.chdir(old)
    # the file, or the record it holds (named by the file's stem)
    assert name in res.message or f"{Path(name).stem}: " in res.message, (name, res.message)


@pytest.mark.parametrize("entry", [e for e in CLI if e in _entries() and e != "batch"])
def test_debug_shows_the_traceback(entry, tmp_path, monkeypatch):
    bad = next(b for b in INPUTS if b.key == "empty_csv")
    monkeypatch.chdir(tmp_path)
    name = bad.make(tmp_path)
    if entry == "run":
        Path("cfg.toml").write_text(RUN_CONFIG.format(name=name))
        argv = ["--debug", "run", "cfg.toml", "--out", "o"]
    else:
        argv = ["--debug", entry, name]
    code, out, err = _cli(argv)
    assert code == 2
    assert any("Traceback" in line for line in err)
    assert err[-1].startswith(f"bayesmodal {entry}: error: ") and "file is empty" in err[-1]


# ---------------------------------------------------------------- the docs table
def _cell(text: str) -> str:
    return text.replace("|", "\\|").strip()


def render_table(outcomes: dict[str, Outcome]) -> str:
    """``docs/bad_inputs.md`` from the outcomes of every case."""
    entries = _entries()
    lines = [
        "# Bad inputs and what the user sees",
        "",
        "Generated by `python docs/make_bad_inputs_table.py` from the cases of",
        "`tests/test_bad_inputs.py`; every row is a test there (and",
        "`test_docs_table_is_in_sync` fails when this file is out of date).",
        "",
        "Every error is one line that names the file and the problem, exits with a non-zero",
        "code (2; 1 for `batch`, whose table and `batch.json` report the failed run), prints",
        "nothing on stdout and leaves no output folder; `--debug` shows the traceback.",
        "A warning is one line on stderr and the result is still given.  Loader rows show the",
        "exception of `bayesmodal.data.load_experiment`; `run` and `batch` rows use a",
        "configuration `cfg.toml` whose `[data] files` names the input.  Reader options",
        "(`--columns`, `--input-scale`, ...) shown with an input are given on the command",
        "line, to the loader as the `ReadOptions` they parse to, and to `run` as the",
        "`[data]` keys of the same names (`columns = { t = \"time\", ... }`, `input_scale`).",
        "A well-formed MATLAB v7.3 (HDF5) file with t, x1..xn, v is not a bad input: it is read",
        "like a v5 file (`test_every_entry_point_and_input_is_covered`).",
        "",
        f"Entry points: {', '.join(f'`{e}`' for e in entries)}.",
        "",
        "| input | entry point | exit | message the user sees |",
        "|---|---|---|---|",
    ]
    for entry, bad in CASES:
        res = outcomes[_case_id(entry, bad)]
        ep = "`load_experiment`" if entry == "load_experiment" else f"`bayesmodal {entry}`"
        code = res.code if isinstance(res.code, str) else str(res.code)
        what = bad.what + (f", given `{' '.join(bad.args)}`" if bad.args else "")
        lines.append(f"| {_cell(what)} | {ep} | {code} | `{_cell(res.message)}` |")
    return "\n".join(lines) + "\n"


def all_outcomes(folder: Path) -> dict[str, Outcome]:
    """Run every case (once) in sub-folders of ``folder``."""
    for i, (entry, bad) in enumerate(CASES):
        sub = Path(folder).resolve() / ("batch" if entry == "batch" else f"case{i}")
        sub.mkdir(exist_ok=True)
        outcome(entry, bad, sub)
    return _OUTCOMES


def test_docs_table_is_in_sync(tmp_path):
    text = render_table(all_outcomes(tmp_path))
    assert TABLE.is_file(), "run: python docs/make_bad_inputs_table.py"
    assert TABLE.read_text() == text, "docs/bad_inputs.md is stale: run " \
        "python docs/make_bad_inputs_table.py"


def test_every_entry_point_and_input_is_covered():
    entries = {e for e, _ in CASES}
    assert entries == set(_entries())
    assert len(INPUTS) >= 30
    # a valid record passes every loader check (the cases are bad for their stated reason)
    folder_cases = {"csv": _csv("ok.csv"), "mat": _ecp_mat("ok.mat"), "v73": _mat73("ok73.mat")}
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        for make in folder_cases.values():
            e = load_experiment(Path(d) / make(Path(d)), max_bytes=MAX_FILE_BYTES)
            assert e.n_samples == N and e.n_outputs == 3
            np.testing.assert_allclose(e.y_m, _record()[2], rtol=1e-8, atol=1e-12)


def test_size_limit_can_be_raised(tmp_path, monkeypatch):
    t, v, y = _record()
    p = tmp_path / "r.csv"
    save_csv(Experiment(t, v, y), p)
    size = p.stat().st_size
    with pytest.raises(DataError, match=f"over the size limit of {size - 1} bytes"):
        load_experiment(p, max_bytes=size - 1)
    monkeypatch.setenv("BAYESMODAL_MAX_BYTES", str(size - 1))
    with pytest.raises(DataError, match="BAYESMODAL_MAX_BYTES"):
        load_experiment(p)
    monkeypatch.setenv("BAYESMODAL_MAX_BYTES", str(size))
    assert load_experiment(p).n_samples == N


def test_an_unexpected_error_is_one_line_too(tmp_path, monkeypatch):
    # a bug (not a data problem) still reaches the user as one line, exit code 1, and
    # --debug shows the traceback
    import bayesmodal.cli._lsq as lsq

    def boom(args):
        raise RuntimeError("something the package did not foresee\nsecond line")

    monkeypatch.setattr(lsq, "run", boom)
    code, out, err = _cli(["lsq", "x.csv"])
    assert code == 1 and out == "" and len(err) == 1, err
    assert err[0] == ("bayesmodal lsq: internal error: RuntimeError: something the package "
                      "did not foresee (run with --debug for the traceback)")
    code, _, err = _cli(["--debug", "lsq", "x.csv"])
    assert code == 1 and any("Traceback" in line for line in err)
