"""``bayesmodal identify``: from records to modal parameters, with the model that explains
them (bayesmodal.runs.identify)."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from .._errors import ConfigError
from ..runs.config import load_config, parse_config
from ..runs.identify import identify, spec_from_config
from ..runs.identify_summary import story


def register(sub) -> None:
    p = sub.add_parser(
        "identify",
        help="records to modal parameters: linear posterior, diagnosis, the found model's "
             "posterior, held-out checks",
        description="The whole workflow, each stage resumable in --out: the linear model's "
                    "posterior and residual checks (linear/), the diagnosis of what it gets "
                    "wrong (diagnosis.json), the joint posterior of the model with the causes "
                    "found (final/), both checked by leaving each record out in turn, and "
                    "report.html: the rig's modal parameters from the model that explains "
                    "the data, the linear model's beside them, the causes and their held-out "
                    "gains.  Takes CONFIG, a run configuration of the linear model (TOML), "
                    "or DATA files with --rig.  Rerunning continues where it stopped.",
    )
    p.add_argument("inputs", nargs="+", metavar="CONFIG|DATA",
                   help="a TOML run configuration of the linear model, or data files")
    p.add_argument("--rig", default=None, metavar="FILE",
                   help="with DATA: rig description (TOML file or preset, docs/rigs.md); "
                   "default the ECP 210 three-cart rig")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="workflow folder (default runs/<config name>_identify)")
    p.add_argument("--force", action="store_true",
                   help="start every stage over (deletes the folder's runs)")
    p.add_argument("--null", type=int, default=None, metavar="N",
                   help="null data sets of the diagnosis' calibration (default: [identify] "
                   "null of CONFIG, else 19)")
    p.add_argument("--max-effects", type=int, default=None, metavar="N",
                   help="most effects the diagnosis puts in the model (default: [identify] "
                   "max_effects of CONFIG, else 4)")
    p.add_argument("--no-split", action="store_true",
                   help="do not cut the record that moves the driven cart furthest at its "
                   "rests for the diagnosis")
    p.add_argument("--steps", type=int, default=None, metavar="N",
                   help="steps per walker of the found model's posterior (default: "
                   "[identify] steps of CONFIG, else 12000)")
    p.add_argument("--walkers", type=int, default=None, metavar="N",
                   help="walkers of the found model's posterior (default: [identify] "
                   "walkers of CONFIG, else 56)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=run)


def _config(args):
    first = Path(args.inputs[0])
    if first.suffix.lower() == ".toml":
        if len(args.inputs) > 1 or args.rig:
            raise ConfigError("identify: give one CONFIG, or DATA files (with --rig); "
                              "a configuration names its own data and rig")
        return load_config(first)
    raw = {"data": {"files": [str(Path(f).resolve()) for f in args.inputs]},
           "crossval": {"enabled": len(args.inputs) > 1}}
    if args.rig:
        rig = Path(args.rig)
        raw["rig"] = {"file": str(rig.resolve()) if rig.is_file() else args.rig}
    return parse_config(raw, source="<identify DATA>", name=Path(args.inputs[0]).stem)


def run(args) -> int:
    cfg = _config(args)
    spec = spec_from_config(cfg)  # the config's [identify] table, else the defaults
    diag, final = spec.diagnosis, spec.final
    if args.null is not None:
        diag = replace(diag, n_null=args.null)
    if args.max_effects is not None:
        diag = replace(diag, max_effects=args.max_effects)
    if args.no_split:
        diag = replace(diag, split="none")
    if args.steps is not None:
        burn = min(final.burn, args.steps // 2)
        final = replace(final, steps=args.steps, burn=burn,
                        prune=None if final.prune is None else min(final.prune, burn // 2))
    if args.walkers is not None:
        final = replace(final, walkers=args.walkers)
    spec = replace(spec, diagnosis=diag, final=final)
    out = Path(args.out) if args.out else Path("runs") / f"{cfg.name}_identify"
    res = identify(spec, out, force=args.force, progress=not args.quiet)
    if not args.quiet:
        print_story(res)
    return 0


def print_story(res) -> None:
    """The report's first screen in text: the verdict, what the records say, the link."""

    verdict, lines = story(res.summary)
    print(verdict)
    for line in lines:
        print(f"  - {line}")
    print(f"report: {(res.out_dir / 'report.html').resolve().as_uri()}")
    sys.stdout.flush()
