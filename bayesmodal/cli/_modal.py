"""``bayesmodal modal``: classical modal analysis of one parameter set (report 3-4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._errors import ConfigError
from .._format import param_unit, sig
from ..modal import ConvergenceError, modal_report, rayleigh_modes, transfer_function
from ..model.system import LinearModel, Rig
from ..plots.modal import plot_bode, plot_mode_shapes, plot_rayleigh_contour
from ._common import add_rig_argument, damping_of, load_rig, print_json

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
        "(proportional); springs k1..k3 to the rig's (N/m).",
    )
    p.add_argument("--params", default="", metavar="NAME=VALUE,...",
                   help="parameters to change from the report's values, "
                   "e.g. m1=1.57,ca=1.6,cb=8e-5; springs k1..k3 in N/m "
                   "(default: the report's Table 3 or 4 and the rig's springs)")
    p.add_argument("--damping", choices=["free", "proportional"], default=None,
                   help="damping model: free (c1, c2, c3, c12, c23) or proportional "
                   "(C = ca M + cb K) (default: the rig's [dampers] proportional "
                   "declaration, else free)")
    add_rig_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.add_argument("--plots", metavar="DIR", type=Path,
                   help="write rayleigh_contour.png, bode_force.png, mode_shapes.png here "
                   "(default: no plots)")
    p.set_defaults(func=run)


def parse_params(text: str, damping: str, springs=None, names=None
                 ) -> tuple[dict[str, float], list[float]]:
    """``"a=1,k2=900"`` merged over the report's values and the rig's springs.

    Returns the model parameters (``LinearModel.names``) and the springs k1..kn, N/m.
    Each value is checked on its own, so that an error names the parameter.  With
    ``names`` (a rig other than the report's) there are no defaults: every name must be
    given, and the springs are the rig's (known or among ``names``).
    """
    params = dict(REPORT_PARAMS[damping]) if names is None else dict.fromkeys(names, np.nan)
    springs = [] if names is not None else list(
        Rig().springs_n_m if springs is None else springs)
    ks = {f"k{i + 1}": i for i in range(len(springs))}
    known = [*params, *ks]
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in known:
            raise ConfigError(
                f"bad parameter {item!r}: expected NAME=VALUE with NAME one of "
                f"{', '.join(known)} (--damping {damping})"
            )
        default = springs[ks[name]] if name in ks else params[name]
        try:
            x = float(value)
        except ValueError:
            raise ConfigError(f"parameter {name} is not a number: {value!r} (write e.g. "
                              f"{name}={default:g})") from None
        # gain, masses and springs must be positive; damping coefficients may vanish
        positive = name == "g_v" or name[0] in "mk"
        if not (np.isfinite(x) and (x > 0 if positive else x >= 0)):
            raise ConfigError(f"parameter {name} = {value.strip()} is impossible: it must be "
                              f"finite and {'>' if positive else '>='} 0 {param_unit(name)} "
                              f"(the default is {name}={default:g})")
        if name in ks:
            springs[ks[name]] = x
        else:
            params[name] = x
    return params, springs


def run(args) -> int:
    rig = load_rig(args)
    damping = damping_of(args, rig)
    if rig == Rig():
        params, springs = parse_params(args.params, damping)
        model = LinearModel(Rig(tuple(springs)), damping)
    else:
        model = LinearModel(rig, damping)
        params, _ = parse_params(args.params, damping, names=model.names)
    theta = model.as_vector(params)
    if not np.all(np.isfinite(theta)):
        missing = [n for n, v in zip(model.names, theta, strict=True) if not np.isfinite(v)]
        raise ConfigError(f"--params must give {missing} for this rig (no report values)")
    try:
        report = modal_report(model, theta)
    except ConvergenceError as exc:
        raise ConfigError(str(exc)) from None
    report["springs_n_m"] = list(model.rig.springs_n_m)
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
    print("parameters: " + ", ".join(f"{k} = {sig(v)} {param_unit(k)}".rstrip()
                                     for k, v in r["parameters"].items()))
    if "springs_n_m" in r:
        print("springs: " + ", ".join(f"k{i + 1} = {sig(k)} N/m"
                                      for i, k in enumerate(r["springs_n_m"])))
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
