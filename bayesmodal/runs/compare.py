"""Model choice across finished run folders fitted to the same data.

For each run: PSIS-LOO and WAIC from the pointwise log-likelihood in its ``posterior.nc``
(``bayesmodal.inference.information_criteria``), the ranking and LOO differences with
their standard errors (``arviz.compare``), the evidence when the run computed it, and the
held-out fit (from the run's ``summary.json``, or computed here on ``test`` records).
LOO and WAIC compare models only on the same observations, so runs on different data are
refused.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._errors import ConfigError
from ..inference import (
    information_criteria,
    likelihood_from_idata,
    load_idata,
    posterior_matrix,
    predictive_check,
    with_pointwise_loglik,
)
from ..inference.idata import arviz
from ..inference.likelihood import as_experiments
from ..plots.runs import plot_run_intervals
from .folder import atomic_savefig, atomic_write_json, atomic_write_text
from .verdict import record_status

__all__ = ["RunRow", "RunComparison", "check_distinct_runs", "compare_runs", "write_comparison"]


@dataclass(frozen=True, eq=False)
class RunRow:
    """One run in a comparison.

    Attributes
    ----------
    label : str
        Folder name (made unique).
    path : Path
    damping, noise : str
    n_params : int
        Sampled parameters.
    summary : dict
        The run's ``summary.json``.
    criteria : bayesmodal.inference.InformationCriteria
    rank : int
        0 for the best PSIS-LOO.
    elpd_diff, dse : float
        LOO difference to the best run and its standard error (0 and 0 for the best).
    weight : float
        Stacking weight (``arviz.compare``).
    evidence : dict or None
        ``{"log_z", "log_z_err"}`` when the run computed it.
    heldout : dict or None
        ``{"experiments", "lpd", "fit_percent_median"}`` when available.
    crossval : dict or None
        Leave-one-record-out: ``{"lpd", "lpd_se", "records": {name: lpd}}`` when the run
        has it (``[crossval] enabled``).
    """

    label: str
    path: Path
    damping: str
    noise: str
    n_params: int
    summary: dict
    criteria: object
    rank: int
    elpd_diff: float
    dse: float
    weight: float
    evidence: dict | None = None
    heldout: dict | None = None
    crossval: dict | None = None

    @property
    def n_modes(self) -> int:
        return len(self.summary["omega_rad_s"]["median"])


@dataclass(frozen=True, eq=False)
class RunComparison:
    """Runs ranked by PSIS-LOO, with the other criteria alongside.

    Attributes
    ----------
    rows : tuple of RunRow
        Best PSIS-LOO first.
    preferred : dict
        Best run label by ``"loo"``, ``"waic"`` and, when every run has them,
        ``"evidence"`` and ``"heldout"``.
    verdict : str
    notes : tuple of str
        Warnings raised by ArviZ while comparing.
    """

    rows: tuple[RunRow, ...]
    preferred: dict
    verdict: str
    notes: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict:
        out = {"preferred": dict(self.preferred), "verdict": self.verdict,
               "notes": list(self.notes), "runs": []}
        for r in self.rows:
            c = r.criteria
            out["runs"].append({
                "label": r.label, "path": str(r.path), "damping": r.damping, "noise": r.noise,
                "n_params": r.n_params, "rank": r.rank,
                "elpd_loo": c.elpd_loo, "se_loo": c.se_loo, "p_loo": c.p_loo,
                "elpd_diff": r.elpd_diff, "dse": r.dse, "weight": r.weight,
                "max_pareto_k": c.max_pareto_k, "n_bad_k": c.n_bad_k,
                "elpd_waic": c.elpd_waic, "se_waic": c.se_waic, "p_waic": c.p_waic,
                "evidence": r.evidence, "heldout": r.heldout, "crossval": r.crossval,
                "converged": r.summary.get("diagnostics", {}).get("converged"),
                "omega_rad_s": r.summary["omega_rad_s"], "zeta": r.summary["zeta"],
            })
        return out

    def to_markdown(self) -> str:
        """The model-choice table, best PSIS-LOO first."""
        head = ("| run | damping | noise | P | elpd LOO (se) | diff (dse) | p_loo | k > 0.7 | "
                "elpd WAIC (se) | ln Z (err) | held-out lpd | held-out fit % | "
                "leave-one-record-out lpd (se) |")
        out = [head, "|" + "---|" * (head.count("|") - 1)]
        for r in self.rows:
            c = r.criteria
            ev = (f"{r.evidence['log_z']:.1f} ({r.evidence['log_z_err']:.1f})"
                  if r.evidence else "")
            ho = f"{r.heldout['lpd']:.1f}" if r.heldout else ""
            fit = (", ".join(f"{v:.1f}" for v in np.ravel(r.heldout["fit_percent_median"]))
                   if r.heldout else "")
            out.append(
                f"| {r.label} | {r.damping} | {r.noise} | {r.n_params} | "
                f"{c.elpd_loo:.1f} ({c.se_loo:.1f}) | {r.elpd_diff:.1f} ({r.dse:.1f}) | "
                f"{c.p_loo:.1f} | {c.n_bad_k} | {c.elpd_waic:.1f} ({c.se_waic:.1f}) | {ev} | "
                f"{ho} | {fit} | {_cv_cell(r.crossval)} |")
        return "\n".join(out)


def _cv_cell(cv: dict | None) -> str:
    if not cv:
        return ""
    cell = f"{cv['lpd']:.1f} ({cv['lpd_se']:.1f})"
    if cv.get("calibrated") is not None:
        cell += f"; bands calibrated on {cv['calibrated']} of {len(cv['records'])}"
    return cell


def _crossval_of(summary: dict) -> dict | None:
    """Summed leave-one-record-out lpd, per-record lpd, and (with coverage references)
    the number of left-out records whose band the report's verdict finds consistent with
    a calibrated band (``verdict.record_status``)."""

    cv = summary.get("crossval")
    if not cv or not cv.get("records"):
        return None
    recs = cv["records"]
    calibrated = None
    if all("record_pit_90" in r for r in recs):
        calibrated = sum(record_status(r, len(recs)) == "ok" for r in recs)
    return {"lpd": cv["total"]["lpd"], "lpd_se": cv["total"]["lpd_se"],
            "records": {r["name"]: r["lpd"] for r in recs}, "calibrated": calibrated}


def crossval_difference(a: dict, b: dict) -> tuple[float, float]:
    """Summed leave-one-record-out lpd of ``a`` minus ``b`` and its standard error, from
    the paired per-record differences (``sqrt(R) sd(d_r)``, as PSIS-LOO's ``dse``).

    Raises
    ------
    ConfigError
        If the two runs left out different records.
    """
    if set(a["records"]) != set(b["records"]):
        raise ConfigError(f"leave-one-record-out on different records: {sorted(a['records'])} "
                          f"and {sorted(b['records'])}")
    d = np.array([a["records"][k] - b["records"][k] for k in a["records"]])
    se = float(np.sqrt(d.size) * np.std(d, ddof=1)) if d.size > 1 else math.nan
    return float(d.sum()), se


def _labels(paths: list[Path]) -> list[str]:
    names = [p.name for p in paths]
    if len(set(names)) == len(names):
        return names
    return [f"{p.parent.name}/{p.name}" if names.count(p.name) > 1 else p.name for p in paths]


def _load_run(path: Path):
    if not path.is_dir():
        raise ConfigError(f"{path}: not a run folder")
    st = path / "status.json"
    if st.is_file():
        state = json.loads(st.read_text(encoding="utf-8")).get("state")
        if state != "finished":
            raise ConfigError(f"{path}: the run is {state}, not finished")
    sp = path / "summary.json"
    if not sp.is_file():
        raise ConfigError(f"{path}: no summary.json (not a finished run folder)")
    summary = json.loads(sp.read_text(encoding="utf-8"))
    # a run saved with [outputs] pointwise_loglik = false: the terms are rebuilt exactly
    idata = with_pointwise_loglik(load_idata(path / "posterior.nc"))
    return summary, idata


def check_distinct_runs(paths, idatas) -> None:
    """Refuse a run given twice: the same folder, or the same sampler configuration (its
    hash, which includes the seed) on the same data, e.g. a copied folder.

    Parameters
    ----------
    paths : sequence of path
        The run folders.
    idatas : sequence of arviz.InferenceData
        Their posteriors (``posterior.attrs``: ``config_hash``, ``data_sha256``).

    Raises
    ------
    ConfigError
        Naming the two folders that hold the same run.
    """
    seen: dict = {}
    for path, idt in zip(paths, idatas, strict=True):
        attrs = idt.posterior.attrs
        keys = [("folder", Path(path).resolve())]
        if attrs.get("config_hash"):
            keys.append(("run", attrs["config_hash"], attrs.get("data_sha256", "")))
        for key in keys:
            if key in seen:
                how = "the same folder" if key[0] == "folder" else \
                    "the same run (same sampler configuration and seed on the same data)"
                raise ConfigError(f"{seen[key]} and {path} are {how}: comparing a run with "
                                  "itself says nothing; give runs of different models")
            seen[key] = path


def compare_runs(run_dirs, *, test=None) -> RunComparison:
    """Model choice across finished run folders fitted to the same data.

    Parameters
    ----------
    run_dirs : sequence of path
        At least two run folders (``bayesmodal run`` or ``bayesmodal sample`` output).
    test : Experiment or sequence of Experiment, optional
        Held-out records scored by every run (overrides held-out results stored in the
        runs' summaries).

    Returns
    -------
    RunComparison

    Raises
    ------
    ConfigError
        Fewer than two runs, an unfinished run, the same run twice, or runs fitted to
        different data.
    """

    paths = [Path(p) for p in run_dirs]
    if len(paths) < 2:
        raise ConfigError(f"compare needs at least two run folders, got {len(paths)}")
    labels = _labels(paths)
    loaded = [_load_run(p) for p in paths]
    check_distinct_runs(paths, [idt for _, idt in loaded])
    shas = [tuple(json.loads(idt.posterior.attrs.get("data_sha256", "[]"))) for _, idt in loaded]
    if len(set(shas)) > 1:
        diff = ", ".join(f"{lab}: {list(s)[:1]}" for lab, s in zip(labels, shas, strict=True))
        raise ConfigError(f"the runs were fitted to different data ({diff}); LOO and WAIC "
                          "compare models only on the same observations")
    idatas = {lab: idt for lab, (_, idt) in zip(labels, loaded, strict=True)}
    crit = {lab: information_criteria(idt) for lab, idt in idatas.items()}
    az = arviz()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = az.compare(idatas, ic="loo", var_name="y")
    notes = tuple(dict.fromkeys(str(w.message) for w in caught))
    tests = None
    if test is not None:
        tests = as_experiments(test)
    rows = []
    for lab, path, (summary, idt) in zip(labels, paths, loaded, strict=True):
        heldout = summary.get("heldout")
        if tests is not None:
            lik = likelihood_from_idata(idt, tests)
            draws = posterior_matrix(idt, list(lik.names)).reshape(-1, lik.n_params)
            ps = predictive_check(lik, draws)
            heldout = {"experiments": list(ps.experiments), "lpd": ps.lpd,
                       "fit_percent_median": np.asarray(ps.fit_percent_median).tolist()}
        ev = summary.get("evidence")
        rows.append(RunRow(
            label=lab, path=path, damping=idt.posterior.attrs["damping"],
            noise=idt.posterior.attrs["noise"],
            n_params=len(json.loads(idt.posterior.attrs["parameter_names"])),
            summary=summary, criteria=crit[lab], rank=int(table.loc[lab, "rank"]),
            elpd_diff=float(table.loc[lab, "elpd_diff"]), dse=float(table.loc[lab, "dse"]),
            weight=float(table.loc[lab, "weight"]),
            evidence=None if ev is None else {"log_z": ev["log_z"], "log_z_err": ev["log_z_err"]},
            heldout=heldout, crossval=_crossval_of(summary)))
    rows.sort(key=lambda r: r.rank)
    pref = {"loo": rows[0].label,
            "waic": max(rows, key=lambda r: r.criteria.elpd_waic).label}
    if all(r.evidence for r in rows):
        pref["evidence"] = max(rows, key=lambda r: r.evidence["log_z"]).label
    if all(r.heldout for r in rows):
        pref["heldout"] = max(rows, key=lambda r: r.heldout["lpd"]).label
    if all(r.crossval for r in rows):
        pref["crossval"] = max(rows, key=lambda r: r.crossval["lpd"]).label
    return RunComparison(rows=tuple(rows), preferred=pref, verdict=_verdict(rows, pref),
                         notes=notes)


def _verdict(rows, pref: dict) -> str:
    best, second = rows[0], rows[1]
    z = abs(second.elpd_diff) / second.dse if second.dse > 0 else math.inf
    clear = abs(second.elpd_diff) >= 4 and z >= 2
    words = [f"PSIS-LOO ranks {best.label} first; its lead over {second.label} is "
             f"{abs(second.elpd_diff):.1f} nats ({z:.1f} standard errors), "
             f"{'a clear' if clear else 'not a clear'} difference."]
    for key, what in (("waic", "WAIC"), ("evidence", "the evidence"),
                      ("heldout", "the held-out records")):
        if key in pref:
            words.append(f"By {what}: {pref[key]}.")
    if "crossval" in pref:
        best_cv = next(r for r in rows if r.label == pref["crossval"])
        others = [r for r in rows if r is not best_cv]
        runner_up = max(others, key=lambda r: r.crossval["lpd"])
        diff, se = crossval_difference(best_cv.crossval, runner_up.crossval)
        words.append(
            f"Which model predicts the next experiment (leave-one-record-out, the criterion "
            f"for that question): {best_cv.label}, ahead of {runner_up.label} by {diff:.1f} "
            f"nats ({diff / se if se > 0 else math.inf:.1f} standard errors over records).")
        cal = [r for r in rows if r.crossval.get("calibrated") is not None]
        if cal:
            words.append("Left-out bands consistent with calibrated ones: " + ", ".join(
                f"{r.label} {r.crossval['calibrated']} of {len(r.crossval['records'])}"
                for r in cal) + " records.")
    if len(set(pref.values())) == 1:
        words.append("All criteria agree.")
    else:
        words.append("The criteria disagree.")
    if any(r.criteria.n_bad_k for r in rows):
        words.append("Some Pareto k exceed 0.7: PSIS-LOO is unreliable for those samples "
                     "(autocorrelated records make leave-one-sample-out optimistic).")
    return " ".join(words)


def write_comparison(comparison: RunComparison, out_dir: str | os.PathLike, *,
                     plots: bool = True) -> Path:
    """Write ``comparison.json``, ``comparison.md`` and ``intervals.png`` atomically."""

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "comparison.json", comparison.as_dict())
    atomic_write_text(out / "comparison.md",
                      comparison.to_markdown() + "\n\n" + comparison.verdict + "\n")
    if plots:
        atomic_savefig(plot_run_intervals(comparison)[0, 0].figure, out / "intervals.png")
    return out
