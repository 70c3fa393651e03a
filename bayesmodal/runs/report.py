"""``report.html``: a self-contained page describing one run folder.

Everything comes from the files of the folder (``summary.json``, ``status.json``,
``config.toml``, the ``*.png`` plots), so a finished run can be re-rendered at any time.
Images are embedded as base64 ``data:`` URIs and the page has no scripts and no external
references: it opens from anywhere, also after being mailed.  Every string taken from the
folder is HTML-escaped.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
from pathlib import Path

from .._errors import ConfigError
from .folder import atomic_write_text
from .verdict import COVERAGE_TOLERANCE, cell_statuses, run_verdict

__all__ = ["render_report", "write_report", "REPORT_IMAGES"]

#: Plots shown in the report when present: file name -> (section, caption).
REPORT_IMAGES = {
    "trace.png": ("convergence", "Trace of every walker (retained draws) and marginals."),
    "predictive.png": ("predictive", "Posterior predictive: measured positions, median "
                       "prediction and 90 % band of replicated measurements."),
    "bode.png": ("bode", "Bode diagram, motor voltage to cart positions: posterior median "
                 "(line) and 90 % credible band (shaded) of the model, measured H1 estimate "
                 "of the fitted record(s) (dots); the bottom panel gives the width of the band, "
                 "which is thinner than the lines where it cannot be seen."),
    "modal_intervals.png": ("modal", "Posterior intervals of the modal quantities with the "
                            "least-squares and LSCE values."),
    "corner.png": ("parameters", "Pairwise posterior marginals, zoomed on the posterior; "
                   "a least-squares value outside the panel is marked by an arrow at the "
                   "edge with its value."),
    "residuals.png": ("residuals", "Residuals at the posterior median."),
    "residual_acf.png": ("residuals", "Autocorrelation of the residuals against the lag; "
                         "residuals that are only measurement noise stay inside the grey "
                         "white-noise limit at every lag but 0."),
}

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2em auto;
max-width:1100px;padding:0 1em;color:#222;line-height:1.4}
h1{margin-bottom:0.2em}h2{border-bottom:1px solid #ccc;padding-bottom:0.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.92em}
th,td{border:1px solid #ccc;padding:0.25em 0.6em;text-align:right}
th{background:#f2f2f2}td.l,th.l{text-align:left}
.ok{color:#11691b;font-weight:600}.bad{color:#a31515;font-weight:600}
.verdict{padding:0.6em 1em;border-radius:6px;margin:0.6em 0}
.verdict.ok{background:#e6f4e8}.verdict.bad{background:#fbe9e9}
.verdict.unknown{background:#fff4d6}.unknown{color:#8a5a00;font-weight:600}
.wide{color:#b35c00;font-weight:600}
.verdict.big{font-size:1.15em;border:1px solid #ccc}
table.answers td{text-align:left;vertical-align:top}table.answers td.s{white-space:nowrap}
pre{background:#f6f6f6;padding:0.8em;overflow-x:auto;font-size:0.85em}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:0.9em;color:#555}.muted{color:#666;font-size:0.9em}
nav a{margin-right:0.8em}
"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _num(x, fmt: str = ".5g") -> str:
    if x is None:
        return "&ndash;"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return _e(x)
    if not math.isfinite(v):
        return "&ndash;"
    return _e(format(v, fmt))


def _interval(lo, hi, fmt: str = ".5g") -> str:
    return f"[{_num(lo, fmt)}, {_num(hi, fmt)}]"


def _table(header, rows, left=(0,)) -> str:
    """An HTML table; ``rows`` hold already-escaped cell HTML."""
    def cell(tag, i, v):
        cls = ' class="l"' if i in left else ""
        return f"<{tag}{cls}>{v}</{tag}>"

    out = ["<table>", "<tr>" + "".join(cell("th", i, _e(h)) for i, h in enumerate(header))
           + "</tr>"]
    for r in rows:
        out.append("<tr>" + "".join(cell("td", i, v) for i, v in enumerate(r)) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _img(folder: Path, name: str) -> str:
    p = folder / name
    if not p.is_file():
        return ""
    data = base64.b64encode(p.read_bytes()).decode("ascii")
    caption = REPORT_IMAGES.get(name, ("", name))[1]
    return (f'<figure><img alt="{_e(name)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


def _clip(text: str, n: int = 400) -> str:
    return text if len(text) <= n else text[: n - 3] + "..."


def _yes(flag: bool) -> str:
    return '<span class="ok">yes</span>' if flag else '<span class="bad">no</span>'


def _unit(name: str, rows: dict) -> str:
    if name.startswith("sigma"):
        return "mm"
    if name in rows:
        return rows[name]["unit"]
    return ""


def _sc(k: float, x):
    """``k * x`` for a number, None for a missing one."""
    return None if x is None else k * float(x)


def _scale(name: str) -> float:
    """Factor from the stored unit (SI) to the unit shown (noise levels in mm, as the
    residuals)."""
    return 1e3 if name.startswith("sigma") else 1.0


_STATUS = {"ok": ("ok", "yes"), "bad": ("bad", "no"), "unknown": ("unknown", "not tested")}


def _answer_word(question: str, status: str) -> str:
    cls, word = _STATUS[status]
    if question.startswith("How far") and status != "unknown":
        word = "as stated" if status == "ok" else "not as stated"
    return f"<span class='{cls}'>{_e(word)}</span>"


#: Colour (CSS class) of a coverage cell by ``coverage_status``: too narrow red, wider
#: than needed amber, within the window green, as the verdict's sentence says.
_COVERAGE_CLASS = {"ok": "ok", "narrow": "bad", "wide": "wide"}


def _ranges(pairs, fmt: str, scale: float = 1.0) -> str:
    """'a-b, c-d' from per-output [lo, hi] pairs ('&ndash;' without)."""
    txt = ", ".join(f"{format(scale * lo, fmt)}-{format(scale * hi, fmt)}"
                    for lo, hi in (pairs or []))
    return _e(txt) or "&ndash;"


def _coverage_rows(records, role: str, *, relative: bool = False, factor: bool = False,
                   prob: float = 0.9) -> list[list[str]]:
    """Table rows; band widths in mm, or (``relative``) divided by the record's sd; each
    coverage coloured by :func:`~.verdict.cell_statuses` (against the record's coverage
    reference where it has one) and followed by the range a calibrated band would cover;
    with ``factor`` also the factor on the band's width that would cover 90 %
    (``band_factor_90``) and its calibrated range."""
    rows = []
    for r in records:
        cov = _flat(r.get("coverage_90", []))
        width = _flat(r.get("width_90", []))
        fit = _flat(r.get("fit_percent", []))
        cells = [f"<span class='{_COVERAGE_CLASS[st]}'>{100 * c:.0f}</span>"
                 for c, st in zip(cov, cell_statuses(r, prob), strict=True)]
        row = [_e(r.get("name", "?")), _e(role), ", ".join(cells) or "&ndash;",
               _ranges(r.get("coverage_90_expected"), ".0f", 100.0),
               _e(", ".join(f"{w:.2f}" if relative else f"{1e3 * w:.3f}"
                            for w in width)) or "&ndash;"]
        if factor:
            row += [_e(", ".join(f"{x:.2f}" for x in
                                 _flat(r.get("band_factor_90", [])))) or "&ndash;",
                    _ranges(r.get("band_factor_90_expected"), ".2f")]
        rows.append(row + [_e(", ".join(f"{f:.1f}" for f in fit)) or "&ndash;"])
    return rows


def _noise_scale_note(s: dict) -> str:
    """How the run scaled its noise level with the records' size ("" for one level)."""
    return {"response": " (level per record size)",
            "power": " (level per record size to a sampled power)"}.get(
        s.get("run", {}).get("config", {}).get("noise_scale"), "")


