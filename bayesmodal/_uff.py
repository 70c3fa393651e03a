"""Universal File Format (UFF/UNV) dataset 58 time records, read with ``pyuff``.

Dataset 58 ("function at nodal DOF") holds one channel per record: ID lines, the
response node and direction, the function type (1: time response; 4: a frequency
response function, ...), the abscissa (minimum and increment, or the values) with its
unit label, the ordinate's specific data type (8 displacement, 13 excitation force, ...)
and unit label, and the samples in fixed-width ASCII or binary.  The variants (ASCII or
binary, single or double precision, even or uneven abscissa, real or complex) are what
``pyuff`` reads; this module keeps the time records and names them.

A record's name is its first ID line, or ``NODE:DIR`` when that line is empty; the
alias ``NODE:DIR`` (``2:1``) always works.  Without a column map the outputs are the
displacement records ordered by node and direction, the input the one voltage (else
force) record.  A record measured along a negative direction (``-1``: -X) is negated so
that every output counts along +X.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._channels import Channel, channel_roles, require
from ._errors import DataError

#: Dataset 58 function types (the names of the common ones, for messages).
_FUNCTION = {0: "general", 1: "time response", 2: "auto spectrum", 3: "cross spectrum",
             4: "frequency response function", 5: "transmissibility", 6: "coherence",
             9: "power spectral density", 12: "spectrum"}


def _label(s) -> str:
    s = str(s or "").strip()
    return "" if s.upper() == "NONE" else s


def read_channels(path: Path) -> list[Channel]:
    """The time records of a UFF file as channels, ordered by node and direction.

    Parameters
    ----------
    path : Path

    Returns
    -------
    list of Channel

    Raises
    ------
    DataError
        pyuff missing, no dataset 58 record, no time record (function type 1), a record
        shorter than its header says (truncated file), complex samples.
    """
    pyuff = require("pyuff", "uff", path)
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises several types for malformed files
        raise DataError(f"{path}: not a readable UFF file ({str(exc).splitlines()[0]})"
                        ) from exc
    if isinstance(sets, dict):
        sets = [sets]
    s58 = [s for s in sets if s.get("type") == 58]
    if not s58:
        found = sorted({s.get("type") for s in sets})
        raise DataError(f"{path}: no dataset 58 (function at nodal DOF) record"
                        + (f"; the file holds datasets {found}" if found else
                           " (not a UFF file, or truncated)"))
    times = [s for s in s58 if s.get("func_type") == 1]
    if not times:
        kinds = sorted({f"{s.get('func_type')} ({_FUNCTION.get(s.get('func_type'), '?')})"
                        for s in s58})
        raise DataError(f"{path}: dataset 58 records of function type {', '.join(kinds)}, "
                        "none a time response (type 1); bayesmodal reads time records")
    channels = []
    for s in sorted(times, key=lambda s: (s["rsp_node"], abs(s["rsp_dir"]))):
        node, direction = int(s["rsp_node"]), int(s["rsp_dir"])
        alias = f"{node}:{direction}"
        name = _label(s.get("id1")) or alias
        data, x = np.asarray(s["data"]), np.asarray(s["x"], dtype=float)
        if data.size != int(s.get("num_pts", data.size)):
            raise DataError(f"{path}: record {name!r} holds {data.size} values, its header "
                            f"says {s['num_pts']} (truncated or corrupt file)")
        if np.iscomplexobj(data):
            raise DataError(f"{path}: record {name!r} holds complex values; a time "
                            "record is real")
        t_unit = _label(s.get("abscissa_axis_units_lab")).lower()
        t_s = x * (1e-3 if t_unit == "ms" else 1.0)
        sign = -1.0 if direction < 0 else 1.0
        channels.append(Channel(name, sign * data.astype(float),
                                _label(s.get("ordinate_axis_units_lab")), t_s, (alias,)))
    return channels


def read_roles(path: Path, columns: dict | None, m_per_count: float | None,
               time_scale: float) -> dict:
    """``t`` (s), ``v`` (V) and ``x1..xn`` (m) of a UFF file (``_channels.channel_roles``)."""
    return channel_roles(path, read_channels(path), columns=columns,
                         m_per_count=m_per_count, time_scale=time_scale)
