"""The ECP Executive's "export raw data" text format.

The ECP Executive (the real-time controller program of the ECP 210 and its torsional
siblings) writes gathered data as a MATLAB matrix literal under a header row::

     Sample   Time     Commanded Pos   Encoder 1 Pos   Encoder 2 Pos   Control Effort

    [    0    0.000      0      0      0   0.0000;
         1    0.009      0      0      0   0.5000;
       ...
       676    5.985    -11    -11    -32   0.0000]

one column per gathered quantity: the sample index, the time in s printed to three
decimals, the commanded position and each encoder's position in counts, and the control
effort (the motor command) in volts.  The first row opens with ``[``, rows end with
``;``, the last closes with ``]``.

The printed time is rounded: the servo's sample period (8.854 ms on the ECP 210) is not a
whole number of milliseconds.  The sample index is exact, so the period is the slope of
the least-squares line of the printed times on the index, and the times are replaced by
that line when every printed time lies within half a printing quantum of some line (the
Chebyshev test of :mod:`bayesmodal.timebase`): rounding, and nothing else, explains them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import DataError
from .timebase import _minimax_line

#: A column name of the export: index, time, commanded and measured positions (velocities
#: and accelerations when gathered), control effort.
_NAME = (r"(?:Sample|Time|Control Effort|Commanded (?:Pos(?:ition)?|Vel(?:ocity)?|"
         r"Acc(?:eleration)?)|Encoder \d+ (?:Pos(?:ition)?|Vel(?:ocity)?|Acc(?:eleration)?))")
_HEADER = re.compile(rf"\s*{_NAME}(?:\s+{_NAME})*\s*", re.IGNORECASE)
_TOKEN = re.compile(_NAME, re.IGNORECASE)
_ENCODER = re.compile(r"Encoder (\d+) Pos(?:ition)?", re.IGNORECASE)


@dataclass(frozen=True)
class ExportTable:
    """The columns of an ECP Executive export.

    Attributes
    ----------
    names : list of str
        Column names as the header spells them (``"Encoder 1 Pos"``).
    data : ndarray, shape (n_rows, n_columns)
        The values: sample index, time (s), counts, volts.
    decimals : int
        Decimals printed in the time column (3: a quantum of 1 ms).
    """

    names: list
    data: np.ndarray
    decimals: int

    def column(self, name: str) -> np.ndarray | None:
        """The column of that name (case-insensitive), or None."""
        for i, n in enumerate(self.names):
            if n.lower() == name.lower():
                return self.data[:, i]
        return None

    @property
    def encoders(self) -> dict[int, np.ndarray]:
        """Encoder number to its position column, counts."""
        out = {}
        for i, n in enumerate(self.names):
            m = _ENCODER.fullmatch(n)
            if m:
                out[int(m.group(1))] = self.data[:, i]
        return out


def header_index(lines: list[str]) -> int | None:
    """Index of the export's header row in ``lines``, or None when it is not an export.

    The header is the last non-blank line before the first row of numbers (bracketed or
    not), and it must consist of export column names only, among them ``Sample``,
    ``Time``, ``Control Effort`` and at least one ``Encoder k Pos``.
    """
    last = None
    for i, ln in enumerate(lines):
        s = ln.strip()
        if not s:
            continue
        if s[0] in "[-+.0123456789":
            break
        last = i
    if last is None or not _HEADER.fullmatch(lines[last]):
        return None
    names = {n.lower() for n in _TOKEN.findall(lines[last])}
    if not ({"sample", "time", "control effort"} <= names
            and any(_ENCODER.fullmatch(n) for n in names)):
        return None
    return last


def read_export(path: Path, lines: list[str], header: int) -> ExportTable:
    """The table of an export whose header row is ``lines[header]``.

    Raises
    ------
    DataError
        A row with another number of values than the header has names, a value that is
        not a number, or no rows.
    """
    names = [" ".join(n.split()) for n in _TOKEN.findall(lines[header])]
    rows, decimals = [], 0
    for i, ln in enumerate(lines[header + 1:], start=header + 2):
        body = ln.replace("[", " ").replace("]", " ").replace(";", " ").strip()
        if not body:
            continue
        parts = body.split()
        if len(parts) != len(names):
            raise DataError(f"{path}: line {i} has {len(parts)} values, the header names "
                            f"{len(names)} columns ({', '.join(names)}); truncated or "
                            "ragged export")
        try:
            rows.append([float(p) for p in parts])
        except ValueError as exc:
            raise DataError(f"{path}: line {i}: non-numeric value ({exc})") from exc
        t_text = parts[[n.lower() for n in names].index("time")]
        decimals = max(decimals, len(t_text.partition(".")[2]))
    if not rows:
        raise DataError(f"{path}: an ECP Executive export with no data rows")
    return ExportTable(names, np.array(rows, dtype=float), decimals)


@dataclass(frozen=True)
class ExportTime:
    """Times of an export recovered from its sample index.

    Attributes
    ----------
    t_s : ndarray, shape (N,)
        ``t0 + dt * sample``, s (the printed times when ``recovered`` is False).
    dt : float
        Sample period per unit of the index, s.
    recovered : bool
        The printed times are a rounded copy of the line and were replaced by it.
    max_shift_s : float
        Largest distance of a printed time from the line, s.
    quantum_s : float
        Printing quantum, ``10**-decimals`` s.
    """

    t_s: np.ndarray
    dt: float
    recovered: bool
    max_shift_s: float
    quantum_s: float

    def message(self) -> str:
        """One line saying what was done."""
        return (f"ECP Executive export: times printed to {self.quantum_s:g} s; the sample "
                f"period {self.dt:.6g} s is recovered from the Sample index by a linear fit "
                f"of the printed times, which moves them by at most {self.max_shift_s:.3g} s")


def export_time(sample: np.ndarray, printed: np.ndarray, decimals: int) -> ExportTime:
    """The time base of an export: the least-squares line of the printed times on the
    sample index, when rounding to ``10**-decimals`` s explains their deviations.

    Parameters
    ----------
    sample : ndarray, shape (N,)
        Sample index (exact).
    printed : ndarray, shape (N,)
        Printed times, s.
    decimals : int
        Decimals printed.

    Returns
    -------
    ExportTime
    """

    q = 10.0 ** -decimals
    k = np.asarray(sample, float)
    t = np.asarray(printed, float)
    if k.size < 3 or np.any(np.diff(k) <= 0):
        return ExportTime(t, float("nan"), False, 0.0, q)
    dt, t0 = np.polyfit(k, t, 1)
    line = t0 + dt * k
    r = t - line
    shift = float(np.max(np.abs(r)))
    # rounding to q leaves every printed time within q/2 of the true line; the
    # least-squares line may miss by more when many printed times are ties, so the
    # test is the best (Chebyshev) line's
    if dt > 0 and _minimax_line(k - k[0], r / q) <= 0.5 + 1e-6:
        return ExportTime(line, float(dt), True, shift, q)
    return ExportTime(t, float(dt), False, shift, q)