def _section_verdict(s: dict) -> str:
    """The first screen: the overall sentence and the three questions."""
    v = run_verdict(s)
    cls = "ok" if v.ok else ("bad" if any(a.status == "bad" for a in v.answers)
                             else "unknown")
    rows = "".join(
        f"<tr><td><b>{_e(a.question)}</b></td><td class='s'>"
        f"{_answer_word(a.question, a.status)}</td><td>{_e(a.text)}</td></tr>"
        for a in v.answers)
    out = (f"<div id='verdict' class='verdict big {cls}'>{_e(v.sentence)}</div>"
           f"<table class='answers'>{rows}</table>")
    held = (s.get("heldout") or {})
    tol = f"{100 * COVERAGE_TOLERANCE:.0f}"
    rows = _coverage_rows(held.get("records") or [], "held out")
    rows += _coverage_rows(held.get("fitted_records") or [], "fitted (in-sample)")
    cv = s.get("crossval") or {}
    cv_rows = _coverage_rows(cv.get("records") or [], "left out", relative=True,
                             factor=True)
    legend = ("<p class='muted'>Coverage: the share of the measured samples inside the "
              "90 % posterior-predictive band (model output plus fitted noise). One "
              "record is one draw of it: when the misfit is correlated over hundreds of "
              "samples, even a calibrated band covers anything from about 70 to 100 % of "
              "a single record. The <i>calibrated</i> columns give the central 90 % of "
              "what a calibrated band shows on a record like this one (the predictive "
              "draws scored against each other). <span class='ok'>Green</span>: inside "
              "that range; <span class='bad'>red</span>: the band is too narrow (coverage "
              "below it, or misses further out than a calibrated band's); "
              "<span class='wide'>amber</span>: wider than needed. Without a calibrated "
              f"range: green within 90 &plusmn; {tol} %.</p>")
    if rows:
        out += legend + _table(["record", "role", "coverage of 90 % band (%, per output)",
                                "calibrated (%)", "band width (mm, per output)",
                                "fit % (per output)"], rows, left=(0, 1))
    if cv_rows:
        method = cv.get("method") or "each record left out of the fit in turn"
        out += (f"<h3 id='crossval'>Leave-one-record-out ({_e(method)})</h3>"
                + ("" if rows else legend)
                + _table(["record", "role", "coverage of 90 % band (%, per output)",
                          "calibrated (%)", "band width / record sd (per output)",
                          "width factor that would cover 90 % (per output)",
                          "calibrated factor", "fit % (per output)"],
                         cv_rows, left=(0, 1)))
    return out


