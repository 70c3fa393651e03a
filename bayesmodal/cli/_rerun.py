"""``bayesmodal rerun``: re-run a recorded run and check that it reproduces its results."""

from __future__ import annotations

import sys

from ..runs.rerun import rerun_run
from ._common import print_json


def register(sub) -> None:
    p = sub.add_parser(
        "rerun",
        help="re-run a recorded run and compare its summary.json",
        description="Read RUN_DIR's recorded configuration (config.json, checked against "
                    "the configuration hash in summary.json), check the SHA-256 of every "
                    "data file, sample it again into --out (default RUN_DIR-rerun) and "
                    "compare summary.json byte for byte.  Exit code 0 when identical, 1 "
                    "when not (the differing keys and any changed package versions are "
                    "listed).",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="a finished run folder")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder of the new run (default RUN_DIR-rerun)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args) -> int:
    res = rerun_run(args.run_dir, args.out, progress=not args.quiet)
    if args.json:
        print_json(res.as_dict())
    else:
        if res.identical:
            print(f"{res.rerun_dir}: summary.json reproduced byte for byte")
        else:
            print(f"{res.rerun_dir}: summary.json differs from {res.run_dir}:")
            for d in res.differences:
                print(f"  {d}")
        for name, (then, now) in res.version_changes.items():
            print(f"  version of {name}: recorded {then}, installed {now}")
        sys.stdout.flush()
    return 0 if res.identical else 1
