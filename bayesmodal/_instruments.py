"""Instrument files (UFF/UNV dataset 58, TDMS): which reader reads a file's channels.

The readers (``_uff``, ``_tdms``) share the channel helpers of ``_channels``; this module
dispatches to them, so that ``_channels`` imports neither.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from . import _tdms, _uff
from ._channels import FORMATS

__all__ = ["FORMATS", "read_roles"]


def read_roles(path: Path, kind: str, opts):
    """Roles in SI units of a UFF/UNV or TDMS file, and the options left to apply.

    Parameters
    ----------
    path : Path
    kind : {"uff", "unv", "tdms"}
    opts : ReadOptions

    Returns
    -------
    roles : dict
        ``t`` (s), ``v`` (V before ``input_scale``), ``x1..xn`` (m).
    opts : ReadOptions
        ``opts`` with the output and time scales already applied (``m_per_count`` None,
        ``time_scale`` 1), for ``bayesmodal.data``'s assembly of the record.
    """
    reader = _tdms if kind == "tdms" else _uff
    roles = reader.read_roles(path, opts.column_map, opts.m_per_count, opts.time_scale)
    return roles, replace(opts, m_per_count=None, time_scale=1.0)