def _section_run(s: dict, status: dict, config_text: str, timing: dict) -> str:
    run = {**s.get("run", {}), **timing}  # timings live in timing.json
    cfg = run.get("config", {})
    items = [
        ("state", _e(status.get("state", "?"))),
        ("configuration", _e(run.get("config_source", ""))),
        ("configuration hash", f"<code>{_e(run.get('config_hash', ''))}</code>"),
        ("model", _e(f"{s.get('damping')} damping, {s.get('noise')} noise"
                     f"{_noise_scale_note(s)}")),
        ("sampler", _e(f"{run.get('walkers')} walkers x {run.get('steps')} steps, burn "
                       f"{run.get('burn')}, thin {run.get('thin')}, moves {run.get('moves')}, "
                       f"seed {run.get('seed')}")),
        ("started / finished", _e(f"{run.get('started', '?')} / {run.get('finished', '?')}")),
        ("wall time", _e(f"{run.get('wall_time_s', float('nan')):.1f} s "
                         f"({run.get('action', '?')}, "
                         f"{run.get('steps_in_checkpoint_at_start', 0)} steps from the "
                         "checkpoint)")),
        ("bayesmodal", _e(run.get("bayesmodal_version", "?"))),
        ("dependencies", _e(", ".join(f"{k} {v}" for k, v in
                                      run.get("dependencies", {}).items()))),
    ]
    if cfg.get("extensions"):
        items.insert(4, ("extensions", _e(", ".join(cfg["extensions"]))))
    rows = [[_e(k), v] for k, v in items]
    data_rows = [[_e(d["name"]), _e("fitted"), f"<code>{_e(d['sha256'])}</code>",
                  _e(d["bytes"])] for d in run.get("data", [])]
    data_rows += [[_e(d["name"]), _e("held out"), f"<code>{_e(d['sha256'])}</code>",
                   _e(d["bytes"])] for d in run.get("heldout_data", [])]
    return ("<h2 id='run'>What was run</h2>"
            + _table(["item", "value"], rows, left=(0, 1))
            + _table(["data file", "role", "SHA-256", "bytes"], data_rows, left=(0, 1, 2))
            + "<details open><summary>Configuration file</summary>"
            + f"<pre>{_e(config_text)}</pre></details>")


