"""``bayesmodal diagnose``: what the linear simulation gets wrong, its cause and the gain."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .._format import sig
from ..discrepancy.diagnosis import DEFAULT_CANDIDATES, DiagnoseSpec, diagnose
from ..model.effects import EXTENSIONS
from ..plots.diagnosis import write_plots
from ..segments import split_records
from ._common import add_data_args, add_rig_argument, load_args, load_rig, print_json


def _indices(text: str) -> list[int]:
    """``--train`` or ``--split-at-rest`` indices, ``"0"`` or ``"0,1"`` (one argument, so
    DATA may follow it)."""
    try:
        return [int(s) for s in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"takes record indices such as 0 or 0,1, got {text!r}") from None


def _candidates(text: str) -> list[str]:
    """``--candidates``: names, or ``+name,...`` to add to the default candidates."""

    extra = text.startswith("+")
    names = [s.strip() for s in text.lstrip("+").split(",") if s.strip()]
    unknown = [c for c in names if c not in EXTENSIONS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"takes catalogue names such as coulomb_friction,input_offset or +end_stop "
            f"(added to the default ones), got {text!r}; known: {sorted(EXTENSIONS)}")
    return list(DEFAULT_CANDIDATES) + [c for c in names if c not in DEFAULT_CANDIDATES] \
        if extra else names


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="diagnose the linear model's misfit and name the cause",
        description="Fit the linear model to the training experiment, test its residuals "
        "against simulated null data sets, fit the catalogued model extensions (friction, "
        "backlash, cubic springs, input effects) and report the cause, its parameters "
        "with intervals, and the gain in fit on training and held-out DATA.  Takes "
        "minutes; progress goes to stderr.",
    )
    add_data_args(p, many=True)
    add_rig_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR",
                   help="write the diagnostics' plots to DIR (default: no plots)")
    p.add_argument("--seed", type=int, default=0, help="seed of the null simulations and "
                   "the sampler (default %(default)s)")
    p.add_argument("--no-posterior", action="store_true",
                   help="skip the emcee step (least-squares estimates, Laplace intervals)")
    p.add_argument("--null", type=int, default=40, metavar="N",
                   help="null data sets of the calibration (default %(default)s)")
    p.add_argument("--steps", type=int, default=1500, metavar="N",
                   help="emcee steps per walker of the posterior step (default %(default)s)")
    p.add_argument("--starts", type=int, default=3, metavar="N",
                   help="least-squares fits per candidate extension, from the N best points "
                   "of its start grid; the cheapest wins (default %(default)s)")
    p.add_argument("--train", type=_indices, default=[0], metavar="K[,K...]",
                   help="index (or comma-separated indices) of the training experiments "
                   "among DATA; with two or more, each forward step is judged by its "
                   "leave-one-record-out gain (default %(default)s: the first)")
    p.add_argument("--split-at-rest", type=_indices, default=None, metavar="K[,K...]",
                   help="cut these records of DATA where the drive starts again after a "
                   "rest of 1 s (no drive, carts still), each part a record (of the "
                   "training set if its record is): lets the parts of one record predict "
                   "each other, e.g. an effect only its large pulses reach "
                   "(bayesmodal.segments; default: no record is cut)")
    p.add_argument("--max-effects", type=int, default=3, metavar="N",
                   help="largest number of effects forward selection puts in the model; 1 "
                   "stops after the first cause (default %(default)s)")
    p.add_argument("--candidates", type=_candidates, default=None, metavar="NAME,...",
                   help="the effects tried as causes: catalogue names, or +NAME,... to add "
                   "to the default ones (e.g. +end_stop); default: "
                   "discrepancy.diagnosis.DEFAULT_CANDIDATES")
    p.add_argument("--local-search", action="store_true",
                   help="forward selection fits stick-slip models from local starts only "
                   "(faster; by default also by differential evolution, whose fit the "
                   "local starts miss on friction behind an input effect)")
    p.add_argument("--weights", choices=("none", "spread"), default="none",
                   help="how the least-squares fits weigh several training records: "
                   "'none' sums their squared residuals (the largest record dominates), "
                   "'spread' weighs each record as much as the others (default: %(default)s)")
    p.add_argument("--threads", default="auto", metavar="N|auto",
                   help="threads for the fits that do not depend on one another (starts, "
                   "generations of the global search, held-out folds); the same diagnosis "
                   "on any count (default: %(default)s, one per core)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def _report(d) -> str:
    lines = [f"discrepancy: {'yes' if d.discrepancy else 'no'} "
             f"(T = {d.statistic:.1f}, threshold {d.threshold:.1f}, p = {d.p_value:.3f})",
             f"cause: {d.cause}" + (f" at {d.location_label}" if d.location_label else "")]
    for k, c in enumerate(d.causes, 1):
        ins, ho = c.gain["in_sample"], c.gain.get("held_out")
        line = (f"  cause {k}: {c.cause}" + (f" at {c.location_label}" if c.location_label
                                             else "")
                + (f" (replaces {c.replaces})" if c.replaces else "")
                + f"; gain in sample {ins['delta_lpd']:.1f} nats (LR {ins['lr_statistic']:.1f},"
                f" {ins['n_params']} parameters)")
        if ho:
            line += f", held out {ho['delta_lpd']:.1f} +- {ho['se']:.1f} nats"
        lines.append(line)
        if ho and ho.get("fit_percent"):
            rows = "; ".join(", ".join(f"{x:.1f}" for x in r) for r in ho["fit_percent"])
            lines.append(f"    held-out fit percent (each record predicted from the others, "
                         f"refits started from the full fit): {rows}")
    lines.append(f"explained: {'yes' if d.explained else 'no'}")
    label = {"posterior": "90 % credible interval",
             "posterior_unconverged": "90 % interval of UNCONVERGED chains",
             "laplace": "90 % Laplace interval"}.get(d.interval_method, d.interval_method)
    if d.gain.get("model"):
        lines.append(f"final model: linear + {d.gain['model']} (the intervals, fit percents "
                     "and ELPD below are this model's)")
    for name, iv in d.parameters.items():
        lines.append(f"  {name} = {sig(iv.median)}  [{sig(iv.lo)}, {sig(iv.hi)}] ({label})")
    g = d.gain
    for key in ("fit_percent_before", "fit_percent_after", "heldout_fit_percent_before",
                "heldout_fit_percent_after"):
        if key in g:
            vals = "; ".join(", ".join(f"{x:.1f}" for x in row) for row in g[key])
            lines.append(f"{key}: {vals}")
    for key, vals in (g.get("posterior") or {}).items():
        if "fit_percent" in key and not key.endswith(("_lo", "_hi")):
            lo, hi = g["posterior"][key + "_lo"], g["posterior"][key + "_hi"]
            rows = "; ".join(", ".join(f"{m:.1f} [{a:.1f}, {b:.1f}]"
                                       for m, a, b in zip(r, ra, rb, strict=True))
                             for r, ra, rb in zip(vals, lo, hi, strict=True))
            lines.append(f"posterior {key}: {rows}")
    if g.get("delta_elpd") is not None:
        lines.append(f"delta ELPD: {g['delta_elpd']:.1f} +- {g['delta_elpd_se']:.1f}")
    lines.append("tests:")
    several = len({t.experiment for t in d.tests}) > 1
    for k, t in enumerate(d.tests):
        if several and (k == 0 or t.experiment != d.tests[k - 1].experiment):
            lines.append(f"  {t.experiment}:")  # each record's diagnostics under its name
        mark = "!" if t.exceeded else " "
        lines.append(f" {mark} {t.name:22s} z = {t.z:7.1f}  {t.summary}")
    lines.append("ranking:")
    for c in d.ranking:
        lines.append(f"   {c.name:18s} score {c.score:10.1f}  {c.message}")
    test = "" if len(d.train) < 2 else "; significant by the AR(1) or the output-error test"
    for k, st in enumerate(d.as_dict()["forward_steps"], 2):
        lines.append(f"forward step {k} after {st['model']} (T = {st['T']:.1f}, threshold "
                     f"{st['threshold']:.1f}): in-sample AR(1) gain, least-squares cost "
                     f"ratio, held-out AR(1) gain{test}")
        width = max((len(c["cause"]) for c in st["candidates"]), default=0)
        for c in st["candidates"]:
            ho = c.get("held_out")
            lines.append(f"   {'*' if c['significant'] else ' '} {c['cause']:{width}s} "
                         f"{c['delta_lpd']:10.1f} nats  cost x{c['cost_ratio']:.2f}"
                         + (f"  held out {ho['delta_lpd']:.1f} +- {ho['se']:.1f}" if ho
                            else ""))
    lines.extend(f"note: {n}" for n in d.notes)
    return "\n".join(lines)


def run(args) -> int:
    exps, train = load_args(args), args.train
    if args.split_at_rest:
        exps, train = split_records(exps, args.split_at_rest, train)
    spec = DiagnoseSpec(
        candidates=args.candidates, n_null=args.null, posterior=not args.no_posterior,
        posterior_options={"n_steps": args.steps}, n_starts=args.starts,
        max_effects=args.max_effects, global_search=not args.local_search,
        weights=None if args.weights == "none" else args.weights, threads=args.threads)
    d = diagnose(exps, spec, rig=load_rig(args), train=train, rng=args.seed,
                 progress=not args.quiet)
    if args.plots:
        write_plots(d, exps, Path(args.plots))
    if args.json:
        print_json(d.as_dict())
    else:
        print(_report(d))
    sys.stdout.flush()
    for line in caveats(d):
        print(f"bayesmodal diagnose: warning: {line}", file=sys.stderr)
    return 0


def caveats(d) -> list[str]:
    """One-line warnings about what the diagnosis does not settle (empty when all is well)."""
    out = []
    if d.discrepancy and not d.explained:
        rest = sorted({t.name for t in d.tests_after if t.exceeded})
        if d.cause != "none" and rest:
            out.append(f"{d.cause} explains part of the misfit; still beyond threshold: "
                       f"{', '.join(rest)} (explained: false; see the notes)")
        else:
            out.append("discrepancy not explained by any catalogued extension "
                       "(explained: false)")
    if d.interval_method == "posterior_unconverged":
        out.append("the posterior chains did not converge: the intervals are labelled "
                   "posterior_unconverged; run longer chains with --steps N (or "
                   "--no-posterior for Laplace intervals)")
    return out
