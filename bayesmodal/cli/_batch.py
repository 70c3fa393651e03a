"""``bayesmodal batch``: many configurations in parallel, each into its own run folder."""

from __future__ import annotations

import sys

from .._errors import ConfigError
from ..runs import run_batch
from ._common import print_json


def register(sub) -> None:
    p = sub.add_parser(
        "batch",
        help="many posterior runs in parallel (local processes or a Dask cluster)",
        description="Run every CONFIG (as `bayesmodal run` would) into "
                    "OUT_ROOT/<outputs.dir or config name>/, on local processes or, with "
                    "--scheduler, as tasks of a Dask distributed cluster.  A failing run is "
                    "reported with its error and does not stop the others; a summary table "
                    "is printed and written to OUT_ROOT/batch.json.  Exit code 1 when any "
                    "run failed.",
    )
    p.add_argument("configs", nargs="+", metavar="CONFIG", help="TOML run configurations")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: CPUs, at most the number of runs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address, e.g. tcp://127.0.0.1:8786 (needs the "
                        "'dask' extra; default: local processes)")
    p.add_argument("--out-root", default="runs", metavar="DIR",
                   help="folder of the run folders (default runs)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true", help="continue interrupted runs")
    g.add_argument("--force", action="store_true", help="start every run over")
    p.add_argument("--json", action="store_true", help="print batch.json to stdout")
    p.add_argument("--quiet", action="store_true",
                   help="no progress and no table; each failed run still gets one line "
                   "on stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers} (leave it out to use "
                          "one process per CPU)")
    res = run_batch(args.configs, out_root=args.out_root, workers=args.workers,
                    scheduler=args.scheduler, resume=args.resume, force=args.force,
                    progress=not args.quiet)
    if args.json:
        print_json(res.as_dict())
    elif not args.quiet:
        print(res.table())
        sys.stdout.flush()
    if args.quiet:  # quiet drops progress, never errors
        for it in res.items:
            if it.state != "finished":
                print(f"bayesmodal batch: failed: {it.config}: {it.error}", file=sys.stderr)
    return 1 if res.n_failed else 0