def _section_convergence(s: dict, folder: Path) -> str:
    conv = s.get("convergence", {})
    d = s["diagnostics"]
    ok = bool(conv.get("converged", d.get("converged")))
    verdict = conv.get("detail") or "; ".join(d.get("problems", []))
    cls = "ok" if ok else "bad"
    rows = [[_e("max R-hat (walkers as chains)"), _num(d["max_rhat"], ".4f")],
            [_e("min bulk ESS"), _num(d["min_ess"], ".0f")],
            [_e("post burn-in steps / max tau"), _num(d["n_over_tau"], ".1f")],
            [_e("mean acceptance"), _num(d["acceptance"], ".3f")]]
    tau = [[_e(k), _num(v, ".1f")] for k, v in d.get("tau", {}).items()]
    return (f"<h2 id='convergence'>Sampler convergence</h2><p class='{cls}'>"
            f"{'Sampler converged' if ok else 'Sampler NOT converged'}: {_e(verdict)}. "
            "This is about the sampler only, not about the model (see the first screen)."
            "</p>"
            + _table(["check", "value"], rows)
            + "<details><summary>Integrated autocorrelation time per parameter (steps)"
              "</summary>" + _table(["parameter", "tau"], tau) + "</details>"
            + "<p class='muted'>Walker traces: at the end of the report.</p>")


def _section_parameters(s: dict, folder: Path) -> str:
    prob = s.get("prob", 0.9)
    lsq = {r["quantity"]: r for r in s.get("lsq_comparison", [])}
    rows = []
    for nm, iv in s["parameters"].items():
        r = lsq.get(nm)
        k = _scale(nm)
        rows.append([_e(nm), _e(_unit(nm, lsq)), _num(_sc(k, iv["median"])),
                     _interval(_sc(k, iv["lo"]), _sc(k, iv["hi"])),
                     _interval(_sc(k, iv["hdi_lo"]), _sc(k, iv["hdi_hi"])),
                     _num(_sc(k, r["lsq"])) if r else "&ndash;",
                     _yes(r["inside"]) if r else "&ndash;"])
    pct = f"{100 * prob:.0f} %"
    params = s["parameters"]
    note = ""
    if any(nm.startswith("phi") for nm in params):
        # AR(1) noise: sigma is the innovation; the noise itself is much larger when phi ~ 1
        sd = []
        for nm in sorted(k for k in params if k.startswith("sigma")):
            ph = params.get("phi" + nm[len("sigma"):], {}).get("median")
            sg = params[nm].get("median")
            if ph is not None and sg is not None and abs(ph) < 1:
                sd.append(1e3 * sg / math.sqrt(1 - ph**2))
        if sd:
            note = ("<p class='muted'>Noise model AR(1): sigma is the standard deviation of "
                    "the innovations, phi the correlation of successive noise samples; the "
                    "noise itself has standard deviation sigma / &radic;(1 - phi&sup2;) = "
                    + _e(", ".join(f"{v:.3f}" for v in sd))
                    + " mm per output, to compare with the residual RMS below.</p>")
    return ("<h2 id='parameters'>Parameters</h2>"
            + _table(["parameter", "unit", "median", f"{pct} interval (equal-tailed)",
                      f"{pct} HDI", "least squares", "LSQ inside"], rows, left=(0, 1))
            + note + _img(folder, "corner.png"))


