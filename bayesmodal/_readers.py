"""File formats to named columns: MATLAB v5 / v7.3 variables and text tables.

Each reader returns what the file holds, without interpreting it: MATLAB variables (struct
fields flattened to ``struct.field``) with a kind per variable, or a text table with its
header names.  ``bayesmodal._columns`` decides which column is time, input and output.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import DataError

#: Deepest struct nesting flattened into ``a.b.c`` names.
_MAX_DEPTH = 4


@dataclass(frozen=True)
class MatVariables:
    """Variables of a MATLAB file.

    Attributes
    ----------
    kinds : dict of str to str
        Every variable (struct fields as ``struct.field``) and its kind: ``"numeric"``,
        ``"struct"``, ``"text"``, ``"cell"``, ...
    top : dict of str to str
        The top-level variables and their kinds.
    arrays : dict of str to ndarray
        The numeric variables.
    """

    kinds: dict
    top: dict
    arrays: dict


def _kind(v) -> str:
    """``"numeric"`` for a real numeric array, else a short description of the variable."""
    if isinstance(v, np.ndarray) and v.dtype.kind in "fiu":
        return "numeric"
    if isinstance(v, np.ndarray) and v.dtype.names:
        return "struct"
    if isinstance(v, np.ndarray) and v.dtype.kind == "O":
        return "cell"
    if isinstance(v, np.ndarray) and v.dtype.kind in "US":
        return "text"
    if isinstance(v, np.ndarray) and v.dtype.kind == "c":
        return "complex"
    return type(v).__name__


def _flatten_v5(name: str, value, kinds: dict, arrays: dict, depth: int) -> None:
    kind = _kind(value)
    kinds[name] = kind
    if kind == "numeric":
        arrays[name] = value
    elif kind == "struct" and value.size == 1 and depth < _MAX_DEPTH:
        rec = value.reshape(-1)[0]
        for field in value.dtype.names:
            _flatten_v5(f"{name}.{field}", rec[field], kinds, arrays, depth + 1)


def read_mat(path: Path) -> MatVariables:
    """Variables of a MATLAB v5 or v7.3 (HDF5) file."""
    import scipy.io

    with open(path, "rb") as fh:
        head = fh.read(128)
    if len(head) < 128:
        raise DataError(f"{path}: truncated .mat file ({len(head)} bytes of header)")
    if head[:6] == b"\x89HDF\r\n" or b"MATLAB 7.3" in head[:116]:
        return _read_mat73(path)
    try:
        raw = scipy.io.loadmat(path, squeeze_me=False)
    except Exception as exc:  # scipy raises several types for corrupt files
        raise DataError(f"{path}: not a readable MATLAB v5 file (truncated or corrupt: "
                        f"{exc})") from exc
    kinds, arrays = {}, {}
    for k, v in raw.items():
        if not k.startswith("__"):
            _flatten_v5(k, v, kinds, arrays, 0)
    top = {k: kinds[k] for k in raw if not k.startswith("__")}
    return MatVariables(kinds, top, arrays)


def _read_mat73(path: Path) -> MatVariables:
    import h5py

    kinds, arrays = {}, {}

    def visit(prefix: str, group, depth: int) -> None:
        for k in group.keys():
            if k.startswith("#"):  # MATLAB's #refs# and #subsystem# bookkeeping
                continue
            obj = group[k]
            name = f"{prefix}{k}"
            if isinstance(obj, h5py.Dataset):
                cls = obj.attrs.get("MATLAB_class", b"double")
                cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                numeric = obj.dtype.kind in "fiu" and cls not in ("char", "logical")
                kinds[name] = "numeric" if numeric else cls
                if numeric:
                    arrays[name] = np.array(obj)
            else:
                kinds[name] = "struct"
                if depth < _MAX_DEPTH:
                    visit(f"{name}.", obj, depth + 1)

    try:
        with h5py.File(path, "r") as f:
            visit("", f, 0)
    except OSError as exc:
        raise DataError(f"{path}: not a readable MATLAB v7.3 (HDF5) file (truncated or "
                        f"corrupt: {exc})") from exc
    top = {k: v for k, v in kinds.items() if "." not in k}
    return MatVariables(kinds, top, arrays)


@dataclass(frozen=True)
class TextTable:
    """A numeric table read from a text file.

    Attributes
    ----------
    data : ndarray, shape (n_rows, n_columns)
    names : list of str or None
        Column names from the last header row, when it splits into one name per column.
    header : list of str
        The header rows (lines before the first numeric row), stripped.
    """

    data: np.ndarray
    names: list | None
    header: list


def _split(line: str, delimiter: str | None) -> list[str]:
    return [p.strip() for p in line.split(delimiter)] if delimiter else line.split()


def _numeric(parts: list[str]) -> bool:
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return bool(parts)


def _header_names(line: str, width: int) -> list[str] | None:
    """One name per column: split on tabs, commas or semicolons, runs of two or more
    spaces, or single spaces, whichever gives ``width`` names."""
    import re

    for splitter in (r"\t", ",", ";", r" {2,}", r"\s+"):
        names = [n.strip() for n in re.split(splitter, line.strip())]
        if len(names) == width and all(names):
            return names
    return None


def read_text(path: Path, delimiter: str | None, *, header_rows: int | None) -> TextTable:
    """A numeric table with optional header rows.

    Parameters
    ----------
    path : Path
    delimiter : str or None
        Field separator (None: any whitespace).
    header_rows : int or None
        Number of header rows; None: every line before the first all-numeric line.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text file (binary content: {exc.reason})") from exc
    lines = [(i, ln) for i, ln in enumerate(text.splitlines(), start=1) if ln.strip()]
    if header_rows is None:
        header_rows = 0
        while header_rows < len(lines) and not _numeric(_split(lines[header_rows][1],
                                                                delimiter)):
            header_rows += 1
        if header_rows == len(lines) and lines:
            # no numeric row at all: report the first line as it would be parsed
            header_rows = 0
    header = [ln.strip() for _, ln in lines[:header_rows]]
    body = lines[header_rows:]
    if not body:
        raise DataError(f"{path}: no data rows")
    rows = []
    width = None
    for i, ln in body:
        parts = _split(ln, delimiter)
        if width is None:
            width = len(parts)
        elif len(parts) != width:
            raise DataError(
                f"{path}: line {i} has {len(parts)} columns, expected {width} "
                "(truncated or ragged file)"
            )
        try:
            rows.append([float(p) for p in parts])
        except ValueError as exc:
            raise DataError(f"{path}: line {i}: non-numeric value ({exc})") from exc
    names = _header_names(header[-1], width) if header else None
    return TextTable(np.array(rows, dtype=float), names, header)
