"""``bayesmodal diagnose``: what the linear simulation gets wrong, its cause and the gain."""

from __future__ import annotations

from pathlib import Path

from ._common import add_data_args, add_rig_argument, load_args, load_rig, print_json


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="diagnose the linear model's misfit and name the cause")
    add_data_args(p, many=True)
    add_rig_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", help="write the diagnostics' plots to DIR")
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
    p.add_argument("--train", type=int, default=0, metavar="K",
                   help="index of the training experiment among DATA (default %(default)s)")
    p.set_defaults(func=run)


def _report(d) -> str:
    lines = [f"discrepancy: {'yes' if d.discrepancy else 'no'} "
             f"(T = {d.statistic:.1f}, threshold {d.threshold:.1f}, p = {d.p_value:.3f})",
             f"cause: {d.cause}" + (f" at {d.location_label}" if d.location_label else "")]
    for name, iv in d.parameters.items():
        lines.append(f"  {name} = {iv.median:.4g}  [{iv.lo:.4g}, {iv.hi:.4g}] "
                     f"({d.interval_method})")
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
    for t in d.tests:
        mark = "!" if t.exceeded else " "
        lines.append(f" {mark} {t.name:22s} z = {t.z:7.1f}  {t.summary}")
    lines.append("ranking:")
    for c in d.ranking:
        lines.append(f"   {c.name:18s} score {c.score:10.1f}  {c.message}")
    lines.extend(f"note: {n}" for n in d.notes)
    return "\n".join(lines)


def run(args) -> int:
    from ..diagnose import diagnose

    exps = load_args(args)
    d = diagnose(exps, rig=load_rig(args), train=args.train, n_null=args.null,
                 posterior=not args.no_posterior,
                 rng=args.seed, posterior_options={"n_steps": args.steps},
                 n_starts=args.starts)
    if args.plots:
        from ..diagnose.plots import write_plots

        write_plots(d, exps, Path(args.plots))
    if args.json:
        print_json(d.as_dict())
    else:
        print(_report(d))
    return 0
