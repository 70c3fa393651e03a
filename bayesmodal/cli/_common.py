"""Helpers shared by sub-commands: loading data and rig arguments, printing JSON."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .._errors import DataError
from ..data import ECP_M_PER_COUNT, Experiment, check_identifiable, load_experiment
from ..system import Rig


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


def add_rig_argument(p) -> None:
    """Add ``--rig FILE``: a TOML rig description or a preset name (docs/rigs.md)."""
    from ..rigs import PRESETS

    p.add_argument("--rig", metavar="FILE", default=None,
                   help="rig description: a TOML file or a preset (" + ", ".join(PRESETS)
                   + "); default the ECP 210 three-cart rig (see docs/rigs.md)")


def load_rig(args) -> Rig:
    """The rig of ``--rig`` (``Rig()`` when the option is absent or not given)."""
    from ..rigs import load_rig as _load

    source = getattr(args, "rig", None)
    return Rig() if source is None else _load(source)


def load_args(args) -> list[Experiment]:
    paths = args.data if isinstance(args.data, list) else [args.data]
    rig = load_rig(args) if getattr(args, "rig", None) else None
    mpc = args.m_per_count
    if rig is not None and mpc == ECP_M_PER_COUNT:
        # encoder files in counts: the rig's sensor scale unless --m-per-count says otherwise
        scales = {s.m_per_unit for s in rig.sensors if s.unit == "count"}
        mpc = scales.pop() if len(scales) == 1 else mpc
    exps = [load_experiment(Path(p), m_per_count=mpc) for p in paths]
    for e in exps:  # before any output folder is made
        if rig is not None and e.n_outputs != rig.n_outputs:
            raise DataError(f"{e.source or e.name}: {e.n_outputs} outputs but the rig "
                            f"{args.rig!r} has {rig.n_outputs} sensors; give one column "
                            "per sensor, in the rig's sensor order")
        if getattr(args, "initial_state", "rest") == "rest":
            check_identifiable(e)  # (a free decay has no input: checked by the fit)
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


def add_initial_state_argument(p) -> None:
    """Add ``--initial-state {rest,estimate}`` (``estimate`` for free decays)."""
    p.add_argument("--initial-state", choices=["rest", "estimate"], default="rest",
                   help="rest: records start at rest; estimate: fit each record's initial "
                   "positions and velocities (free decays with no input)")
