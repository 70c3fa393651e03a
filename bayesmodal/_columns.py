"""Columns of a table-shaped lab file to the roles t, v, x1..xn (ECP .mat/.txt, CSV).

MATLAB variables and text tables (read by ``_readers``, the ECP Executive's export by
``_ecp_export``) hold one column per quantity.  Without a column map the file's own
layout names them: ECP ``.mat``/``.txt`` files ``t, x1..xn, v`` (a ``.txt`` by position
without a header), a CSV its header ``t,v,x1,...,xn``; with one
(``ReadOptions.columns``) each role is the variable, header name or column number it
names.  Each reader returns the role's raw column, in the file's units, and refuses a
missing, misnamed or gapped column with the fix.  ``bayesmodal.data`` scales them and
builds the ``Experiment``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from . import _ecp_export, _readers
from ._errors import DataError
from .reading import ReadOptions
from .timebase import _DT_RTOL

__all__ = ["csv_roles", "mat_roles", "txt_roles"]


def _hint_columns(names) -> str:
    shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
    return ("map the file's columns with --columns t=NAME,v=NAME,x1=NAME,... "
            f"(ReadOptions(columns=...)); available: {shown}")


def _standard(k: str) -> bool:
    return k in ("t", "v") or (k[:1] == "x" and k[1:].isdigit())


def _check_variables(path: Path, kinds: dict[str, str], numeric: list[str]) -> None:
    """Refuse a MATLAB file whose variables are not exactly numeric t, x1..xn, v."""
    found = ", ".join(f"{k} ({kind})" for k, kind in kinds.items()) or "no variables"
    wrong = [k for k, kind in kinds.items() if _standard(k) and kind != "numeric"]
    if wrong:
        raise DataError(f"{path}: variable(s) {wrong} must be real numeric vectors; found "
                        f"{found}")
    has_x = any(k[:1] == "x" for k in kinds if _standard(k))
    missing = [k for k in ("t", "v") if k not in kinds] + ([] if has_x else ["x1"])
    if missing:
        raise DataError(f"{path}: missing column(s) {missing}; an ECP .mat file holds "
                        f"t, x1..xn, v (found {found}); " + _hint_columns(numeric))
    unexpected = [k for k in kinds if not _standard(k)]
    if unexpected:
        raise DataError(f"{path}: unexpected variable(s) {unexpected}; an ECP .mat file "
                        "holds only t, x1..xn, v (save the record without the others, or "
                        "pick the columns with --columns t=t,v=v,x1=x1,...)")


def _standard_roles(path: Path, cols: dict[str, np.ndarray], what: str) -> dict:
    xs = sorted((k for k in cols if k[:1] == "x" and k[1:].isdigit()), key=lambda k: int(k[1:]))
    missing = [k for k in ("t", "v") if k not in cols]
    if not xs:
        missing.append("x1")
    if missing:
        raise DataError(f"{path}: missing column(s) {missing}; {what} needs t, x1..xn, v "
                        f"(found {sorted(cols)})")
    if xs != [f"x{i + 1}" for i in range(len(xs))]:
        raise DataError(f"{path}: output columns must be x1..xn without gaps, found {xs}")
    return {k: cols[k] for k in ("t", "v", *xs)}


def _mapped_roles(path: Path, opts: ReadOptions, lookup, available: list[str]) -> dict:
    roles = {}
    for role, source in opts.columns:
        col = lookup(source)
        if col is None:
            raise DataError(f"{path}: column {source!r} (for {role}) not found; "
                            + _hint_columns(available))
        roles[role] = col
    return roles


def mat_roles(path: Path, opts: ReadOptions) -> dict:
    var = _readers.read_mat(path)
    numeric = list(var.arrays)
    if opts.columns is None:
        _check_variables(path, var.top, numeric)
        return _standard_roles(path, dict(var.arrays), "an ECP file")

    def lookup(name: str):
        if name in var.arrays:
            return var.arrays[name]
        if name in var.kinds:
            raise DataError(f"{path}: variable {name!r} is {var.kinds[name]}, not a real "
                            f"numeric vector; " + _hint_columns(numeric))
        return None

    return _mapped_roles(path, opts, lookup, numeric)


def txt_roles(path: Path, opts: ReadOptions) -> dict:
    export = _export_roles(path, opts)
    if export is not None:
        return export
    table = _readers.read_text(path, None, header_rows=None)
    arr, names = table.data, table.names
    width = arr.shape[1]
    if opts.columns is None:
        if table.header:
            if names is not None and set(names) >= {"t", "v"}:
                return _standard_roles(path, {n: arr[:, i] for i, n in enumerate(names)},
                                       "an ECP .txt file")
            raise DataError(f"{path}: header {table.header[-1][:60]!r} does not name the "
                            "columns t, x1..xn, v; " + _hint_columns(_available(names, width)))
        if width < 3:
            raise DataError(f"{path}: {width} column(s); an ECP .txt file needs t x1 .. xn v")
        cols = {"t": arr[:, 0], "v": arr[:, -1]}
        cols.update({f"x{i + 1}": arr[:, 1 + i] for i in range(width - 2)})
        return cols
    return _table_roles(path, opts, arr, names)


def _export_roles(path: Path, opts: ReadOptions) -> dict | None:
    """Roles of an ECP Executive export (``_ecp_export``), or None for another text file.

    Without a column map: time from the Sample index (the printed times are rounded),
    the input from ``Control Effort`` (V), outputs from ``Encoder 1..n Pos`` (counts).
    With a map, columns are named as the header spells them (``Time`` is the recovered
    time) or by number.
    """
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        return None  # read_text says it is not a text file
    header = _ecp_export.header_index(lines)
    if header is None:
        return None
    table = _ecp_export.read_export(path, lines, header)
    time = _ecp_export.export_time(table.column("Sample"), table.column("Time"),
                                   table.decimals)
    # times printed exactly (to rounding of the float itself) need no word
    if time.recovered and time.max_shift_s > _DT_RTOL * time.dt + 1e-12:
        warnings.warn(f"{path}: {time.message()}", stacklevel=5)
    data = table.data.copy()
    data[:, [n.lower() for n in table.names].index("time")] = time.t_s
    if opts.columns is not None:
        return _table_roles(path, opts, data, table.names)
    enc = table.encoders
    if sorted(enc) != list(range(1, len(enc) + 1)):
        raise DataError(f"{path}: ECP Executive export with encoders {sorted(enc)}; the "
                        "outputs must be Encoder 1..n Pos without gaps, or map them with "
                        "--columns x1='Encoder 2 Pos',... " + _hint_columns(
                            _available(table.names, len(table.names))))
    roles = {"t": time.t_s, "v": table.column("Control Effort")}
    roles.update({f"x{k}": enc[k] for k in sorted(enc)})
    return roles


def _table_roles(path: Path, opts: ReadOptions, arr: np.ndarray, names) -> dict:
    width = arr.shape[1]
    index = {n: i for i, n in enumerate(names or [])}

    def lookup(name: str):
        if name in index:
            return arr[:, index[name]]
        if name.isdigit():
            if not 1 <= int(name) <= width:
                raise DataError(f"{path}: column number {name} is out of range: the file "
                                f"has {width} columns (numbered from 1)")
            return arr[:, int(name) - 1]
        return None

    return _mapped_roles(path, opts, lookup, _available(names, width))


def _available(names, width: int) -> list[str]:
    """Columns of a text table as a user may name them: header names with their numbers,
    or numbers only."""
    if names:
        return [f"{n} ({i + 1})" for i, n in enumerate(names)]
    return [f"columns 1..{width} by number"]


def csv_roles(path: Path, opts: ReadOptions) -> dict:
    try:
        with open(path, encoding="utf-8") as fh:
            header = fh.readline()
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text file (binary content)") from exc
    names = [h.strip() for h in header.strip().split(",")]
    if opts.columns is not None:  # any number of header rows; names from the last one
        table = _readers.read_text(path, ",", header_rows=None)
        return _table_roles(path, opts, table.data, table.names)
    xs = [h for h in names if h.startswith("x") and h[1:].isdigit()]
    missing = [c for c in ("t", "v") if c not in names]
    if not xs:
        missing.append("x1")
    if missing:
        raise DataError(
            f"{path}: missing column(s) {missing} in header {names}; "
            "a CSV needs the header t,v,x1,...,xn (SI units: s, V, m), or map its columns "
            "with --columns t=NAME,v=NAME,x1=NAME,..."
        )
    extra = [h for h in names if h not in ("t", "v") and h not in xs]
    if extra:
        raise DataError(f"{path}: unknown column(s) {extra}; expected t,v,x1,...,xn (or map "
                        "the columns with --columns)")
    if len(set(names)) != len(names):
        raise DataError(f"{path}: duplicated column names in header {names}")
    expected = [f"x{i + 1}" for i in range(len(xs))]
    if sorted(xs, key=lambda k: int(k[1:])) != expected:
        raise DataError(f"{path}: output columns must be x1..xn without gaps, found {xs}")
    arr = _readers.read_text(path, ",", header_rows=1).data
    if arr.shape[1] != len(names):
        raise DataError(f"{path}: rows have {arr.shape[1]} columns, header has {len(names)}")
    col = {h: arr[:, i] for i, h in enumerate(names)}
    return {k: col[k] for k in ("t", "v", *expected)}
