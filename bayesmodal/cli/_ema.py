"""``bayesmodal ema``: experimental modal analysis of one experiment (no physical model)."""

from __future__ import annotations

from .._errors import DataError
from ..ema import METHODS, identify
from ._common import add_data_args, add_rig_argument, load_args, print_json


def register(sub) -> None:
    p = sub.add_parser(
        "ema",
        help="experimental modal analysis (LSCE, circle fit, multi-mode fit, tfest)",
        description="Modal parameters from the FRF of motor volts to cart positions (m/V); "
        "mode shapes normalised to cart 1.",
    )
    add_data_args(p)
    add_rig_argument(p)  # (the FRF is model-free: the rig sets the sensors and scale)
    p.add_argument("--method", choices=METHODS, default="lsce",
                   help="modal parameter fit (default %(default)s)")
    p.add_argument("--n-modes", type=int, default=3,
                   help="number of modes sought (default %(default)s)")
    p.add_argument("--order", type=int, default=None,
                   help="model order in modes: LSCE polynomial order 2N (default 2 x n-modes), "
                   "tfest denominator order 2N (default n-modes)")
    p.add_argument("--band", type=float, nargs=2, metavar=("LO", "HI"), default=None,
                   help="frequency band, rad/s (default: around the FRF peaks)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write the FRF, Nyquist and stabilisation figures (PNG) into DIR")
    p.set_defaults(func=run)


def run(args) -> int:
    (exp,) = load_args(args)
    orders = None
    if args.plots and args.method == "lsce":
        top = args.order or 2 * args.n_modes
        orders = list(range(1, top + 3))
    try:
        res = identify(exp, args.method, n_modes=args.n_modes, order=args.order,
                       band=tuple(args.band) if args.band else None,
                       stabilization_orders=orders)
    except DataError as exc:  # name the file in every data problem
        where = exp.source or exp.name
        raise DataError(str(exc) if str(exc).startswith(where) else f"{where}: {exc}") from exc
    files = []
    if args.plots:
        from ..plots.ema import save_ema_figures

        files = save_ema_figures(res, args.plots)
    summary = res.as_dict()
    summary["data"] = exp.name
    if files:
        summary["plots"] = [str(f) for f in files]
    if args.json:
        print_json(summary)
        return 0
    est = res.estimate
    print(f"{exp.name}: {args.method}, band {res.band[0]:.4g}..{res.band[1]:.4g} rad/s, "
          f"FRF in {res.frf.units}")
    print(" mode  omega (rad/s)   zeta     identified  shape (cart 1 = 1)")
    for k in range(est.n_modes):
        shape = " ".join(f"{x:+.3f}" for x in est.mode_shapes[k].real)
        print(f" {k + 1:4d}  {est.omega_rad_s[k]:12.4f}  {est.zeta[k]:8.4f}  "
              f"{'yes' if est.identified[k] else 'no':>10s}  {shape}")
    for note in est.notes:
        print(f"  note: {note}")
    for f in files:
        print(f"  wrote {f}")
    return 0
