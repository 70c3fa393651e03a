"""``bayesmodal static``: steady-state analysis of a step experiment (report Table 2)."""

from __future__ import annotations

from pathlib import Path

from ..plots.static import plot_steady_state
from ..static import steady_state
from ._common import add_data_args, add_rig_argument, load_args, load_rig, print_json


def register(sub) -> None:
    p = sub.add_parser(
        "static",
        help="voltage-to-force gain and spring ratios from steps",
        description="Steady-state analysis of a step experiment (report Table 2): the "
        "voltage-to-force gain g_v and the spring ratios from the settled plateaus, "
        "referenced to zero and to the previous plateau.",
    )
    add_data_args(p)
    add_rig_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", help="write the plateau-picking plot into DIR "
                   "(default: no plots)")
    p.set_defaults(func=run)


def format_static(results) -> str:
    """Plain-text table of StaticResult objects, one row per quantity and reference."""
    head = f"{'quantity':<9s}{'reference':<11s}{'estimate':>10s}{'std.err':>10s}" \
           f"{'nominal':>10s}{'error %':>9s}"
    lines = [head, "-" * len(head)]
    first = results[0]
    rows = [("g_v", lambda r: (r.g_v, r.g_v_se, r.nominal_g_v, r.g_v_error_percent))]
    for j, name in enumerate(first.ratio_names):
        rows.append((name, lambda r, j=j: (r.ratios[j], r.ratios_se[j], r.nominal_ratios[j],
                                           r.ratios_error_percent[j])))
    for name, get in rows:
        for r in results:
            est, se, nom, err = get(r)
            lines.append(f"{name:<9s}{r.reference:<11s}{est:>10.4f}{se:>10.4f}{nom:>10.4f}"
                         f"{err:>+9.1f}")
    p = first.plateaus
    lines.append(f"plateaus: {int(p.on.sum())} on, {int(p.off.sum())} rest, "
                 f"{len(p.unsettled)} unsettled; error % = 100 (estimate - nominal) / nominal")
    return "\n".join(lines)


def run(args) -> int:
    (exp,) = load_args(args)
    results = [steady_state(exp, rig=load_rig(args), reference=ref)
               for ref in ("zero", "previous")]
    if args.plots:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt


        out = Path(args.plots)
        out.mkdir(parents=True, exist_ok=True)
        ax = plot_steady_state(results[0])
        ax.figure.savefig(out / f"{exp.name}_plateaus.png", dpi=120)
        plt.close(ax.figure)
    if args.json:
        print_json({r.reference: r.as_dict() for r in results})
    else:
        print(format_static(results))
    return 0
