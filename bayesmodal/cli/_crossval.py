"""``bayesmodal crossval``: leave-one-record-out validation of a model on several records."""

from __future__ import annotations

import sys
from pathlib import Path

from .._errors import ConfigError
from ..inference.crossval import CrossvalSpec, crossval
from ..inference.noise_spec import accepted_noise
from ..inference.record_layout import parse_layout
from ..inference.record_scale import NOISE_SCALES
from ..inference.temperature import calibrate_loro
from ..model.system import Rig
from ..runs.config import load_config
from ..runs.crossval import write_crossval
from ._common import (
    add_data_args,
    add_rig_argument,
    damping_of,
    load_args,
    load_rig,
    print_json,
)


def register(sub) -> None:
    p = sub.add_parser(
        "crossval",
        help="leave-one-record-out validation: sample on the others, predict each record",
        description="For each record, sample the posterior on the other records (shared "
                    "physics, per-record gain and offset from a population by default) and "
                    "predict it: fit percent of the predictive median, coverage of the 50 % "
                    "and 90 % bands, band width / record sd, CRPS and log predictive "
                    "density, and the summed lpd with its standard error over records.  "
                    "Writes crossval.json, crossval.txt, heldout_<record>.png and forest.png "
                    "into --out.",
    )
    add_data_args(p, many=True)
    add_rig_argument(p)
    p.add_argument("--config", default=None, metavar="FILE",
                   help="run configuration (TOML) whose [model], [likelihood], [records] and "
                        "[sampler] settings are used (default: the options below)")
    p.add_argument("--damping", choices=["free", "proportional"], default=None,
                   help="damping model (default: the rig's [dampers] proportional "
                        "declaration, else free)")
    p.add_argument("--noise", default="ar1", metavar="MODEL",
                   help=f"residual model: {accepted_noise()}; ar:auto chooses on each "
                   "fold's training records (default ar1)")
    p.add_argument("--per-record", default="g_v=hierarchical,v0=shared",
                   metavar="NAME=KIND,...",
                   help="per-record parameters, KIND independent, hierarchical or shared (v0), "
                        "or 'none' (default %(default)s)")
    p.add_argument("--noise-scale", choices=NOISE_SCALES, default="none",
                   help="response: each record's noise level times the relative size of "
                   "the model's response to its input; power: times that size to a sampled "
                   "power in [0, 1] (default none: one level in m)")
    p.add_argument("--walkers", type=int, default=48, help="ensemble size (default 48)")
    p.add_argument("--steps", type=int, default=4000, help="steps per walker (default 4000)")
    p.add_argument("--draws", type=int, default=200,
                   help="posterior draws per held-out prediction (default 200)")
    p.add_argument("--temperature", default="1.0", metavar="T|loro",
                   help="likelihood temperature T of the generalised posterior, or 'loro': "
                        "calibrate it so that the held-out 90 %% bands reach nominal coverage "
                        "(one study per --temperatures value; docs/uncertainty.md) "
                        "(default %(default)s)")
    p.add_argument("--temperatures", default="1,10,100,1000", metavar="T1,T2,...",
                   help="grid of the 'loro' calibration (default %(default)s)")
    p.add_argument("--criterion", choices=["mean", "worst"], default="mean",
                   help="'loro' calibration: mean coverage over held-out records, or the "
                        "worst record's (default %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes (default: the number of CPUs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address; the folds run as its tasks (default: local)")
    p.add_argument("--out", default="runs/crossval", metavar="DIR",
                   help="output folder (default runs/crossval)")
    p.add_argument("--no-joint", dest="joint", action="store_false",
                   help="skip the run on all records together (the forest plot then has no "
                        "joint interval); saves one posterior run of all records")
    p.add_argument("--json", action="store_true", help="print crossval.json to stdout")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def spec_from_args(args):
    """The ``CrossvalSpec`` of the command line (or of ``--config``)."""

    if args.config:
        cfg = load_config(args.config, check_files=False)
        if cfg.likelihood.temperature == "loro":  # [likelihood] temperature = "loro": calibrate
            args.temperature = "loro"
        return cfg.crossval_spec()
    rig = load_rig(args) if getattr(args, "rig", None) else None
    return CrossvalSpec(damping=damping_of(args, rig or Rig()), noise=args.noise, rig=rig,
                        layout=parse_layout(args.per_record,
                                            noise_scale=args.noise_scale), n_walkers=args.walkers,
                        n_steps=args.steps, n_predictive=args.draws, seed=args.seed,
                        temperature=1.0 if _calibrating(args) else _number(
                            args.temperature, "--temperature"))


def _calibrating(args) -> bool:
    return str(getattr(args, "temperature", "1")).strip().lower() == "loro"


def _number(text: str, flag: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{flag} {text!r}: give a number (e.g. 10) or 'loro'") from None


def run(args) -> int:
    exps = load_args(args)
    spec = spec_from_args(args)
    say = None if args.quiet else (lambda line: print(f"bayesmodal crossval: {line}",
                                                      file=sys.stderr, flush=True))
    if say:
        say(f"{len(exps)} folds{' + the joint run' if args.joint else ''}, "
            f"{spec.n_walkers} walkers x {spec.n_steps} steps each")
    cal = None
    if _calibrating(args):
        grid = [_number(t, "--temperatures") for t in args.temperatures.split(",")]
        cal, res = calibrate_loro(exps, spec, temperatures=grid, criterion=args.criterion,
                                  workers=args.workers, scheduler=args.scheduler,
                                  progress=say, joint=args.joint)
    else:
        res = crossval(exps, spec, workers=args.workers, scheduler=args.scheduler,
                       progress=say, joint=args.joint)
    path = write_crossval(res, Path(args.out), calibration=cal)
    if args.json:
        print_json({**res.to_dict(), **({} if cal is None else
                                        {"temperature_calibration": cal.to_dict()})})
    elif not args.quiet:
        if cal is not None:
            print(cal.table())
        print(res.table())
        print(f"-> {path}")
    return 0
