"""``bayesmodal lsq``: output-error least-squares fit and modal summary."""

from __future__ import annotations

from ..fit import fit_lsq
from ..system import LinearModel, Rig
from ._common import add_data_args, load_args, print_json


def register(sub) -> None:
    p = sub.add_parser(
        "lsq",
        help="least-squares fit of the linear model",
        description="Output-error least-squares fit of the linear rig model (motor volts to "
        "cart positions) to DATA, with standard errors, fit percent per cart and the "
        "modal summary (natural frequencies, damping ratios, mode shapes) of the fit "
        "(report Tables 3-6).",
    )
    add_data_args(p, many=True)
    p.add_argument("--damping", choices=["free", "proportional"], default="free",
                   help="damping model: free (c1, c2, c3, c12, c23 each fitted) or "
                   "proportional (C = ca M + cb K)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=run)


def lsq_summary(res) -> dict:
    """JSON-ready summary of an LSQResult with its modal quantities."""
    out = {
        "damping": res.model.damping,
        "parameters": res.params,
        "stderr": dict(zip(res.model.names, res.stderr.tolist(), strict=True)),
        "fit_percent": res.fit_percent[0].tolist() if len(res.fit_percent) == 1
        else res.fit_percent.tolist(),
        "sigma_m": res.sigma_m.tolist(),
        "success": res.success,
    }
    try:
        from ..modal import modal_summary
    except ImportError:  # modal module not built yet
        return out
    out.update(modal_summary(res.model, res.theta))
    return out


def run(args) -> int:
    exps = load_args(args)
    model = LinearModel(Rig(), args.damping)
    res = fit_lsq(exps, model)
    summary = lsq_summary(res)
    if args.json:
        print_json(summary)
    else:
        print(f"damping: {summary['damping']}")
        for k, v in summary["parameters"].items():
            print(f"  {k:>4s} = {v:.6g} +- {summary['stderr'][k]:.2g}")
        print("fit percent:", summary["fit_percent"])
        for key in ("omega_rad_s", "zeta"):
            if key in summary:
                print(f"{key}:", [round(x, 5) for x in summary[key]])
    return 0
