"""``bayesmodal lsq``: output-error least-squares fit and modal summary."""

from __future__ import annotations

from ..fit import fit_lsq
from ..system import LinearModel
from ._common import (
    add_data_args,
    add_initial_state_argument,
    add_rig_argument,
    load_args,
    load_rig,
    print_json,
)


def register(sub) -> None:
    p = sub.add_parser("lsq", help="least-squares fit of the linear model")
    add_data_args(p, many=True)
    add_rig_argument(p)
    add_initial_state_argument(p)
    p.add_argument("--damping", choices=["free", "proportional"], default="free")
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
    model = LinearModel(load_rig(args), args.damping)
    res = fit_lsq(exps, model, initial_state=args.initial_state)
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