def _section_modal(s: dict, folder: Path) -> str:
    prob = s.get("prob", 0.9)
    lsq = {r["quantity"]: r for r in s.get("lsq_comparison", [])}
    lsce = s.get("crosscheck", {}).get("lsce", [])
    head = ["mode", "quantity", "unit", "posterior median", f"{100 * prob:.0f} % interval",
            "least squares"]
    head += [f"LSCE {c['experiment']}" for c in lsce]
    rows = []
    n = len(s["omega_rad_s"]["median"])
    hz = 1.0 / (2.0 * math.pi)
    for i in range(n):
        for key, label, name, unit, k, col in (
                ("omega_rad_s", "omega", "f_n (natural)", "Hz", hz, "omega_matched"),
                ("zeta", "zeta", "zeta (damping ratio)", "-", 1.0, "zeta_matched"),
                ("damped_rad_s", "omega_d", "f_d (damped)", "Hz", hz, None)):
            iv = s[key]
            lo, hi = iv["lo"][i], iv["hi"][i]
            r = lsq.get(f"{label}_{i + 1}")
            cells = [_e(i + 1), _e(name), _e(unit), _num(_sc(k, iv["median"][i])),
                     _interval(_sc(k, lo), _sc(k, hi)),
                     _num(_sc(k, r["lsq"])) if r else "&ndash;"]
            if r:
                cells[-1] = (f"<span class='{'ok' if r['inside'] else 'bad'}'>"
                             f"{cells[-1]}</span>")
            for c in lsce:
                if col is None:
                    cells.append("")
                    continue
                v = c[col][i] if i < len(c[col]) else None
                if v is None or not math.isfinite(float(v)) or lo is None or hi is None:
                    cells.append("&ndash;")
                else:
                    inside = lo <= float(v) <= hi
                    cls = "ok" if inside else "bad"
                    cells.append(f"<span class='{cls}'>{_num(_sc(k, v))}</span>")
            rows.append(cells)
    notes = "".join(f"<li>LSCE on {_e(c['experiment'])}: {_e(_clip(c['error']))}</li>"
                    for c in lsce if c.get("error"))
    text = ("<p class='muted'>Frequencies in Hz (f = omega / 2 pi). LSCE (least-squares "
            "complex exponential, <code>bayesmodal.ema</code>) uses only the measured input "
            "and outputs, not the rig model. Green: inside the posterior interval, red: "
            "outside.</p>")
    return ("<h2 id='modal'>Modal quantities</h2>" + text
            + _table(head, rows, left=(1, 2))
            + (f"<ul>{notes}</ul>" if notes else "")
            + _img(folder, "modal_intervals.png"))


def _section_predictive(s: dict, folder: Path) -> str:
    out = "<h2 id='predictive'>Posterior predictive</h2>" + _img(folder, "predictive.png")
    cc = s.get("crosscheck", {})
    if cc.get("lsq"):
        fits = cc["lsq"]["fit_percent"]
        out += "<p>Least-squares fit: " + _e("; ".join(
            ", ".join(f"{v:.2f}" for v in row) for row in fits)) + " % (per output).</p>"
    h = s.get("heldout")
    if h:
        ref = h.get("fitted_lpd_per_obs")
        per = h["lpd_per_obs"]
        rows = [[_e(", ".join(h["experiments"])), _num(per, ".3f"),
                 _num(ref, ".3f") if ref is not None else "&ndash;",
                 _e(", ".join(f"{v:.1f}" for v in _flat(h["fit_percent_median"]))),
                 _e(", ".join(f"[{a:.1f}, {b:.1f}]" for a, b in
                              zip(_flat(h["fit_percent_lo"]), _flat(h["fit_percent_hi"]),
                                  strict=True)))]]
        out += ("<h3>Held-out records</h3>"
                + _table(["records", "log predictive density per sample (nats)",
                          "same on the fitted record(s) (in-sample)",
                          "fit % (median)", "fit % 90 % interval"], rows, left=(0,)))
        text = (f"Log predictive density: {per:.3f} nats per sample and output "
                f"({h['lpd']:.0f} nats in total). Positions are in m, so the value depends "
                "on that unit; only differences mean something.")
        if ref is not None and math.isfinite(float(ref)):
            d = float(ref) - float(per)
            text += (f" The fitted record scores {float(ref):.3f} nats per sample: the "
                     f"held-out record is predicted {abs(d):.2f} nats per sample "
                     f"{'worse' if d > 0 else 'better'}, a density ratio of "
                     f"{math.exp(min(abs(d), 700)):.3g} per sample.")
        out += f"<p class='muted'>{_e(text)}</p>"
    return out


