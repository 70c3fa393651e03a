"""Helpers shared by sub-commands: loading data arguments, printing JSON."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..data import ECP_M_PER_COUNT, Experiment, check_identifiable, load_experiment


def add_data_args(p, *, many: bool = False) -> None:
    """Add the positional DATA argument(s) and ``--m-per-count``."""
    if many:
        p.add_argument("data", nargs="+", metavar="DATA",
                       help="data files (.mat/.txt ECP in counts, .csv t,v,x1..xn in SI)")
    else:
        p.add_argument("data", metavar="DATA",
                       help="data file (.mat/.txt ECP in counts, .csv t,v,x1..xn in SI)")
    p.add_argument("--m-per-count", type=float, default=ECP_M_PER_COUNT,
                   help="metres per encoder count for ECP files (default %(default).6g)")


def load_args(args) -> list[Experiment]:
    paths = args.data if isinstance(args.data, list) else [args.data]
    exps = [load_experiment(Path(p), m_per_count=args.m_per_count) for p in paths]
    for e in exps:  # before any output folder is made
        check_identifiable(e)
    return exps


def to_jsonable(obj):
    """Convert numpy containers to plain JSON types (NaN becomes null)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if np.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def print_json(obj) -> None:
    json.dump(to_jsonable(obj), sys.stdout, indent=2)
    sys.stdout.write("\n")
