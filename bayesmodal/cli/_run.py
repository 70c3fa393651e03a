"""``bayesmodal run``: one posterior run from a TOML configuration into its own folder."""

from __future__ import annotations

import sys
from dataclasses import replace

from .._errors import ConfigError
from .._format import sig
from ..inference.threads import resolve_threads
from ..runs import default_out_dir, execute_run, prepare_run
from ..runs.config import load_config
from ..runs.identify import identify, spec_from_config
from ..runs.runner import one_line
from ._identify import print_story


def register(sub) -> None:
    p = sub.add_parser(
        "run",
        help="one posterior run from a configuration file",
        description="Check CONFIG against its data, then sample the posterior into its own "
                    "folder (default runs/<outputs.dir or config name>/): chain.h5 checkpoint, "
                    "posterior.nc, summary.json, plots, run.log, status.json and report.html. "
                    "A finished run is never overwritten without --force; an interrupted "
                    "one continues with --resume.",
    )
    p.add_argument("config", metavar="CONFIG", help="TOML run configuration")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="run folder (default: OUT_ROOT/<outputs.dir or config name>)")
    p.add_argument("--out-root", default="runs", metavar="DIR",
                   help="folder holding run folders when --out is not given (default runs)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true",
                   help="continue an interrupted run from its checkpoint")
    g.add_argument("--force", action="store_true",
                   help="delete the run files in the folder and start over")
    p.add_argument("--threads", default=None, metavar="N|auto",
                   help="threads evaluating each half-ensemble (auto: one per core); the "
                   "same chain, faster for an extended model (default: [sampler] threads "
                   "of CONFIG, 1 if not given)")
    p.add_argument("--quiet", action="store_true", help="no progress bars, no text output")
    p.set_defaults(func=run)


def _identify(cfg, args) -> int:
    out = args.out or default_out_dir(cfg, args.out_root)
    res = identify(spec_from_config(cfg), out, force=args.force, progress=not args.quiet)
    if not args.quiet:
        print_story(res)
    return 0


def run(args) -> int:
    try:
        cfg = load_config(args.config)
        if args.threads is not None:
            cfg = replace(cfg, sampler=replace(cfg.sampler,
                                               threads=resolve_threads(args.threads)))
        if cfg.identify is not None:  # [identify] enabled: the whole workflow
            return _identify(cfg, args)
        prep = prepare_run(cfg)
    except ConfigError as exc:
        raise ConfigError(one_line(exc)) from exc
    out = args.out or default_out_dir(cfg, args.out_root)
    res = execute_run(prep, out, resume=args.resume, force=args.force,
                      progress=not args.quiet)
    if not args.quiet:
        s = res.summary
        if res.action == "none":
            print(f"{res.out_dir}: already finished, nothing to do")
        print(f"{cfg.name}: {s['convergence']['verdict']}")
        for key, label in (("omega_rad_s", "omega (rad/s)"), ("zeta", "zeta")):
            d = s[key]
            cells = ", ".join(f"{sig(m)} [{sig(lo)}, {sig(hi)}]"
                              for m, lo, hi in zip(d["median"], d["lo"], d["hi"], strict=True))
            print(f"  {label}: {cells}")
        report = res.out_dir / "report.html"
        if report.is_file():
            print(f"report: {report.resolve().as_uri()}")
        sys.stdout.flush()
    return 0
