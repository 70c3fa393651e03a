"""Named channels with units to the roles t, v, x1..xn (the UFF and TDMS readers' layer).

Instrument files (UFF dataset 58, TDMS) hold one named channel per sensor, each with its
own unit label and time axis, not a table of columns in a fixed order.  The readers
``_uff`` and ``_tdms`` turn a file into :class:`Channel` objects; :func:`channel_roles`
picks time, input and outputs from them (by unit, or by name with a column map) and
converts each to SI: time in s, the input in V (before ``input_scale``), the outputs in m.

Units of the outputs: a length label (``m``, ``mm``, ``um``, ``cm``, ``in``) converts by
its own factor; encoder counts (``counts``, ``cnt``, ``count``) by ``m_per_count``
(default the ECP 210's 0.0706/16000 m); an output with no unit label needs
``m_per_count``.  A ``m_per_count`` that contradicts a length label is refused.  The
input: ``V`` (or ``mV``) converts to volts; a force channel (``N``) is read as it is.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import DataError

#: Metres per unit of the length labels an instrument writes.
_LENGTH = {"m": 1.0, "meter": 1.0, "metre": 1.0, "mm": 1e-3, "cm": 1e-2, "um": 1e-6,
           "µm": 1e-6, "micron": 1e-6, "in": 0.0254, "inch": 0.0254}
#: Labels of encoder counts.
_COUNTS = {"count", "counts", "cnt", "cnts", "cts", "pulses"}
#: Volts per unit of the voltage labels.
_VOLT = {"v": 1.0, "volt": 1.0, "volts": 1.0, "mv": 1e-3}
#: Newtons per unit of the force labels.
_FORCE = {"n": 1.0, "newton": 1.0, "kn": 1e3}
#: Seconds per unit of the time labels.
_TIME = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3}

#: Metres per encoder count of the ECP 210 (as ``bayesmodal.data.ECP_M_PER_COUNT``).
_ECP_M_PER_COUNT = 0.0706 / 16000


@dataclass(frozen=True)
class Channel:
    """One channel of an instrument file.

    Attributes
    ----------
    name : str
        The name a column map uses (a UFF record's ID line, a TDMS channel name).
    values : ndarray, shape (N,)
        The samples, in ``unit``.
    unit : str
        The unit label as written (``"mm"``, ``"V"``, ``"counts"``; ``""`` when none).
    t_s : ndarray, shape (N,), or None
        The channel's own time axis, s (a UFF abscissa, TDMS waveform properties), or
        None (a time channel itself, or no time axis).
    aliases : tuple of str
        Other names the column map may use (``"2:1"``: node 2, direction 1 of a UFF
        record; ``"group/channel"`` in TDMS).
    """

    name: str
    values: np.ndarray
    unit: str = ""
    t_s: np.ndarray | None = None
    aliases: tuple[str, ...] = ()

    @property
    def kind(self) -> str:
        """``"length"``, ``"counts"``, ``"volt"``, ``"force"``, ``"time"`` or ``""``."""
        u = self.unit.strip().lower()
        for kind, table in (("length", _LENGTH), ("counts", _COUNTS), ("volt", _VOLT),
                            ("force", _FORCE), ("time", _TIME)):
            if u in table:
                return kind
        if self.name.strip().lower() in ("t", "time"):
            return "time"
        return ""


def require(module: str, extra: str, path: Path):
    """Import an optional reader library, or one line naming the extra that installs it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise DataError(f"{path}: reading {path.suffix} files needs the optional library "
                        f"{module}: pip install 'bayesmodal[{extra}]'") from None


def _names(channels: list[Channel]) -> str:
    shown = [f"{c.name}" + "".join(f" ({a})" for a in c.aliases if a != c.name)
             + f" [{c.unit or 'no unit'}]" for c in channels[:12]]
    return ", ".join(shown) + (", ..." if len(channels) > 12 else "")


def _hint(channels: list[Channel]) -> str:
    return ("name the channels with --columns t=time,v=NAME,x1=NAME,... "
            f"(ReadOptions(columns=...)); channels: {_names(channels)}")


def _find(path: Path, channels: list[Channel], source: str, role: str) -> Channel | None:
    hits = [c for c in channels if source == c.name or source in c.aliases]
    if len(hits) > 1:
        raise DataError(f"{path}: {len(hits)} channels are named {source!r} (for {role}); "
                        "name one by its alias: " + ", ".join(
                            "/".join((c.name, *c.aliases)) for c in hits))
    return hits[0] if hits else None


def _output_m(path: Path, c: Channel, m_per_count: float | None) -> np.ndarray:
    u = c.unit.strip().lower()
    if u in _LENGTH:
        if m_per_count is not None and not np.isclose(m_per_count, _LENGTH[u], rtol=1e-9):
            raise DataError(f"{path}: channel {c.name!r} is in {c.unit}, but --m-per-count "
                            f"says {m_per_count:g} m per unit; drop --m-per-count (the "
                            "file's unit converts it) or correct it")
        return c.values * _LENGTH[u]
    if m_per_count is not None:
        return c.values * m_per_count
    if u in _COUNTS:
        return c.values * _ECP_M_PER_COUNT
    raise DataError(f"{path}: output channel {c.name!r} has the unit "
                    f"{c.unit or 'none'!r}, not a length or counts; give metres per unit "
                    "with --m-per-count (ReadOptions(m_per_count=...))")


def _input_v(c: Channel) -> np.ndarray:
    u = c.unit.strip().lower()
    return c.values * _VOLT.get(u, 1.0)


def channel_roles(path: Path, channels: list[Channel], *, columns: dict | None,
                  m_per_count: float | None, time_scale: float) -> dict:
    """Time, input and outputs of a file's channels, in s, V and m.

    Parameters
    ----------
    path : Path
        The file (for messages).
    channels : list of Channel
        In the order the outputs take without a column map (``x1`` first).
    columns : dict of str to str, optional
        Role to channel name or alias.  ``t`` may name a time channel; when the file has
        none, any name (``t=time``) selects the channels' own time axis.
    m_per_count : float, optional
        Metres per unit of the outputs, m (counts, or channels without a unit).
    time_scale : float
        Seconds per unit of a time with no unit label, s.

    Returns
    -------
    dict
        ``t`` (s), ``v`` (V, or N for a force channel), ``x1..xn`` (m), each shape (N,).

    Raises
    ------
    DataError
        No channel, a missing or ambiguous role, channels on different time axes, an
        output unit that is neither a length nor counts without ``m_per_count``.
    """
    if not channels:
        raise DataError(f"{path}: holds no channels with samples")
    times = [c for c in channels if c.kind == "time"]
    if columns is not None:
        picked = {}
        for role, source in columns.items():
            c = _find(path, channels, source, role)
            if c is None and not (role == "t" and not times):
                raise DataError(f"{path}: channel {source!r} (for {role}) not found; "
                                + _hint(channels))
            picked[role] = c
        time_ch = picked.get("t")
        v_ch = picked["v"]
        xs = [picked[f"x{i}"] for i in range(1, len(picked) - 1)]
    else:
        data = [c for c in channels if c.kind != "time"]
        inputs = [c for c in data if c.kind == "volt"] or [c for c in data
                                                            if c.kind == "force"]
        if len(inputs) != 1:
            what = "no voltage or force channel" if not inputs else (
                f"{len(inputs)} input channels ({_names(inputs)})")
            raise DataError(f"{path}: {what} to take as the input; " + _hint(channels))
        v_ch = inputs[0]
        xs = [c for c in data if c.kind in ("length", "counts")]
        if not xs:
            raise DataError(f"{path}: no displacement channel (a length unit such as m or "
                            "mm, or counts); " + _hint(channels))
        if len(times) > 1:
            raise DataError(f"{path}: {len(times)} time channels ({_names(times)}); "
                            + _hint(channels))
        time_ch = times[0] if times else None
    used = [v_ch, *xs]
    n = {c.name: c.values.size for c in used}
    if len(set(n.values())) != 1:
        raise DataError(f"{path}: channels of unequal lengths {n}; map channels of one "
                        "recording with --columns")
    if time_ch is not None:
        u = time_ch.unit.strip().lower()
        t = time_ch.values * (_TIME[u] if u in _TIME else time_scale)
        if t.size != v_ch.values.size:
            raise DataError(f"{path}: time channel {time_ch.name!r} has {t.size} samples, "
                            f"the channels {v_ch.values.size}")
    else:
        axes = [c for c in used if c.t_s is not None]
        if len(axes) != len(used):
            bare = [c.name for c in used if c.t_s is None]
            raise DataError(f"{path}: channel(s) {bare} have no time axis and the file no "
                            "time channel; " + _hint(channels))
        t = axes[0].t_s * time_scale
        for c in axes[1:]:
            if not np.allclose(c.t_s * time_scale, t, rtol=1e-9, atol=1e-12):
                raise DataError(f"{path}: channels {axes[0].name!r} and {c.name!r} are "
                                "sampled at different times (start or step); map channels "
                                "of one recording with --columns")
    roles = {"t": t, "v": _input_v(v_ch)}
    roles.update({f"x{i + 1}": _output_m(path, c, m_per_count) for i, c in enumerate(xs)})
    return roles


#: Instrument formats (file suffixes) read as named channels.
FORMATS = ("uff", "unv", "tdms")
