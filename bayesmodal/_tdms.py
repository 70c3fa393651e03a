"""NI TDMS files (LabVIEW, NI DAQ), read with ``npTDMS``.

A TDMS file holds groups of channels; a channel's properties carry its unit
(``unit_string``) and, for a waveform, its time axis (``wf_start_offset`` and
``wf_increment``, s).  A channel named ``t`` or ``Time``, or in s, is a time channel
instead.  Channels are named as in the file, or ``GROUP/CHANNEL`` (needed when two groups
hold channels of one name).  Without a column map the file's channels must be in one
group: the input is its one voltage (else force) channel, the outputs its length or
counts channels in the order they were written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._channels import Channel, channel_roles, require
from ._errors import DataError

#: The first bytes of a TDMS segment ("TDSm") and of an index file ("TDSh").
_LEAD_IN = (b"TDSm", b"TDSh")


def read_channels(path: Path) -> tuple[list[Channel], list[str]]:
    """The channels of a TDMS file and the groups that hold them.

    Returns
    -------
    channels : list of Channel
    groups : list of str
        Groups with at least one channel with samples.

    Raises
    ------
    DataError
        npTDMS missing, not a TDMS file, a file npTDMS cannot read.
    """
    nptdms = require("nptdms", "tdms", path)
    with open(path, "rb") as fh:
        if fh.read(4) not in _LEAD_IN:
            raise DataError(f"{path}: not a TDMS file (no TDSm lead-in)")
    try:
        f = nptdms.TdmsFile.read(path)
    except Exception as exc:  # npTDMS raises several types for malformed files
        raise DataError(f"{path}: not a readable TDMS file ({str(exc).splitlines()[0]})"
                        ) from exc
    channels, groups = [], []
    for g in f.groups():
        for ch in g.channels():
            data = np.asarray(ch[:])
            if data.size == 0 or data.dtype.kind not in "fiu":
                continue
            props = ch.properties
            t_s = None
            if "wf_increment" in props:
                t_s = (float(props.get("wf_start_offset", 0.0))
                       + np.arange(data.size) * float(props["wf_increment"]))
            unit = str(props.get("unit_string", "") or "")
            channels.append(Channel(ch.name, data.astype(float), unit, t_s,
                                    (f"{g.name}/{ch.name}",)))
            if g.name not in groups:
                groups.append(g.name)
    return channels, groups


def read_roles(path: Path, columns: dict | None, m_per_count: float | None,
               time_scale: float) -> dict:
    """``t`` (s), ``v`` (V) and ``x1..xn`` (m) of a TDMS file (``_channels.channel_roles``)."""
    channels, groups = read_channels(path)
    if columns is None and len(groups) > 1:
        raise DataError(f"{path}: channels in {len(groups)} groups {groups}; name them as "
                        "GROUP/CHANNEL with --columns t=time,v=GROUP/NAME,x1=GROUP/NAME,...")
    return channel_roles(path, channels, columns=columns, m_per_count=m_per_count,
                         time_scale=time_scale)