def _flat(x) -> list[float]:
    out = []
    for v in x:
        out.extend(_flat(v) if isinstance(v, list) else [float(v)])
    return out


def _section_bode(folder: Path) -> str:
    return "<h2 id='bode'>Bode diagram with credible bands</h2>" + _img(folder, "bode.png")


def _verdict_word(d: dict) -> str:
    if d["detected"]:
        return "<span class='bad'>fails</span>"
    return "<span class='ok'>passes</span>"


def _test_cell(d: dict) -> str:
    p = d.get("p_value")
    if p is not None:
        return f"p = {_num(p, '.2g')}"
    thr = d.get("threshold")
    if thr is not None:
        return f"statistic {_num(d.get('statistic'), '.3g')} vs threshold {_num(thr, '.3g')}"
    return f"statistic {_num(d.get('statistic'), '.3g')} (rule in summary)"


def _section_residuals(s: dict, folder: Path) -> str:
    res = s.get("crosscheck", {}).get("residuals", [])
    rows = []
    for r in res:
        rows.append([_e(r["experiment"]), _e(", ".join(f"{1e3 * v:.3f}" for v in r["rms_m"])),
                     _e(", ".join(f"{v:.2f}" for v in r["fit_percent"])),
                     _e(", ".join(f"{v:.3f}" for v in r["acf_lag1"])),
                     "&plusmn;" + _num(r["white_band"], ".3f")])
    band = next((r["white_band"] for r in res if r.get("white_band") is not None), None)
    lag1 = [abs(v) for r in res for v in r.get("acf_lag1", []) if v is not None]
    expl = ("<p class='muted'>Residual = measured minus model output at the posterior median. "
            "Lag-1 autocorrelation: correlation of each residual sample with the next one. "
            "Residuals that are only measurement noise (white) give a value inside the "
            "white-noise limit, the 95 % range of a white sequence of this length "
            "(&plusmn;1.96/&radic;N)")
    if band is not None and lag1:
        expl += (f"; here the limit is &plusmn;{band:.3f} and the residuals reach "
                 f"{max(lag1):.3f}")
        if max(lag1) > band:
            expl += (", so they are a slowly varying signal the model misses, not noise")
    expl += ".</p>"
    out = ("<h2 id='residuals'>Residual diagnostics</h2>" + expl
           + _table(["experiment", "RMS (mm, per output)", "fit % (per output)",
                     "lag-1 autocorrelation", "white-noise limit"], rows))
    diag_rows = []
    for r in res:
        for d in r.get("diagnostics", []):
            if "error" in d:
                diag_rows.append([_e(r["experiment"]), _e(d["name"]), "&ndash;", "&ndash;",
                                  "", _e(d["error"])])
                continue
            diag_rows.append([_e(r["experiment"]), _e(d["name"].replace("_", " ")),
                              _verdict_word(d), _test_cell(d),
                              _e(", ".join(d["suggests"]).replace("_", " ")),
                              _e(d["summary"])])
    if diag_rows:
        out += ("<p class='muted'>Tests of <code>bayesmodal.discrepancy.checks</code> on the "
                "residuals at the posterior median. A test fails when its p-value is below its "
                "significance level (1 %, family-wise) or its statistic passes its "
                "threshold.</p>"
                + _table(["experiment", "check", "result (fails: effect found)", "test",
                          "suggests", "summary"],
                         diag_rows, left=(0, 1, 2, 3, 4, 5)))
    return out + _img(folder, "residuals.png") + _img(folder, "residual_acf.png")


