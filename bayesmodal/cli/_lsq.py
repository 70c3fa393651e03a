"""``bayesmodal lsq``: output-error least-squares fit and modal summary."""

from __future__ import annotations

import warnings

import numpy as np

from .._errors import IdentificationError
from .._format import estimate, param_unit, percent, values
from ..fit.lsq import fit_lsq
from ..identified import identify
from ..modal import modal_summary
from ..model.system import LinearModel
from ._common import (
    add_data_args,
    add_initial_state_argument,
    add_rig_argument,
    damping_of,
    load_args,
    load_rig,
    print_json,
)


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
    add_rig_argument(p)
    add_initial_state_argument(p)
    p.add_argument("--damping", choices=["free", "proportional"], default=None,
                   help="damping model: free (c1, c2, c3, c12, c23 each fitted) or "
                   "proportional (C = ca M + cb K)"
                   " (default: the rig's [dampers] proportional declaration, else free)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=run)


def lsq_summary(res, names=None) -> dict:
    """JSON-ready summary of an LSQResult with its modal quantities and its
    identifiability verdict (``identified``, ``reason``, ``problems``; record names
    ``names`` in the messages)."""
    out = {
        "damping": res.model.damping,
        "scale": res.model.scale,
        "tied": res.model.tied,
        "parameters": res.params,
        "stderr": dict(zip(res.model.names, res.stderr.tolist(), strict=True)),
        "fit_percent": res.fit_percent[0].tolist() if len(res.fit_percent) == 1
        else res.fit_percent.tolist(),
        "sigma_m": res.sigma_m.tolist(),
        "success": res.success,
        **identify(res, names).as_dict(),
    }
    if out["identified"]:
        out.update(modal_summary(res.model, res.theta))
        return out
    # the estimate is not an answer: its modes are printed with --json, but their
    # warnings (an overdamped mode of a switched-off model) would only hide the verdict
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out.update(modal_summary(res.model, res.theta))
    return out


def run(args) -> int:
    exps = load_args(args)
    rig = load_rig(args)
    model = LinearModel(rig, damping_of(args, rig))
    res = fit_lsq(exps, model, initial_state=args.initial_state)
    summary = lsq_summary(res, [e.name for e in exps])
    if args.json:  # the whole result, `identified` and `reason` included, in any case
        print_json(summary)
    if not summary["identified"]:
        # the estimate is not an answer: one line with the cause and the fix, exit 2
        where = ", ".join(str(e.source or e.name) for e in exps)
        raise IdentificationError(f"{where}: not identified: {summary['reason']}")
    if not args.json:
        print(format_lsq(summary, res, [e.name for e in exps]))
    return 0


def format_lsq(summary: dict, res, names: list[str]) -> str:
    """Text of ``bayesmodal lsq``: estimates with units and standard errors."""
    per_unit = summary.get("scale") == "per_unit_gain"
    lines = [f"damping: {summary['damping']}"]
    if per_unit:
        lines.append("scale: per unit of drive gain (no mass, spring or gain is known): "
                     "masses in V s^2/m, dampers in V s/m, springs in V/m; frequencies, "
                     "damping ratios and mode shapes are absolute")
    lines.append("parameters (estimate +- standard error; white-noise Gauss-Newton errors, "
                 "optimistic for correlated residuals):")
    for k, v in summary["parameters"].items():
        # every parameter is >= 0: damping coefficients may end on that bound
        lines.append(f"  {k:>4s} = " + estimate(v, summary["stderr"][k],
                                                unit=param_unit(k, per_unit), lower=0.0))
    for follower, head in summary.get("tied", {}).items():
        lines.append(f"  {follower:>4s} = {head} (tied in the rig description)")
    for name, row in zip(names, np.atleast_2d(res.fit_percent), strict=True):
        lines.append(f"fit percent, {name}: {percent(row)} (carts 1..{len(row)})")
    kinds = res.model.rig.output_kinds
    if all(k == "position" for k in kinds):
        lines.append("RMS residual: "
                     + values(1e3 * np.asarray(res.sigma_m), unit='mm', digits=3))
    else:  # each sensor in its own SI unit
        units = {"position": "m", "velocity": "m/s", "acceleration": "m/s^2"}
        lines.append("RMS residual: " + ", ".join(
            values([x], unit=units[k], digits=3)
            for x, k in zip(np.ravel(res.sigma_m), kinds, strict=True)))
    if "omega_rad_s" in summary:
        lines.append(f"natural frequencies: {values(summary['omega_rad_s'], unit='rad/s')}")
    if "zeta" in summary:
        lines.append(f"damping ratios: {values(summary['zeta'], digits=3)}")
    return "\n".join(lines)
