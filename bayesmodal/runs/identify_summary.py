"""What an identification found, as ``identify.json`` and its report's first screen.

:func:`summarize` gathers the linear run's and the final run's modal intervals, the
diagnosis' causes with their held-out gains, and each left-out record's own estimate of
the natural frequencies and damping ratios against the interval the other records give
for it.  :func:`write_identify_report` renders that as ``report.html``: the story in
plain words first, then the tables, with links to both runs' own reports.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .folder import atomic_write_text
from .report import _CSS, _e, _interval, _num, _table
from .verdict import diagnostic_counts, record_status, run_verdict

__all__ = ["summarize", "story", "render_identify_report", "write_identify_report"]

_MODAL = ("omega_rad_s", "zeta", "mode_shapes")
#: numbers and intervals on one line each
_CSS_MORE = "td{white-space:nowrap} ul.story li{margin:.15em 0}"


def _modal(summary: dict) -> dict:
    return {k: summary[k] for k in _MODAL if k in summary}


def _run_part(summary: dict | None) -> dict | None:
    if summary is None:
        return None
    v = run_verdict(summary)
    d = summary.get("diagnostics", {})
    n_fail, n_all, _ = diagnostic_counts(summary)
    fits = [x for r in summary.get("crosscheck", {}).get("residuals", [])
            for x in np.ravel(r.get("fit_percent", []))]
    return {"modal": _modal(summary), "verdict": v.sentence, "ok": v.ok,
            "checks_failed": n_fail, "checks_run": n_all,
            "fit_percent_range": [min(fits), max(fits)] if fits else None,
            "model_status": v.model.status, "model_text": v.model.text,
            "converged": bool(summary.get("convergence", {}).get("converged", False)),
            "max_rhat": d.get("max_rhat"), "min_ess": d.get("min_ess"),
            "heldout": _heldout_check(summary)}


def _inside(value, lo, hi) -> bool | None:
    if value is None or lo is None or hi is None:
        return None
    value, lo, hi = float(value), float(lo), float(hi)
    if not all(map(math.isfinite, (value, lo, hi))):
        return None
    return lo <= value <= hi


def _heldout_check(summary: dict) -> list[dict]:
    """Per left-out record: its own least-squares omega and zeta against the interval
    the other records' posterior gives for a new record, and its band's status."""
    cv = summary.get("crossval") or {}
    own = cv.get("own_lsq") or {}
    records = cv.get("records") or []
    out = []
    for r in records:
        name = r.get("heldout")
        est = r.get("estimates") or {}
        mine = own.get(name) or {}
        row = {"record": name, "band": record_status(r, len(records))}
        for key in ("omega_rad_s", "zeta"):
            iv = est.get(key) or {}
            vals = mine.get(key) or []
            row[key] = [{"own": v, "lo": lo, "median": m, "hi": hi,
                         "inside": _inside(v, lo, hi)}
                        for v, lo, m, hi in zip(vals, iv.get("lo", []), iv.get("median", []),
                                                iv.get("hi", []), strict=False)]
        out.append(row)
    return out


def _causes(diag: dict) -> list[dict]:
    out = []
    for c in diag.get("causes", []):
        ho = (c.get("gain") or {}).get("held_out") or {}
        fp_now = ho.get("fit_percent_current")
        fp = ho.get("fit_percent")
        out.append({
            "cause": c["cause"], "where": c.get("location_label") or "",
            "parameters": c.get("parameters", {}),
            "heldout_delta_lpd": ho.get("delta_lpd"), "heldout_se": ho.get("se"),
            "heldout_fit_before": None if fp_now is None else float(np.mean(fp_now)),
            "heldout_fit_after": None if fp is None else float(np.mean(fp)),
        })
    return out


def _ignoring(linear: dict, final: dict | None) -> list[dict]:
    """Per mode: how far the linear model's omega and zeta sit from the final model's
    (relative change of the median, %)."""
    if final is None:
        return []
    out = []
    lo, fi = linear["modal"], final["modal"]
    n = len(fi.get("omega_rad_s", {}).get("median", []))
    for i in range(n):
        row = {"mode": i + 1}
        for key in ("omega_rad_s", "zeta"):
            a = lo.get(key, {}).get("median", [])
            b = fi.get(key, {}).get("median", [])
            row[key] = (100.0 * (a[i] / b[i] - 1.0)
                        if i < len(a) and i < len(b) and b[i] else None)
        out.append(row)
    return out


def summarize(linear: dict, diagnosis_stage: dict, final: dict | None,
              effects: tuple[str, ...]) -> dict:
    """``identify.json``: both models' modal intervals, the causes and the checks.

    Parameters
    ----------
    linear, final : dict
        ``summary.json`` of the linear and of the final run (``final`` None when the
        diagnosis found nothing).
    diagnosis_stage : dict
        ``diagnosis.json`` (the diagnosis and how it was run).
    effects : tuple of str
        The effects the final run sampled.
    """
    diag = diagnosis_stage["diagnosis"]
    lin = _run_part(linear)
    fin = _run_part(final)
    g = diag.get("gain") or {}
    return {
        "final_model": "linear" if not effects else "linear+" + "+".join(effects),
        "found": list(diag.get("effects", [])),
        "sampled": list(effects),
        "explained_by_diagnosis": bool(diag.get("explained")),
        "causes": _causes(diag),
        "fit_percent_before": g.get("fit_percent_before"),
        "fit_percent_after": g.get("fit_percent_after"),
        "training_records": g.get("experiments") or diag.get("experiments"),
        "diagnosis_options": {k: diagnosis_stage.get(k) for k in
                              ("split_at_rest", "weights", "candidates", "elapsed_s")},
        "linear": lin,
        "final": fin if fin is not None else lin,
        "ignoring_causes": _ignoring(lin, fin),
    }


# --------------------------------------------------------------------------- report


def _hz(x):
    return None if x is None else float(x) / (2.0 * math.pi)


def _iv(d: dict, i: int, k: float = 1.0) -> tuple:
    return tuple(None if not d.get(q) or i >= len(d[q]) else k * float(d[q][i])
                 for q in ("median", "lo", "hi"))


def _span(values) -> str:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    if not vals:
        return "&ndash;"
    lo, hi = min(vals), max(vals)
    return f"{lo:.1f}" if abs(hi - lo) < 0.05 else f"{lo:.1f}-{hi:.1f}"


def _count_inside(rows: list[dict], key: str) -> tuple[int, int]:
    """Records whose own estimate of every mode lies inside the interval, and records
    with an estimate."""
    flags = [[c["inside"] for c in r[key]] for r in rows]
    flags = [f for f in flags if f and None not in f]
    return sum(all(f) for f in flags), len(flags)


def story(s: dict) -> tuple[str, list[str]]:
    """The first screen in words: the final model's verdict and what the records say
    (one sentence each, with numbers).

    Parameters
    ----------
    s : dict
        ``identify.json`` (:func:`summarize`).

    Returns
    -------
    verdict : str
    lines : list of str
    """
    lin, fin = s["linear"], s["final"]
    causes = s["causes"]
    lines = []
    if lin["model_status"] == "bad":
        fit = lin.get("fit_percent_range")
        lines.append(f"The linear model does not explain these records: {lin['checks_failed']} "
                     f"of {lin['checks_run']} residual checks fail"
                     + (f", fit {fit[0]:.0f}-{fit[1]:.0f} %" if fit else "")
                     + " (its report lists them).")
    if causes:
        names = "; ".join(f"{c['cause'].replace('_', ' ')}" + (f" at {c['where']}"
                                                                 if c["where"] else "")
                          for c in causes)
        before = s.get("fit_percent_before") or []
        after = s.get("fit_percent_after") or []
        n = len(causes)
        lines.append(f"The diagnosis found {n} cause{'s' if n > 1 else ''} ({names}); with "
                     f"{'them' if n > 1 else 'it'} the fit per record rises from "
                     f"{_span([float(np.mean(r)) for r in before])} % to "
                     f"{_span([float(np.mean(r)) for r in after])} %.")
        if s["sampled"] != s["found"]:
            lines.append("Stick-slip friction is sampled as LuGre friction: the same "
                         "friction levels, with a likelihood smooth enough to sample.")
    else:
        lines.append("The diagnosis found no effect of its catalogue that predicts held-out "
                     "records better: the linear model is the final one.")
    om, ze = fin["modal"].get("omega_rad_s", {}), fin["modal"].get("zeta", {})
    modes = []
    for i in range(len(om.get("median", []))):
        f, flo, fhi = _iv(om, i, 1.0 / (2.0 * math.pi))
        z, zlo, zhi = _iv(ze, i)
        modes.append(f"mode {i + 1}: {f:.4g} Hz [{flo:.4g}, {fhi:.4g}], "
                     f"zeta {z:.3g} [{zlo:.3g}, {zhi:.3g}]")
    if modes:
        lines.append("The rig's modes (final model, 90 % intervals): " + "; ".join(modes) + ".")
    moved = [f"zeta{r['mode']} by {r['zeta']:+.0f} %" for r in s["ignoring_causes"]
             if r.get("zeta") is not None and abs(r["zeta"]) >= 1.0]
    if moved:
        lines.append("Ignoring the causes (the linear model) moves " + ", ".join(moved) + ".")
    if fin["heldout"]:
        k_f, n_f = _count_inside(fin["heldout"], "omega_rad_s")
        k_z, n_z = _count_inside(fin["heldout"], "zeta")
        ok = sum(r["band"] == "ok" for r in fin["heldout"])
        lines.append(f"Left out in turn, {k_f} of {n_f} records have their own natural "
                     f"frequencies inside the interval the others give ({k_z} of {n_z} their "
                     f"damping ratios); {ok} of {len(fin['heldout'])} predictive bands "
                     "cover their record as a calibrated band would.")
    return f"Final model: {fin['verdict']}", lines


def _story(s: dict) -> str:
    verdict, lines = story(s)
    fin = s["final"]
    cls = "ok" if fin["ok"] else ("bad" if fin["model_status"] == "bad" else "unknown")
    items = "".join(f"<li>{_e(t)}</li>" for t in lines)
    return (f"<div id='verdict' class='verdict big {cls}'>{_e(verdict)}</div>"
            f"<h2 id='story'>What the records say</h2><ul class='story'>{items}</ul>")


def _modal_table(s: dict) -> str:
    lin, fin = s["linear"]["modal"], s["final"]["modal"]
    both = s["final"] is not s["linear"] and s["found"]
    head = ["mode", "final f_n (Hz)", "90 % interval", "final zeta", "90 % interval"]
    if both:
        head += ["linear f_n (Hz)", "linear zeta", "zeta if causes ignored"]
    hz = 1.0 / (2.0 * math.pi)
    rows = []
    ign = {r["mode"]: r for r in s["ignoring_causes"]}
    for i in range(len(fin.get("omega_rad_s", {}).get("median", []))):
        fm, flo, fhi = _iv(fin["omega_rad_s"], i, hz)
        zm, zlo, zhi = _iv(fin["zeta"], i)
        row = [str(i + 1), _num(fm, ".5g"), _interval(flo, fhi, ".5g"), _num(zm, ".4g"),
               _interval(zlo, zhi, ".4g")]
        if both:
            lm, llo, lhi = _iv(lin["omega_rad_s"], i, hz)
            lz, lzlo, lzhi = _iv(lin["zeta"], i)
            z = ign.get(i + 1, {}).get("zeta")
            row += [f"{_num(lm, '.5g')} {_interval(llo, lhi, '.5g')}",
                    f"{_num(lz, '.4g')} {_interval(lzlo, lzhi, '.4g')}",
                    "&ndash;" if z is None else f"{z:+.0f} %"]
        rows.append(row)
    return "<h2 id='modal'>Modal parameters</h2>" + _table(head, rows)


def _shape_table(s: dict) -> str:
    ms = s["final"]["modal"].get("mode_shapes")
    if not ms:
        return ""
    med = np.asarray(ms["median"], float)
    lo, hi = np.asarray(ms["lo"], float), np.asarray(ms["hi"], float)
    rows = [[f"x{j + 1}"] + [f"{med[j, i]:.3f} {_interval(lo[j, i], hi[j, i], '.3f')}"
                             for i in range(med.shape[1])] for j in range(med.shape[0])]
    return ("<h3>Mode shapes (final model, 90 % intervals)</h3>"
            + _table(["sensor"] + [f"mode {i + 1}" for i in range(med.shape[1])], rows))


def _cause_table(s: dict) -> str:
    if not s["causes"]:
        return ""
    rows = []
    for c in s["causes"]:
        pars = ", ".join(f"{k} = {_num(v, '.3g')}" for k, v in c["parameters"].items())
        gain = ("&ndash;" if c["heldout_delta_lpd"] is None else
                f"{c['heldout_delta_lpd']:.0f} &plusmn; {c['heldout_se']:.0f} nats")
        fit = ("&ndash;" if c["heldout_fit_after"] is None else
               f"{c['heldout_fit_before']:.1f} &rarr; {c['heldout_fit_after']:.1f} %")
        rows.append([_e(c["cause"].replace("_", " ")), _e(c["where"]), _e(pars), gain, fit])
    return ("<h2 id='causes'>Causes found, in the order found</h2>"
            "<p class='muted'>Held-out gain: each training record predicted by the model "
            "fitted to the others, summed (log predictive density, nats); fit: the mean "
            "held-out fit before and after adding the cause.</p>"
            + _table(["cause", "where", "size", "held-out gain", "held-out fit"], rows,
                     left=(0, 1, 2)))


def _heldout_table(s: dict) -> str:
    rows = []
    for label, part in (("final", s["final"]), ("linear", s["linear"])):
        if label == "linear" and s["final"] is s["linear"]:
            continue
        for r in part["heldout"]:
            cells = [_e(r["record"]), label]
            for key, k in (("omega_rad_s", 1 / (2 * math.pi)), ("zeta", 1.0)):
                items = []
                for c in r[key]:
                    cls = {True: "ok", False: "bad", None: "muted"}[c["inside"]]
                    items.append(f"<span class='{cls}'>{_num(k * c['own'], '.4g')}</span>"
                                 f" {_interval(k * c['lo'], k * c['hi'], '.4g')}")
                cells.append("<br>".join(items) or "&ndash;")
            cells.append(_e(r["band"]))
            rows.append(cells)
    if not rows:
        return ("<h2 id='heldout'>Does the interval hold for the next record?</h2>"
                "<p class='muted'>No leave-one-record-out check in these runs "
                "(<code>[crossval] enabled = true</code> runs it).</p>")
    return ("<h2 id='heldout'>Does the interval hold for the next record?</h2>"
            "<p class='muted'>Each record left out in turn: its own least-squares estimate "
            "(coloured: <span class='ok'>inside</span> or <span class='bad'>outside</span>)"
            " against the 90 % interval for a new record from the others' posterior; "
            "band: the left-out record's predictive band against its calibrated range. "
            "A record's own zeta is a linear fit's, which dry friction inflates.</p>"
            + _table(["left-out record", "model", "f_n (Hz): own [interval]",
                      "zeta: own [interval]", "band"], rows, left=(0, 1)))


def render_identify_report(s: dict, *, name: str = "identify") -> str:
    """The HTML text of an identification's report.

    Parameters
    ----------
    s : dict
        ``identify.json`` (:func:`summarize`, with ``stage_s``).
    name : str
        Title of the page.
    """
    links = " &middot; ".join(
        f"<a href='{p}'>{t}</a>" for p, t in (("final/report.html", "final model's run"),
                                              ("linear/report.html", "linear model's run"),
                                              ("diagnosis.json", "diagnosis")))
    st = s.get("stage_s") or {}
    timing = ", ".join(f"{k} {v / 60:.1f} min" for k, v in st.items() if v)
    body = "\n".join([
        f"<h1>bayesmodal identify: {_e(name)}</h1>",
        f"<p class='muted'>final model: {_e(s['final_model'])}</p>",
        _story(s), _modal_table(s), _shape_table(s), _cause_table(s), _heldout_table(s),
        f"<p>{links}</p>",
        f"<p class='muted'>stages this time: {_e(timing) or 'all reused'}</p>",
    ])
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>bayesmodal identify {_e(name)}</title><style>{_CSS}{_CSS_MORE}</style>"
            "</head>"
            f"<body>\n{body}\n</body></html>\n")


def write_identify_report(folder: str | Path, summary: dict) -> Path:
    """Write ``report.html`` of an identification into ``folder`` (atomically).

    Parameters
    ----------
    folder : str or path
        The workflow's folder (links point to its ``linear/`` and ``final/``).
    summary : dict
        ``identify.json``.

    Returns
    -------
    Path
    """
    folder = Path(folder)
    return atomic_write_text(folder / "report.html",
                             render_identify_report(summary, name=folder.name))