def _section_extras(s: dict) -> str:
    out = ""
    ext = s.get("extensions") or {}
    if ext:
        rows = []
        for name, e in ext.items():
            iv = e.get("intervals") or {}
            params = ", ".join(
                f"{k} = {v:.4g}" + (f" [{iv[k][0]:.4g}, {iv[k][1]:.4g}]" if k in iv else "")
                for k, v in e["params"].items())
            lin = e.get("linear_fit_percent")
            rows.append([_e(name), _e(", ".join(f"{v:.2f}" for v in _flat(e["fit_percent"]))),
                         _e(", ".join(f"{v:.2f}" for v in _flat(lin)) if lin else "-"),
                         _e(params), _e(e["method"])])
        out += ("<h2 id='extensions'>Model extensions</h2>"
                + _table(["extension", "fit %", "linear fit %", "parameters", "method"], rows,
                         left=(0, 3, 4)))
    ev = s.get("evidence")
    if ev:
        out += ("<h2 id='evidence'>Evidence</h2>"
                + _table(["ln Z", "error", "information (nats)", "likelihood calls", "live points"],
                         [[_num(ev["log_z"], ".2f"), _num(ev["log_z_err"], ".2f"),
                           _num(ev["information_nats"], ".1f"), _e(ev["n_calls"]),
                           _e(ev["nlive"])]]))
    warn = s.get("warnings") or []
    if warn:
        out += ("<h2 id='warnings'>Warnings during the run</h2><ul>"
                + "".join(f"<li>{_e(w)}</li>" for w in warn[:50]) + "</ul>")
    return out


def render_report(run_dir: str | os.PathLike, *, state: str | None = None) -> str:
    """The HTML text of a run folder's report.

    Parameters
    ----------
    run_dir : str or path
        Folder with ``summary.json`` (and optionally the plots, ``status.json``,
        ``timing.json``, ``config.toml``).
    state : str, optional
        Run state to show (default: from ``status.json``).

    Returns
    -------
    str

    Raises
    ------
    ConfigError
        When the folder has no ``summary.json``.
    """
    folder = Path(run_dir)
    sp = folder / "summary.json"
    if not sp.is_file():
        raise ConfigError(f"{folder}: no summary.json (the run has not finished)")
    s = json.loads(sp.read_text(encoding="utf-8"))
    stp = folder / "status.json"
    status = json.loads(stp.read_text(encoding="utf-8")) if stp.is_file() else {}
    if state is not None:
        status = {**status, "state": state}
    tp = folder / "timing.json"
    timing = json.loads(tp.read_text(encoding="utf-8")) if tp.is_file() else {}
    cp = folder / "config.toml"
    config_text = cp.read_text(encoding="utf-8") if cp.is_file() else json.dumps(
        s.get("run", {}).get("config", {}), indent=2)
    name = s.get("run", {}).get("name", folder.name)
    nav = "".join(f"<a href='#{a}'>{_e(t)}</a>" for a, t in (
        ("verdict", "verdict"), ("parameters", "parameters"), ("modal", "modal"),
        ("residuals", "residuals"), ("predictive", "predictive"), ("bode", "Bode"),
        ("convergence", "convergence"), ("run", "run"), ("traces", "traces")))
    trace = _img(folder, "trace.png")
    body = "\n".join([
        f"<h1>bayesmodal run: {_e(name)}</h1>",
        f"<p class='muted'>{_e(s.get('damping'))} damping, {_e(s.get('noise'))} noise"
        f"{_e(_noise_scale_note(s))}; state {_e(status.get('state', '?'))}</p>",
        _section_verdict(s),
        f"<nav>{nav}</nav>",
        _section_parameters(s, folder),
        _section_modal(s, folder),
        _section_residuals(s, folder),
        _section_predictive(s, folder),
        _section_bode(folder),
        _section_convergence(s, folder),
        _section_run(s, status, config_text, timing),
        _section_extras(s),
        ("<h2 id='traces'>Walker traces</h2>" + trace) if trace else "",
    ])
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>bayesmodal run {_e(name)}</title><style>{_CSS}</style></head>"
            f"<body>\n{body}\n</body></html>\n")


def write_report(run_dir: str | os.PathLike, *, state: str | None = None) -> Path:
    """Render and write ``report.html`` into the run folder (atomically); returns its path."""
    folder = Path(run_dir)
    return atomic_write_text(folder / "report.html", render_report(folder, state=state))
