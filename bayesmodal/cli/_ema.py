"""``bayesmodal ema``: experimental modal analysis of one experiment (no physical model)."""

from __future__ import annotations

import warnings

import numpy as np

from .._errors import DataError
from ..ema import FRF_METHODS, METHODS, identify
from ..plots.ema import save_ema_figures
from ._common import add_data_args, add_rig_argument, load_args, load_rig, print_json


def register(sub) -> None:
    p = sub.add_parser(
        "ema",
        help="experimental modal analysis (LSCE, circle fit, multi-mode fit, tfest)",
        description="Modal parameters from the FRF of the input to the outputs (motor "
        "volts to cart positions, m/V; with --rig in the rig's sensor form and input, e.g. "
        "m/s^2/N for accelerometers under a measured force, a hammer test's hits found and "
        "force-windowed); mode shapes normalised to cart 1.  Exit code 2 with a one-line "
        "error when no mode is identified.",
    )
    add_data_args(p)
    add_rig_argument(p)  # (the FRF is model-free: the rig sets the sensors and scale)
    p.add_argument("--method", choices=METHODS, default="lsce",
                   help="modal parameter fit (default %(default)s)")
    p.add_argument("--n-modes", type=int, default=None,
                   help="number of modes sought (default: one per output)")
    p.add_argument("--order", type=int, default=None,
                   help="model order in modes: LSCE polynomial order 2N (default 2 x n-modes), "
                   "tfest denominator order 2N (default n-modes)")
    p.add_argument("--band", type=float, nargs=2, metavar=("LO", "HI"), default=None,
                   help="frequency band, rad/s (default: around the FRF peaks)")
    p.add_argument("--frf", choices=FRF_METHODS, default="auto",
                   help="FRF estimate: pulse train segments, step increments, hammer hits "
                   "(force-windowed), Welch, or the whole record as one transient (default "
                   "%(default)s: from the input; impact needs a force input, --rig)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write the FRF, Nyquist and stabilisation figures (PNG) into DIR "
                   "(default: no plots)")
    p.set_defaults(func=run)


def run(args) -> int:
    (exp,) = load_args(args)
    where = exp.source or exp.name
    n_modes = args.n_modes if args.n_modes is not None else exp.n_outputs
    orders = None
    if args.plots and args.method == "lsce":
        top = args.order or 2 * n_modes
        orders = list(range(1, top + 3))
    rig = load_rig(args) if getattr(args, "rig", None) else None
    kinds = {} if rig is None else {"output_kinds": rig.output_kinds, "input_kind": rig.input}
    try:
        res = identify(exp, args.method, n_modes=n_modes, order=args.order,
                       band=tuple(args.band) if args.band else None,
                       stabilization_orders=orders, frf_method=args.frf, **kinds)
    except DataError as exc:  # name the file in every data problem
        raise DataError(str(exc) if str(exc).startswith(where) else f"{where}: {exc}") from exc
    est = res.estimate
    found = np.flatnonzero(est.identified)
    if found.size == 0:
        why = next((n for n in est.notes if "not identified" in n or "computational" in n),
                   "")
        raise DataError(
            f"{where}: no mode identified by {args.method} in {res.band[0]:.4g}.."
            f"{res.band[1]:.4g} rad/s ({est.n_modes} candidate(s) rejected"
            + (f", e.g. {why}" if why else "") + "); try another --band, --frf transient "
            "or --method, or a record that excites the modes")
    if found.size < n_modes:
        warnings.warn(f"{where}: {found.size} of the {n_modes} modes sought identified "
                      f"(see the notes)", stacklevel=2)
    files = []
    if args.plots:
        files = save_ema_figures(res, args.plots)
    summary = res.as_dict()
    summary["data"] = exp.name
    if files:
        summary["plots"] = [str(f) for f in files]
    est = res.estimate
    if args.json:
        print_json(summary)
        return 0
    print(f"{exp.name}: {args.method}, band {res.band[0]:.4g}..{res.band[1]:.4g} rad/s, "
          f"{res.frf_method} FRF in {res.frf.units} ({res.frf.estimator}, "
          f"{res.frf.n_averages} average(s))")
    stated = bool(np.any(np.isfinite(est.omega_se[found])))
    print(" mode  omega (rad/s)   zeta     shape (cart 1 = 1)" if not stated else
          " mode  omega (rad/s) +- se         zeta +- se            shape (cart 1 = 1)")
    for j, k in enumerate(found):
        shape = " ".join(f"{x:+.3f}" for x in est.mode_shapes[k].real)
        if stated:
            print(f" {j + 1:4d}  {est.omega_rad_s[k]:12.4f} +- {est.omega_se[k]:<8.2g} "
                  f"{est.zeta[k]:8.4f} +- {est.zeta_se[k]:<8.2g}  {shape}")
        else:
            print(f" {j + 1:4d}  {est.omega_rad_s[k]:12.4f}  {est.zeta[k]:8.4f}  {shape}")
    rejected = [k for k in range(est.n_modes) if not est.identified[k]]
    if rejected:
        cells = ", ".join(f"{est.omega_rad_s[k]:.4g} rad/s (zeta {est.zeta[k]:.3g})"
                          for k in rejected)
        print(f"  not identified (computational or without a resonance): {cells}")
    for note in est.notes:
        print(f"  note: {note}")
    for f in files:
        print(f"  wrote {f}")
    return 0
