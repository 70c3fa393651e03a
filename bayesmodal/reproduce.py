"""Reproduce the tables of the reference report end to end.

``reproduce_report`` runs, on the four ECP experiments, every step of the report:

- Table 2: steady-state analysis of ``data_steps`` (:mod:`bayesmodal.static`), with the
  report's zero reference and with the previous rest level as reference;
- Tables 3-5: output-error least squares on ``data_impulses`` with free and proportional
  damping (:func:`bayesmodal.fit.fit_lsq`) and the fit percentages;
- Tables 6-8: undamped modes of both fitted models by the eigenproblem, the Rayleigh
  quotient and matrix iteration (:mod:`bayesmodal.modal`);
- Table 9: modal damping of the proportional model (eq. 41 with errata 3), plus the
  state-space (complex) modes of both models;
- Figure 12: X/F frequency responses of both models;
- predictions of the other experiments (steps, sine sweeps) with the impulse-fitted
  parameters, as fit percentages.

``format_tables`` prints ours next to the report's printed values (``REPORT_*`` below,
transcribed from the report; see docs/errata.md for what is wrong in them).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import DataError
from .data import Experiment, data_root, load_experiment
from .fit.lsq import fit_lsq
from .fit.result import LSQResult
from .metrics import fit_percent
from .modal import (
    ComplexModes,
    ModalDamping,
    UndampedModes,
    matrix_iteration,
    orthogonality_error,
    proportional_modal_damping,
    rayleigh_modes,
    state_space_modes,
    transfer_function,
    undamped_modes,
)
from .model.simulate import simulate_linear
from .model.system import LinearModel, Rig
from .plots.fit import plot_lsq_fit
from .plots.modal import plot_bode, plot_rayleigh_contour
from .plots.static import plot_steady_state
from .static import StaticResult, steady_state

__all__ = [
    "EXPERIMENTS",
    "MODAL_METHODS",
    "REPORT_TABLE2",
    "REPORT_TABLE2_ERROR_PERCENT",
    "REPORT_TABLE3",
    "REPORT_TABLE4",
    "REPORT_TABLE5",
    "REPORT_TABLE6_OMEGA",
    "REPORT_TABLE6_SHAPES",
    "REPORT_TABLE9",
    "ReportTables",
    "default_data_dir",
    "load_report_data",
    "reproduce_report",
    "format_tables",
    "save_report_plots",
]

#: The four experiments of the ECP course data, by file stem.
EXPERIMENTS = ("data_impulses", "data_steps", "data_sine_sweep_slow", "data_sine_sweep_fast")
_REQUIRED = ("data_impulses", "data_steps")

#: Modal methods of Tables 6, 7, 8.
MODAL_METHODS = ("eigenproblem", "rayleigh", "matrix_iteration")

# ---------------------------------------------------------------- the report's numbers
#: Table 2, "from data": stiffness ratios and g_v (N/V).
REPORT_TABLE2 = {"k3/k1": 0.4900, "k3/k2": 0.5227, "g_v": 6.0497}
#: Table 2, "error %" as printed (errata 6: only the g_v one is a relative error).
REPORT_TABLE2_ERROR_PERCENT = {"k3/k1": 4.4, "k3/k2": 6.7, "g_v": 15.2}
#: Table 3, free damping (g_v N/V, masses kg, dampers N s/m).
REPORT_TABLE3 = {"g_v": 6.223, "m1": 1.565, "m2": 1.461, "m3": 1.146, "c1": 2.923,
                 "c2": 1.806, "c3": 2.002, "c12": 0.00221, "c23": 0.00001}
#: Table 4, proportional damping (ca 1/s, cb s); g_v and masses repeat Table 3 (erratum 10).
REPORT_TABLE4 = {"g_v": 6.223, "m1": 1.565, "m2": 1.461, "m3": 1.146, "ca": 1.528,
                 "cb": 8.583e-05}
#: Table 5, "NRMSE" = fit percent per output (errata 5).
REPORT_TABLE5 = {"free": (81.52, 81.35, 81.87), "proportional": (81.22, 81.05, 81.35)}
#: Tables 6-8 (identical in the report), natural frequencies, rad/s.
REPORT_TABLE6_OMEGA = {"free": (8.2808, 27.4038, 41.8258),
                       "proportional": (8.2709, 27.4019, 41.8500)}
#: Tables 6-8, mode shapes normalised on cart 1: rows are carts, columns modes.
REPORT_TABLE6_SHAPES = {
    "free": ((1.0, 1.0, 1.0), (0.8614, -0.5183, -2.5368), (0.6099, -1.3058, 2.3301)),
    "proportional": ((1.0, 1.0, 1.0), (0.8609, -0.5271, -2.5621), (0.6093, -1.3111, 2.3721)),
}
#: Table 9: modal damping ratios and damped frequencies (rad/s) of the proportional model.
REPORT_TABLE9 = {"zeta": (0.093, 0.029, 0.020), "damped_rad_s": (8.235, 27.390, 41.842)}


@dataclass(frozen=True, eq=False)
class ReportTables:
    """Everything the report computes, reproduced from the measured data.

    Attributes
    ----------
    experiments : dict of str to Experiment
        The loaded experiments by name (``EXPERIMENTS`` that were available).
    static : StaticResult
        Table 2 with the report's convention (levels from the encoder zero).
    static_previous : StaticResult
        Table 2 with the rest level before each step as reference.
    lsq : dict of str to LSQResult
        Tables 3 (``"free"``) and 4 (``"proportional"``), fitted on data_impulses; their
        ``fit_percent[0]`` is Table 5.
    modes : dict of str to dict of str to UndampedModes
        Tables 6-8: ``modes[damping][method]`` for methods ``MODAL_METHODS``.
    orthogonality : dict of str to dict of str to float
        Largest M-cosine between two computed modes (0 for exact modes), per damping and
        method: the report's orthogonality check.
    modes_report_params : dict of str to UndampedModes
        Eigenproblem modes of the report's printed Table 3 / Table 4 parameters.
    modal_damping : ModalDamping
        Table 9 from our proportional fit (eq. 41a-b with errata 3).
    modal_damping_report : ModalDamping
        Table 9 recomputed from the report's own printed numbers (Table 6 proportional
        frequencies, Table 4 ``ca, cb``).
    complex_modes : dict of str to ComplexModes
        State-space modes of both fitted models (exact damping ratios, also for free
        damping).
    frf_omega_rad_s : ndarray, shape (n_freq,)
        Frequency grid of the frequency responses, rad/s.
    frf_x_per_f : dict of str to ndarray, shape (n_freq, n_carts), complex
        X/F of both fitted models (report eq. 43, Figure 12), m/N.
    predictions : dict of str to dict of str to ndarray, shape (n_carts,)
        ``predictions[damping][experiment]``: fit percent of the impulse-fitted model
        simulated on each available experiment (including data_impulses itself).
    """

    experiments: dict[str, Experiment]
    static: StaticResult
    static_previous: StaticResult
    lsq: dict[str, LSQResult]
    modes: dict[str, dict[str, UndampedModes]]
    orthogonality: dict[str, dict[str, float]]
    modes_report_params: dict[str, UndampedModes]
    modal_damping: ModalDamping
    modal_damping_report: ModalDamping
    complex_modes: dict[str, ComplexModes]
    frf_omega_rad_s: np.ndarray
    frf_x_per_f: dict[str, np.ndarray]
    predictions: dict[str, dict[str, np.ndarray]]

    def as_dict(self) -> dict:
        """JSON-ready summary (no time series; frequency responses as magnitudes)."""
        out = {
            "data": {n: {"source": e.source, "sha256": e.sha256}
                     for n, e in self.experiments.items()},
            "table2": {"zero": self.static.as_dict(),
                       "previous": self.static_previous.as_dict()},
        }
        for damping, res in self.lsq.items():
            out[f"lsq_{damping}"] = {
                "parameters": res.params,
                "stderr": dict(zip(res.model.names, res.stderr.tolist(), strict=True)),
                "fit_percent": res.fit_percent[0].tolist(),
                "success": res.success,
            }
        out["modes"] = {
            d: {m: {"omega_rad_s": r.omega_rad_s.tolist(), "shapes": r.shapes.tolist(),
                    "orthogonality": self.orthogonality[d][m]}
                for m, r in by.items()}
            for d, by in self.modes.items()
        }
        out["modes_report_params"] = {
            d: {"omega_rad_s": r.omega_rad_s.tolist(), "shapes": r.shapes.tolist()}
            for d, r in self.modes_report_params.items()
        }
        out["table9"] = {"zeta": self.modal_damping.zeta.tolist(),
                         "damped_rad_s": self.modal_damping.damped_rad_s.tolist()}
        out["table9_from_report_values"] = {
            "zeta": self.modal_damping_report.zeta.tolist(),
            "damped_rad_s": self.modal_damping_report.damped_rad_s.tolist(),
        }
        out["complex_modes"] = {
            d: {"omega_rad_s": c.omega_rad_s.tolist(), "zeta": c.zeta.tolist(),
                "damped_rad_s": c.damped_rad_s.tolist()}
            for d, c in self.complex_modes.items()
        }
        out["frf"] = {
            "omega_rad_s": self.frf_omega_rad_s.tolist(),
            "magnitude_m_per_n": {d: np.abs(h).T.tolist() for d, h in self.frf_x_per_f.items()},
        }
        out["predictions_fit_percent"] = {
            d: {n: v.tolist() for n, v in by.items()} for d, by in self.predictions.items()
        }
        return out


# ---------------------------------------------------------------- data
def default_data_dir() -> Path | None:
    """Folder of the ECP course data (``<data_root>/ecp210-3dof``), or None if absent."""
    root = data_root()
    if root is None:
        return None
    p = root / "ecp210-3dof"
    if not p.is_dir() and root.name == "ecp210-3dof":
        p = root  # $BAYESMODAL_DATA names the data set folder itself
    return p if p.is_dir() else None


def load_report_data(data_dir: str | os.PathLike | None = None) -> dict[str, Experiment]:
    """Load the ECP experiments of the report from a folder.

    Parameters
    ----------
    data_dir : path-like, optional
        Folder holding ``data_impulses``, ``data_steps`` and optionally the two sine
        sweeps as ``.mat`` (preferred) or ``.txt``; a folder with an ``ecp210-3dof``
        sub-folder also works.  Default: :func:`default_data_dir`.

    Returns
    -------
    dict of str to Experiment
        By file stem, in ``EXPERIMENTS`` order.

    Raises
    ------
    DataError
        If the folder or a required file is missing.
    """
    if data_dir is None:
        folder = default_data_dir()
        if folder is None:
            raise DataError(
                "the ECP data folder was not found; set BAYESMODAL_DATA to the folder that "
                "holds ecp210-3dof/ (or pass --data-dir DIR)"
            )
    else:
        folder = Path(data_dir)
        if not folder.is_dir():
            raise DataError(f"{folder}: no such data folder")
        if (folder / "ecp210-3dof").is_dir():
            folder = folder / "ecp210-3dof"
    out = {}
    for name in EXPERIMENTS:
        for ext in (".mat", ".txt"):
            p = folder / f"{name}{ext}"
            if p.is_file():
                out[name] = load_experiment(p)
                break
    missing = [n for n in _REQUIRED if n not in out]
    if missing:
        raise DataError(
            f"{folder}: missing {', '.join(m + '.mat' for m in missing)}; the report needs "
            "data_impulses and data_steps (set BAYESMODAL_DATA or pass --data-dir DIR)"
        )
    return out


# ---------------------------------------------------------------- the pipeline
def _modes_by_method(M, K) -> dict[str, UndampedModes]:
    return {
        "eigenproblem": undamped_modes(M, K),
        "rayleigh": rayleigh_modes(M, K),
        "matrix_iteration": matrix_iteration(M, K),
    }


def reproduce_report(
    data: str | os.PathLike | Mapping[str, Experiment] | None = None,
    *,
    rig: Rig | None = None,
    frf_omega_rad_s: np.ndarray | None = None,
) -> ReportTables:
    """Run the report's whole analysis on the measured data.

    Parameters
    ----------
    data : path-like or mapping of str to Experiment, optional
        A data folder (see :func:`load_report_data`; default: the shared ECP folder) or
        experiments by name; ``data_impulses`` and ``data_steps`` are required, the sine
        sweeps are used for predictions when present.
    rig : Rig, optional
        Nominal springs (default: the ECP 210 rig, k = 774, 770, 396 N/m).
    frf_omega_rad_s : ndarray, shape (n_freq,), optional
        Frequency grid of the Bode plots, rad/s (default: 600 points from 1 to 200 rad/s,
        log-spaced).

    Returns
    -------
    ReportTables

    Raises
    ------
    DataError
        If data are missing.

    Examples
    --------
    >>> folder = default_data_dir()
    >>> tables = reproduce_report(folder) if folder else None  # doctest: +SKIP
    >>> print(format_tables(tables))  # doctest: +SKIP
    """
    if data is None or isinstance(data, (str, os.PathLike)):
        experiments = load_report_data(data)
    else:
        experiments = dict(data)
        missing = [n for n in _REQUIRED if n not in experiments]
        if missing:
            raise DataError(f"missing experiment(s) {missing}; need {list(_REQUIRED)}")
        for n, e in experiments.items():
            if not isinstance(e, Experiment):
                raise DataError(f"experiment {n!r} is a {type(e).__name__}, not an Experiment")
    rig = Rig() if rig is None else rig
    steps, impulses = experiments["data_steps"], experiments["data_impulses"]

    static = steady_state(steps, rig=rig, reference="zero")
    static_previous = steady_state(steps, rig=rig, reference="previous",
                                   plateaus=static.plateaus)

    lsq = {d: fit_lsq(impulses, LinearModel(rig, d)) for d in ("free", "proportional")}

    modes, ortho, cmodes = {}, {}, {}
    for d, res in lsq.items():
        M, _, K, _ = res.model.matrices(res.theta)
        modes[d] = _modes_by_method(M, K)
        ortho[d] = {m: float(orthogonality_error(M, r.shapes)) for m, r in modes[d].items()}
        cmodes[d] = state_space_modes(res.model, res.theta)

    report_params = {}
    for d, table in (("free", REPORT_TABLE3), ("proportional", REPORT_TABLE4)):
        model = LinearModel(rig, d)
        M, _, K, _ = model.matrices(model.as_vector(table))
        report_params[d] = undamped_modes(M, K)

    prop = lsq["proportional"]
    pp = prop.params
    damping = proportional_modal_damping(modes["proportional"]["eigenproblem"].omega_rad_s,
                                         pp["ca"], pp["cb"])
    damping_report = proportional_modal_damping(
        np.array(REPORT_TABLE6_OMEGA["proportional"]), REPORT_TABLE4["ca"], REPORT_TABLE4["cb"]
    )

    w = np.logspace(0.0, np.log10(200.0), 600) if frf_omega_rad_s is None \
        else np.asarray(frf_omega_rad_s, dtype=float)
    frf = {d: transfer_function(r.model, r.theta, w, input="force") for d, r in lsq.items()}

    predictions = {}
    for d, res in lsq.items():
        predictions[d] = {}
        for name, e in experiments.items():
            if e.n_outputs != rig.n_carts:
                continue
            y_hat = simulate_linear(res.model, res.theta, e.v_volt, e.dt)
            predictions[d][name] = fit_percent(e.y_m, y_hat)

    return ReportTables(
        experiments=experiments,
        static=static,
        static_previous=static_previous,
        lsq=lsq,
        modes=modes,
        orthogonality=ortho,
        modes_report_params=report_params,
        modal_damping=damping,
        modal_damping_report=damping_report,
        complex_modes=cmodes,
        frf_omega_rad_s=w,
        frf_x_per_f=frf,
        predictions=predictions,
    )


# ---------------------------------------------------------------- text tables
def _rel(ours: float, theirs: float) -> str:
    if theirs == 0:
        return ""
    return f"{100.0 * (ours - theirs) / abs(theirs):+8.2f}"


def _table2(r: ReportTables) -> list[str]:
    z, p = r.static, r.static_previous
    lines = [
        "Table 2 - steady-state analysis of data_steps (g_v in N/V)",
        f"{'':8s}{'report':>9s}{'ours':>9s}{'+-se':>8s}{'ours*':>9s}{'+-se':>8s}"
        f"{'nominal':>9s}{'err% rep':>10s}{'err% ours':>10s}",
    ]
    rows = [("g_v", z.g_v, z.g_v_se, p.g_v, p.g_v_se, z.nominal_g_v, z.g_v_error_percent)]
    for j, name in enumerate(z.ratio_names):
        rows.append((name, z.ratios[j], z.ratios_se[j], p.ratios[j], p.ratios_se[j],
                     z.nominal_ratios[j], z.ratios_error_percent[j]))
    for name, a, ase, b, bse, nom, err in rows:
        lines.append(f"{name:8s}{REPORT_TABLE2[name]:9.4f}{a:9.4f}{ase:8.4f}{b:9.4f}"
                     f"{bse:8.4f}{nom:9.4f}{REPORT_TABLE2_ERROR_PERCENT[name]:10.1f}{err:+10.1f}")
    lines.append("  ours: levels from the encoder zero (the report's convention); ours*: minus "
                 "the rest level")
    lines.append(f"  before each step; {z.n_steps} steps, se = standard error across steps; "
                 "err% ours = 100 (ours - nominal) / nominal")
    lines.append("  (errata 6); the report's ratio errors follow from no formula.")
    return lines


def _param_table(title: str, res: LSQResult, report: dict) -> list[str]:
    lines = [title, f"{'':6s}{'report':>12s}{'ours':>12s}{'+-se':>11s}{'diff %':>9s}"]
    se = dict(zip(res.model.names, res.stderr, strict=True))
    for name, value in res.params.items():
        rep = report[name]
        # a parameter that is zero within its standard error has no meaningful % difference
        diff = "~0 both" if max(abs(rep), abs(value)) < se[name] else _rel(value, rep)
        lines.append(f"{name:6s}{rep:12.5g}{value:12.5g}{se[name]:11.2g}{diff:>9s}")
    return lines


def _table5(r: ReportTables) -> list[str]:
    lines = ["Table 5 - fit percent on data_impulses, 100 (1 - |y - yhat| / |y - mean y|)",
             f"{'':6s}{'free rep':>10s}{'free ours':>11s}{'prop rep':>10s}{'prop ours':>11s}"]
    f, p = r.lsq["free"].fit_percent[0], r.lsq["proportional"].fit_percent[0]
    for j in range(f.size):
        lines.append(f"{'x' + str(j + 1):6s}{REPORT_TABLE5['free'][j]:10.2f}{f[j]:11.2f}"
                     f"{REPORT_TABLE5['proportional'][j]:10.2f}{p[j]:11.2f}")
    return lines


def _modal_tables(r: ReportTables) -> list[str]:
    lines = ["Tables 6-8 - undamped modes (the report prints the same values in all three)"]
    for d in ("free", "proportional"):
        rep_w = REPORT_TABLE6_OMEGA[d]
        rep_u = np.array(REPORT_TABLE6_SHAPES[d])
        table = "Table 3" if d == "free" else "Table 4"
        lines.append(f"  {d} damping: omega [rad/s] and shapes (x2/x1, x3/x1) per mode")
        lines.append(f"  {'':24s}" + "".join(f"{'mode ' + str(i + 1):>27s}" for i in range(3)))
        lines.append(f"  {'':24s}" + f"{'omega':>9s}{'x2/x1':>9s}{'x3/x1':>9s}" * 3)

        def row(label, w, u):
            return f"  {label:24s}" + "".join(
                f"{w[i]:9.4f}{u[1, i]:9.4f}{u[2, i]:9.4f}" for i in range(len(w)))

        lines.append(row("report", rep_w, rep_u))
        for m in MODAL_METHODS:
            res = r.modes[d][m]
            lines.append(row(f"ours {m}", res.omega_rad_s, res.shapes))
        rp = r.modes_report_params[d]
        lines.append(row(f"report's {table}", rp.omega_rad_s, rp.shapes))
        ortho = ", ".join(f"{m} {r.orthogonality[d][m]:.1e}" for m in MODAL_METHODS)
        lines.append(f"  orthogonality (largest M-cosine between modes): {ortho}")
    return lines


def _table9(r: ReportTables) -> list[str]:
    lines = ["Table 9 - modal damping of the proportional model, omega_d = omega sqrt(1-zeta^2)",
             f"{'':6s}{'zeta rep':>10s}{'ours':>9s}{'rep*':>9s}{'free**':>9s}"
             f"{'w_d rep':>10s}{'ours':>9s}{'rep*':>9s}{'free**':>9s}"]
    ours, rep = r.modal_damping, r.modal_damping_report
    free = r.complex_modes["free"]
    for i in range(ours.zeta.size):
        lines.append(
            f"{'mode ' + str(i + 1):6s}{REPORT_TABLE9['zeta'][i]:10.3f}{ours.zeta[i]:9.4f}"
            f"{rep.zeta[i]:9.4f}{free.zeta[i]:9.4f}{REPORT_TABLE9['damped_rad_s'][i]:10.3f}"
            f"{ours.damped_rad_s[i]:9.3f}{rep.damped_rad_s[i]:9.3f}{free.damped_rad_s[i]:9.3f}"
        )
    lines.append("  rep*: eq. 41 on the report's printed Table 6 (prop.) frequencies and Table 4 "
                 "ca, cb;")
    lines.append("  free**: state-space (complex) modes of our free-damping fit.")
    return lines


def _predictions(r: ReportTables) -> list[str]:
    lines = ["Predictions with the impulse-fitted parameters (fit percent x1 x2 x3)"]
    for d, by in r.predictions.items():
        for name, v in by.items():
            vals = " ".join(f"{x:7.2f}" for x in v)
            lines.append(f"  {d:13s}{name:22s}{vals}")
    return lines


def format_tables(report: ReportTables) -> str:
    """Plain-text tables: the report's printed values next to ours.

    Parameters
    ----------
    report : ReportTables

    Returns
    -------
    str
        Tables 2-9 and the predictions, one block each, separated by blank lines.
    """
    blocks = [
        _table2(report),
        _param_table("Table 3 - LSQ fit on data_impulses, free damping (N/V, kg, N s/m)",
                     report.lsq["free"], REPORT_TABLE3),
        _param_table("Table 4 - LSQ fit on data_impulses, proportional damping (ca 1/s, cb s)",
                     report.lsq["proportional"], REPORT_TABLE4),
        _table5(report),
        _modal_tables(report),
        _table9(report),
        _predictions(report),
    ]
    return "\n\n".join("\n".join(b) for b in blocks) + "\n"


# ---------------------------------------------------------------- figures
def save_report_plots(report: ReportTables, out_dir: str | os.PathLike, *,
                      dpi: int = 110) -> list[Path]:
    """Write the report's figures as PNG files.

    Files: ``steps_plateaus.png`` (Figure 2), ``fit_impulses_free.png`` and
    ``fit_impulses_proportional.png`` (Figures 6-7), ``rayleigh_contour_free.png`` and
    ``rayleigh_contour_proportional.png`` (Figures 9-10), ``bode_x_per_f.png`` (Figure 12),
    and ``prediction_<experiment>_free.png`` for the other experiments.

    Parameters
    ----------
    report : ReportTables
    out_dir : path-like
        Created if missing.
    dpi : int

    Returns
    -------
    list of Path
        The files written.
    """
    import matplotlib.pyplot as plt


    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def save(fig, name):
        path = out / name
        tmp = out / f".{name}.tmp.png"
        fig.savefig(tmp, dpi=dpi)
        plt.close(fig)
        os.replace(tmp, path)
        written.append(path)

    ax = plot_steady_state(report.static)
    save(ax.figure, "steps_plateaus.png")
    impulses = report.experiments["data_impulses"]
    for d, res in report.lsq.items():
        axes = plot_lsq_fit(res, impulses)
        save(axes[0].figure, f"fit_impulses_{d}.png")
        M, _, K, _ = res.model.matrices(res.theta)
        ax = plot_rayleigh_contour(M, K, modes=report.modes[d]["rayleigh"])
        ax.set_title(f"Rayleigh quotient, {d} damping fit")
        save(ax.figure, f"rayleigh_contour_{d}.png")
    axes = None
    for d, style in (("free", "-"), ("proportional", "--")):
        h = report.frf_x_per_f[d]
        n_before = len(axes[0].lines) if axes is not None else 0
        axes = plot_bode(report.frf_omega_rad_s, h, ax=axes, unit="m/N",
                         labels=[f"x{i + 1}/F {d}" for i in range(h.shape[1])])
        for a in axes:
            for line in a.lines[n_before:]:
                line.set_linestyle(style)
    axes[0].legend(loc="best", fontsize="small", ncols=2)
    axes[0].set_title("X/F of the impulse-fitted models (report Figure 12)")
    save(axes[0].figure, "bode_x_per_f.png")
    free = report.lsq["free"]
    for name, e in report.experiments.items():
        if name == "data_impulses" or e.n_outputs != free.model.n_carts:
            continue
        axes = plot_lsq_fit(free, e, title=f"{name}: predicted by the impulse fit (free)")
        save(axes[0].figure, f"prediction_{name}_free.png")
    return written
