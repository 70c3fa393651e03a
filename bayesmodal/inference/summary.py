"""Posterior summaries: credible intervals, LSQ-versus-posterior table, ``summary.json``.

Everything here reads an InferenceData written by :func:`~.idata.to_inference_data`, so
a finished run directory can be summarised again without re-sampling.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from .._versions import dependency_versions
from ..model.effects import EXTENSIONS
from ..model.system import Rig
from .idata import model_from_idata, posterior_matrix
from .propagate import Interval, ModalSamples, credible_interval, modal_intervals, propagate_modes

__all__ = [
    "ComparisonRow",
    "parameter_intervals",
    "posterior_modes",
    "lsq_vs_posterior",
    "comparison_markdown",
    "summary_dict",
    "lsq_theta",
    "mechanical_names",
]


def parameter_intervals(idata, prob: float = 0.9) -> dict[str, Interval]:
    """Median, equal-tailed and HDI intervals of every posterior parameter.

    A run on several records with per-record model parameters also has them at the
    population centre (e.g. ``g_v``, see ``to_inference_data``); they are included.
    """
    names = json.loads(idata.posterior.attrs["parameter_names"])
    mech = json.loads(idata.posterior.attrs.get("mechanical_names", "[]"))
    names += [nm for nm in mech if nm not in names and nm in idata.posterior]
    draws = posterior_matrix(idata, names).reshape(-1, len(names))
    return {nm: credible_interval(draws[:, i], prob) for i, nm in enumerate(names)}


def posterior_modes(idata, *, methods=("eig", "iteration", "rayleigh")) -> ModalSamples:
    """Modal quantities of every posterior draw (dims ``(chain, draw, ...)``), with the MAC
    against the least-squares shapes when the run recorded them."""
    model = model_from_idata(idata)
    draws = posterior_matrix(idata, list(model.names))
    ref = lsq_theta(idata)
    return propagate_modes(model, draws, reference=ref, methods=methods)


def mechanical_names(idata, model) -> list[str]:
    """Model parameter names of a run (linear, then a model extension's, if any).

    Parameters
    ----------
    idata : arviz.InferenceData
        A run (``to_inference_data``).
    model : LinearModel
        Its linear model (``model_from_idata``).

    Returns
    -------
    list of str
    """
    text = idata.posterior.attrs.get("mechanical_names")
    return list(model.names) if text is None else json.loads(text)


def lsq_theta(idata) -> np.ndarray | None:
    """Least-squares estimate stored with the run, shape (n_params,), or None.

    Parameters
    ----------
    idata : arviz.InferenceData
        A run (``to_inference_data``).
    """
    text = idata.posterior.attrs.get("lsq_theta_json")
    return None if text is None else np.asarray(json.loads(text), dtype=float)


@dataclass(frozen=True)
class ComparisonRow:
    """One line of the LSQ-versus-posterior table.

    Attributes
    ----------
    quantity : str
        e.g. ``"g_v"``, ``"omega_2"``, ``"zeta_1"``, ``"phi_3[2]"`` (shape component).
    unit : str
    lsq, median, lo, hi : float
        Least-squares value, posterior median and 90 % equal-tailed interval.
    inside : bool
        Whether the LSQ value lies in the interval.
    """

    quantity: str
    unit: str
    lsq: float
    median: float
    lo: float
    hi: float
    inside: bool


_UNITS = {"g_v": "N/V", "ca": "1/s", "cb": "s"}


def _extension_units() -> dict[str, str]:
    return {p.name: p.unit for ext in EXTENSIONS.values() for p in ext.specs(Rig())}


def _unit(name: str) -> str:
    if name in _UNITS:
        return _UNITS[name]
    if name.startswith("m") and name[1:].isdigit():
        return "kg"
    if name.startswith("c"):
        return "N s/m"
    return _extension_units().get(name, "")


def lsq_vs_posterior(idata, *, prob: float = 0.9, modal: ModalSamples | None = None
                     ) -> list[ComparisonRow]:
    """LSQ and posterior estimates side by side, for parameters and modal quantities.

    Parameters
    ----------
    idata : InferenceData
        Must carry the LSQ estimate (runs started from ``fit_lsq`` do).
    prob : float
    modal : ModalSamples, optional
        Posterior modal samples (computed if omitted).

    Returns
    -------
    list of ComparisonRow
        Empty if the run has no LSQ estimate.
    """
    theta = lsq_theta(idata)
    if theta is None:
        return []
    model = model_from_idata(idata)
    params = parameter_intervals(idata, prob)
    rows = []
    for nm, val in zip(mechanical_names(idata, model), theta, strict=True):
        iv = params[nm]
        rows.append(ComparisonRow(nm, _unit(nm), float(val), float(iv.median), float(iv.lo),
                                  float(iv.hi), bool(iv.contains(val))))
    modal = posterior_modes(idata) if modal is None else modal
    ref = propagate_modes(model, theta[None], methods=("eig",))
    post = modal_intervals(modal, prob)
    for key, label, unit in (("omega_rad_s", "omega", "rad/s"), ("zeta", "zeta", ""),
                             ("damped_rad_s", "omega_d", "rad/s")):
        ref_val = getattr(ref, key)[0]
        iv = post[key]
        for i in range(modal.n_modes):
            v, lo, hi = float(ref_val[i]), float(iv.lo[i]), float(iv.hi[i])
            rows.append(ComparisonRow(f"{label}_{i + 1}", unit, v, float(iv.median[i]),
                                      lo, hi, lo <= v <= hi))
    shp = post["mode_shapes"]
    for i in range(modal.n_modes):  # mode i
        for j in range(1, modal.n_modes):  # cart j (cart 1 is 1 by normalisation)
            v = ref.shapes[0, j, i]
            rows.append(ComparisonRow(
                f"shape_{i + 1}[x{j + 1}]", "", float(v), float(shp.median[j, i]),
                float(shp.lo[j, i]), float(shp.hi[j, i]),
                bool(shp.lo[j, i] <= v <= shp.hi[j, i])))
    return rows


def comparison_markdown(rows: list[ComparisonRow]) -> str:
    """Markdown table of :func:`lsq_vs_posterior` rows; LSQ outside the interval is marked."""
    out = ["| quantity | unit | LSQ | posterior median | 90 % interval | LSQ inside |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        flag = "yes" if r.inside else "**no**"
        out.append(f"| {r.quantity} | {r.unit} | {r.lsq:.5g} | {r.median:.5g} | "
                   f"[{r.lo:.5g}, {r.hi:.5g}] | {flag} |")
    return "\n".join(out)


def _triple(iv: Interval) -> dict:
    d = iv.as_dict()
    return {"median": d["median"], "lo": d["lo"], "hi": d["hi"],
            "hdi_lo": d["hdi_lo"], "hdi_hi": d["hdi_hi"]}


def summary_dict(idata, *, prob: float = 0.9, modal: ModalSamples | None = None) -> dict:
    """The ``summary.json`` content of a posterior run.

    Keys: ``damping``, ``noise``, ``prob``, ``parameters`` (name -> median/lo/hi/hdi),
    ``omega_rad_s``, ``zeta``, ``damped_rad_s``, ``mode_shapes`` (each a dict of lists; mode
    shapes are n x n with modes as columns), ``mac_lsq``, ``method_agreement``,
    ``diagnostics`` (``max_rhat``, ``min_ess``, ``tau``, ``acceptance``, ``converged``,
    ``n_over_tau``, ``problems``), ``performance``, ``lsq_comparison``, ``provenance``.
    """
    a = idata.posterior.attrs
    modal = posterior_modes(idata) if modal is None else modal
    mi = modal_intervals(modal, prob)
    names = json.loads(a["parameter_names"])
    diag = json.loads(a["diagnostics_json"])
    n_draws = int(idata.posterior.sizes["chain"] * idata.posterior.sizes["draw"])
    elapsed = float(a["sampling_time_s"])
    rows = lsq_vs_posterior(idata, prob=prob, modal=modal)
    out = {
        "damping": a["damping"],
        **({"extension": a["extension"]} if a.get("extension") else {}),
        "noise": a["noise"],
        "prob": prob,
        "parameters": {nm: _triple(iv) for nm, iv in parameter_intervals(idata, prob).items()},
        "omega_rad_s": _triple(mi["omega_rad_s"]),
        "zeta": _triple(mi["zeta"]),
        "damped_rad_s": _triple(mi["damped_rad_s"]),
        "mode_shapes": _triple(mi["mode_shapes"]),
        "method_agreement": {
            "max_rel_diff_iteration_rayleigh_vs_eig": modal.max_method_difference()},
        "diagnostics": {
            "max_rhat": diag["max_rhat"],
            "min_ess": diag["min_ess"],
            "tau": dict(zip(names, diag["tau"], strict=True)),
            "acceptance": diag["acceptance"],
            "n_over_tau": diag["n_over_tau"],
            "converged": diag["converged"],
            "problems": diag["problems"],
        },
        "performance": {
            "sampling_time_s": elapsed,
            "n_evaluations": int(a["n_evaluations"]),
            "evaluations_per_s": int(a["n_evaluations"]) / elapsed if elapsed > 0 else None,
            "ess_per_s": diag["min_ess"] / elapsed if elapsed > 0 else None,
            "n_draws_retained": n_draws,
        },
        "lsq_comparison": [r.__dict__ for r in rows],
        "lsq_outside_interval": [r.quantity for r in rows if not r.inside],
        "provenance": {
            "bayesmodal_version": a["bayesmodal_version"],
            "dependencies": dependency_versions(),
            "seed": json.loads(a.get("config_json", "{}")).get("seed"),
            "config_hash": a["config_hash"],
            "data": json.loads(a["data_names"]),
            "data_sha256": json.loads(a["data_sha256"]),
            "burn": int(a["burn"]), "thin": int(a["thin"]), "n_steps": int(a["n_steps"]),
        },
    }
    if "mac_reference" in mi:
        out["mac_lsq"] = _triple(mi["mac_reference"])
    return out
