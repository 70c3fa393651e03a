"""``bayesmodal modal``: classical modal analysis of one parameter set (report 3-4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._errors import ConfigError
from ..modal import ConvergenceError, modal_report, rayleigh_modes, transfer_function
from ..system import LinearModel, Rig
from ._common import add_rig_argument, load_rig, print_json

#: Report Table 3 (free damping) and Table 4 (proportional damping), the defaults.
REPORT_PARAMS = {
    "free": {"g_v": 6.223, "m1": 1.565, "m2": 1.461, "m3": 1.146, "c1": 2.923,
             "c2": 1.806, "c3": 2.002, "c12": 0.00221, "c23": 0.00001},
    "proportional": {"g_v": 6.223, "m1": 1.565, "m2": 1.461, "m3": 1.146, "ca": 1.528,
                     "cb": 8.583e-05},
}


def register(sub) -> None:
    p = sub.add_parser(
        "modal",
        help="natural frequencies, mode shapes, modal damping and Bode plots",
        description="Eigenproblem, Rayleigh quotient and matrix iteration (report section 3), "
        "modal damping and transfer functions (section 4) for one parameter set.  "
        "Parameters not given default to the report's Table 3 (free) or Table 4 "
        "(proportional).",
    )
    p.add_argument("--params", default="", metavar="NAME=VALUE,...",
                   help="parameters to change from the report's values, "
                   "e.g. m1=1.57,ca=1.6,cb=8e-5")
    p.add_argument("--damping", choices=["free", "proportional"], default="free")
    add_rig_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", type=Path,
                   help="write rayleigh_contour.png, bode_force.png, mode_shapes.png here")
    p.set_defaults(func=run)


def parse_params(text: str, damping: str, names=None) -> dict[str, float]:
    """``"a=1,b=2"`` merged over the report's values for this damping model.

    With ``names`` (a rig other than the report's), no defaults: every name must be given.
    """
    params = dict(REPORT_PARAMS[damping]) if names is None else dict.fromkeys(names, np.nan)
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in params:
            raise ConfigError(
                f"bad parameter {item!r}: expected NAME=VALUE with NAME in {list(params)}"
            )
        try:
            params[name] = float(value)
        except ValueError:
            raise ConfigError(f"parameter {name} is not a number: {value!r}") from None
    return params


def run(args) -> int:
    model = LinearModel(load_rig(args), args.damping)
    report_rig = model.rig == Rig()
    theta = model.as_vector(parse_params(args.params, args.damping,
                                         None if report_rig else model.names))
    if not np.all(np.isfinite(theta)):
        missing = [n for n, v in zip(model.names, theta, strict=True) if not np.isfinite(v)]
        raise ConfigError(f"--params must give {missing} for this rig (no report values)")
    try:
        report = modal_report(model, theta)
    except ConvergenceError as exc:
        raise ConfigError(str(exc)) from None
    if args.plots is not None:
        report["plots"] = write_plots(model, theta, args.plots)
    if args.json:
        print_json(report)
    else:
        print_report(report)
    return 0


def write_plots(model, theta, folder: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plots.modal import plot_bode, plot_mode_shapes, plot_rayleigh_contour

    folder.mkdir(parents=True, exist_ok=True)
    M, _, K, _ = model.matrices(theta)
    written = []
    if model.n_carts == 3:
        ax = plot_rayleigh_contour(M, K, modes=rayleigh_modes(M, K))
        written.append(_save(ax.figure, folder / "rayleigh_contour.png", plt))
    w = np.logspace(0, np.log10(300.0), 1500)
    H = transfer_function(model, theta, w, input="force")
    ax = plot_bode(w, H, unit="m/N")
    ax[0].set_title(f"X/F, {model.damping} damping")
    written.append(_save(ax[0].figure, folder / "bode_force.png", plt))
    ax = plot_mode_shapes(rayleigh_modes(M, K))
    written.append(_save(ax.figure, folder / "mode_shapes.png", plt))
    return written


def _save(fig, path: Path, plt) -> str:
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


def _row(label, values, fmt="{:>10.4f}"):
    return f"  {label:<22s}" + "".join(fmt.format(v) for v in values)


def print_report(r: dict) -> None:
    print(f"damping: {r['damping']}")
    print("parameters: " + ", ".join(f"{k}={v:.6g}" for k, v in r["parameters"].items()))
    titles = {"eigen": "eigenproblem", "rayleigh": "Rayleigh quotient",
              "iteration": "matrix iteration"}
    for name, m in r["methods"].items():
        print(f"{titles[name]}:")
        print(_row("omega (rad/s)", m["omega_rad_s"]))
        shapes = np.array(m["mode_shapes"]).T
        for i, row in enumerate(shapes):
            print(_row(f"U row {i + 1}", row))
        if "kind" in m:
            print(f"  {'stationary point':<22s}" + "".join(f"{k:>10s}" for k in m["kind"]))
        if "n_iterations" in m:
            print(_row("iterations", m["n_iterations"], "{:>10d}"))
    d = r["max_method_difference"]
    print(f"methods agree to {d['omega_relative']:.1e} (frequency, relative), "
          f"{d['shape_absolute']:.1e} (shapes)")
    mm = r["modal_matrices"]
    print("modal matrices (U^T M U, U^T K U, U^T C U diagonals):")
    print(_row("mass (kg)", np.diag(mm["mass"])))
    print(_row("stiffness (N/m)", np.diag(mm["stiffness"]), "{:>10.1f}"))
    print(_row("damping (N s/m)", np.diag(mm["damping"])))
    print(f"  damping coupling       {mm['damping_coupling']:.3g} (0 for classical damping)")
    ss = r["state_space"]
    print("state-space modes:")
    print(_row("zeta", ss["zeta"]))
    print(_row("damped (rad/s)", ss["damped_rad_s"]))
    if "proportional" in r:
        p = r["proportional"]
        print("modal damping, eq. 41 (proportional):")
        print(_row("zeta", p["zeta"]))
        print(_row("w sqrt(1-zeta^2)", p["damped_rad_s"]))
    print(_row("static gain (mm/V)", 1e3 * np.array(r["static_gain_m_per_v"])))
    for path in r.get("plots", []):
        print(f"wrote {path}")
