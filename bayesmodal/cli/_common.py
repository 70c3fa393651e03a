"""Helpers shared by sub-commands: loading data and rig arguments, printing JSON."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .._errors import DataError
from .._json import to_jsonable
from .._window import motion_at_start, offset_at_rest
from ..data import (
    ECP_M_PER_COUNT,
    Experiment,
    check_identifiable,
    load_experiment,
    options_for_rig,
)
from ..model.rigs import PRESETS
from ..model.rigs import load_rig as _load
from ..model.system import Rig
from ..reading import REST_OFFSETS, TIME_BASES, ReadOptions, parse_columns, parse_scale


def add_data_args(p, *, many: bool = False) -> None:
    """Add the positional DATA argument(s) and the reader options."""
    if many:
        p.add_argument("data", nargs="+", metavar="DATA",
                       help="data files (.mat/.txt ECP in counts, .csv t,v,x1..xn in SI, "
                       ".uff/.unv dataset 58 or .tdms channels with units)")
    else:
        p.add_argument("data", metavar="DATA",
                       help="data file (.mat/.txt ECP in counts, .csv t,v,x1..xn in SI, "
                       ".uff/.unv dataset 58 or .tdms channels with units)")
    add_reader_arguments(p)


def add_reader_arguments(p) -> None:
    """Add ``--columns``, ``--input-scale``, ``--time-scale``, ``--m-per-count``,
    ``--time-base``, ``--t-start``, ``--t-end``, ``--release`` and ``--rest-offset``."""
    g = p.add_argument_group("reading lab files (see bayesmodal.data.ReadOptions)")
    g.add_argument("--columns", default=None, metavar="ROLE=COLUMN,...",
                   help="which column is time, input and outputs, e.g. "
                        "t=time,v=target_v,x1=enc1,x2=enc2 (MATLAB variables or struct "
                        "fields run.enc1, text header names, or 1-based column numbers); "
                        "default: the file's t, x1..xn, v")
    g.add_argument("--input-scale", default=None, metavar="V_PER_UNIT",
                   help="volts per unit of the input column, a number or fraction, e.g. "
                        "5/4096 for a 12-bit converter over 5 V, -1 for a reversed drive "
                        "(+V moves the carts to negative counts) (default 1)")
    g.add_argument("--time-scale", default=None, metavar="S_PER_UNIT",
                   help="seconds per unit of the time column, e.g. 1/1000 for ms (default 1)")
    g.add_argument("--m-per-count", default=None, metavar="M_PER_UNIT",
                   help="metres per unit of the output columns, a number or fraction, "
                        "negative for encoders counting the other way "
                        f"(default {ECP_M_PER_COUNT:.6g} for ECP .mat/.txt in counts, 1 for "
                        ".csv in metres)")
    g.add_argument("--time-base", choices=TIME_BASES, default="auto",
                   help="auto: rounded stamps go on their uniform grid, jittered stamps are "
                        "kept as recorded (the linear fit simulates on them, step by step); "
                        "stamps: keep the recorded stamps; grid: put the stamps on their "
                        "least-squares uniform grid (analyses that need one)")
    g.add_argument("--t-start", default=None, type=float, metavar="S",
                   help="keep the record from this time on, s of the record's own clock "
                        "(times stay as recorded; a window that does not start at rest "
                        "needs --initial-state estimate) (default: the first sample)")
    g.add_argument("--t-end", default=None, type=float, metavar="S",
                   help="keep the record up to this time, s (default: the last sample)")
    g.add_argument("--release", choices=["auto"], default=None,
                   help="auto: a cart held displaced by hand, then released; cut the record "
                        "at the release (the last sample before it moves) and estimate the "
                        "initial state (default: no cut)")
    g.add_argument("--rest-offset", choices=REST_OFFSETS, default=None,
                   help="initial: subtract each output's mean before the first input (an "
                        "encoder not zeroed at rest); final: subtract each output's mean "
                        "over the record's last 10 %%, where dry friction left the carts at "
                        "rest (default none)")


def reader_options(args) -> ReadOptions:
    """The ReadOptions of the parsed reader arguments (one place parses them)."""
    columns = getattr(args, "columns", None)
    scales = {}
    for opt, key in (("input_scale", "input_scale"), ("time_scale", "time_scale"),
                     ("m_per_count", "m_per_count")):
        text = getattr(args, opt, None)
        if text is not None:  # a sign flip of the input or the encoders is allowed
            scales[key] = parse_scale(text, "--" + opt.replace("_", "-"),
                                      signed=key != "time_scale")
    window = {k: getattr(args, k) for k in ("t_start", "t_end", "release", "rest_offset")
              if getattr(args, k, None) is not None}
    return ReadOptions(columns=parse_columns(columns) if columns else None,
                       time_base=getattr(args, "time_base", None) or "auto", **scales,
                       **window)


def load_data(paths, args) -> list[Experiment]:
    """Load data files with the reader options of ``args``."""
    opts = reader_options(args)
    return [load_experiment(Path(p), options=opts) for p in paths]


def add_rig_argument(p) -> None:
    """Add ``--rig FILE``: a TOML rig description or a preset name (docs/rigs.md)."""

    p.add_argument("--rig", metavar="FILE", default=None,
                   help="rig description: a TOML file or a preset (" + ", ".join(PRESETS)
                   + "); default the ECP 210 three-cart rig (see docs/rigs.md)")


def load_rig(args) -> Rig:
    """The rig of ``--rig`` (``Rig()`` when the option is absent or not given)."""

    source = getattr(args, "rig", None)
    return Rig() if source is None else _load(source)


def damping_of(args, rig: Rig) -> str:
    """``--damping`` if given, else the damping the rig declares (``[dampers] proportional``),
    else ``"free"``.  A ``--damping`` that contradicts the rig is refused by
    ``LinearModel``."""
    d = getattr(args, "damping", None)
    return d if d is not None else (rig.damping or "free")


def load_args(args) -> list[Experiment]:
    paths = args.data if isinstance(args.data, list) else [args.data]
    rig = load_rig(args) if getattr(args, "rig", None) else None
    opts = reader_options(args)
    if opts.release is not None and hasattr(args, "initial_state"):
        args.initial_state = "estimate"  # a released cart starts displaced, not at rest
    exps = []
    for p in paths:
        o = opts
        if (rig is not None and getattr(args, "m_per_count", None) is None
                and Path(p).suffix.lower() in (".mat", ".txt")):
            # encoder files in counts: the rig's sensor scale unless --m-per-count says so
            scales = {s.m_per_unit for s in rig.sensors if s.unit == "count"}
            if len(scales) == 1 and all(s.kind == "position" and s.sign > 0
                                        for s in rig.sensors):
                from dataclasses import replace

                o = replace(opts, m_per_count=scales.pop())
        if rig is not None:
            o = options_for_rig(o, rig, p)
        exps.append(load_experiment(Path(p), options=o))
    for e in exps:  # before any output folder is made
        if rig is not None and e.n_outputs != rig.n_outputs:
            raise DataError(f"{e.source or e.name}: {e.n_outputs} outputs but the rig "
                            f"{args.rig!r} has {rig.n_outputs} sensors; give one column "
                            "per sensor, in the rig's sensor order")
        if getattr(args, "initial_state", "rest") == "rest":
            if opts.t_start is not None:  # the fit starts the window from rest
                _check_rest(e, opts, hasattr(args, "initial_state"))
            if opts.rest_offset == "none":
                _check_offset(e)
            check_identifiable(e)  # (a free decay has no input: checked by the fit)
    return exps


def _check_rest(e: Experiment, opts: ReadOptions, can_estimate: bool) -> None:
    """Refuse a window that does not start at rest for a fit that assumes it does."""

    why = motion_at_start(e.y_m, e.v_volt, e.dt)
    if why:
        fix = "fit it with --initial-state estimate, or " if can_estimate else ""
        raise DataError(f"{e.source or e.name}: the window starts at t = {e.t_s[0]:g} s "
                        f"with {why}, not at rest; {fix}start the window where the carts "
                        "rest at 0 with no input")


def _check_offset(e: Experiment) -> None:
    """Refuse a record whose outputs rest away from 0 before its input."""

    why = offset_at_rest(e.y_m, e.v_volt)
    if why:
        raise DataError(f"{e.source or e.name}: before the first input the carts rest with "
                        f"{why}, not at 0 where the model starts; an encoder not zeroed at "
                        "rest: remove each output's rest level with --rest-offset initial")


def print_json(obj) -> None:
    json.dump(to_jsonable(obj), sys.stdout, indent=2)
    sys.stdout.write("\n")


def add_initial_state_argument(p) -> None:
    """Add ``--initial-state {rest,estimate}`` (``estimate`` for free decays)."""
    p.add_argument("--initial-state", choices=["rest", "estimate"], default="rest",
                   help="rest: records start at rest; estimate: fit each record's initial "
                   "positions and velocities (free decays with no input)")
