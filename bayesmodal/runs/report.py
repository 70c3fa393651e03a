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

__all__ = ["render_report", "write_report", "REPORT_IMAGES"]

#: Plots shown in the report when present: file name -> (section, caption).
REPORT_IMAGES = {
    "trace.png": ("convergence", "Trace of every walker (retained draws) and marginals."),
    "predictive.png": ("predictive", "Posterior predictive: measured positions, median "
                       "prediction and 90 % band of replicated measurements."),
    "bode.png": ("bode", "Bode diagram of the posterior with 90 % credible bands."),
    "modal_intervals.png": ("modal", "Posterior intervals of the modal quantities "
                            "(least-squares values marked)."),
    "corner.png": ("parameters", "Pairwise posterior marginals (least-squares estimate "
                   "marked)."),
    "residuals.png": ("residuals", "Residuals at the posterior median."),
    "residual_acf.png": ("residuals", "Autocorrelation of the residuals; white residuals "
                         "stay inside the grey band."),
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
    if name in rows:
        return rows[name]["unit"]
    if name.startswith("sigma"):
        return "m"
    return ""


def _section_run(s: dict, status: dict, config_text: str, timing: dict) -> str:
    run = {**s.get("run", {}), **timing}  # timings live in timing.json
    cfg = run.get("config", {})
    items = [
        ("state", _e(status.get("state", "?"))),
        ("configuration", _e(run.get("config_source", ""))),
        ("configuration hash", f"<code>{_e(run.get('config_hash', ''))}</code>"),
        ("model", _e(f"{s.get('damping')} damping, {s.get('noise')} noise")),
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
    return (f"<h2 id='convergence'>Convergence</h2><div class='verdict {cls}'>"
            f"<b>{'Converged' if ok else 'Not converged'}</b>: {_e(verdict)}</div>"
            + _table(["check", "value"], rows)
            + "<details><summary>Integrated autocorrelation time per parameter (steps)"
              "</summary>" + _table(["parameter", "tau"], tau) + "</details>"
            + _img(folder, "trace.png"))


def _section_parameters(s: dict, folder: Path) -> str:
    prob = s.get("prob", 0.9)
    lsq = {r["quantity"]: r for r in s.get("lsq_comparison", [])}
    rows = []
    for nm, iv in s["parameters"].items():
        r = lsq.get(nm)
        rows.append([_e(nm), _e(_unit(nm, lsq)), _num(iv["median"]),
                     _interval(iv["lo"], iv["hi"]), _interval(iv["hdi_lo"], iv["hdi_hi"]),
                     _num(r["lsq"]) if r else "&ndash;", _yes(r["inside"]) if r else "&ndash;"])
    pct = f"{100 * prob:.0f} %"
    return ("<h2 id='parameters'>Parameters</h2>"
            + _table(["parameter", "unit", "median", f"{pct} interval (equal-tailed)",
                      f"{pct} HDI", "least squares", "LSQ inside"], rows, left=(0, 1))
            + _img(folder, "corner.png"))


def _section_modal(s: dict, folder: Path) -> str:
    prob = s.get("prob", 0.9)
    lsq = {r["quantity"]: r for r in s.get("lsq_comparison", [])}
    lsce = s.get("crosscheck", {}).get("lsce", [])
    head = ["mode", "quantity", "unit", "posterior median", f"{100 * prob:.0f} % interval",
            "least squares"]
    head += [f"LSCE {c['experiment']}" for c in lsce]
    rows = []
    n = len(s["omega_rad_s"]["median"])
    for i in range(n):
        for key, label, unit, col in (("omega_rad_s", "omega", "rad/s", "omega_matched"),
                                      ("zeta", "zeta", "-", "zeta_matched"),
                                      ("damped_rad_s", "omega_d", "rad/s", None)):
            iv = s[key]
            lo, hi = iv["lo"][i], iv["hi"][i]
            r = lsq.get(f"{label}_{i + 1}")
            cells = [_e(i + 1), _e(label), _e(unit), _num(iv["median"][i]),
                     _interval(lo, hi), _num(r["lsq"]) if r else "&ndash;"]
            for c in lsce:
                if col is None:
                    cells.append("")
                    continue
                v = c[col][i] if i < len(c[col]) else None
                if v is None or not math.isfinite(float(v)):
                    cells.append("&ndash;")
                else:
                    inside = lo <= float(v) <= hi
                    cls = "ok" if inside else "bad"
                    cells.append(f"<span class='{cls}'>{_num(v)}</span>")
            rows.append(cells)
    notes = "".join(f"<li>LSCE on {_e(c['experiment'])}: {_e(_clip(c['error']))}</li>"
                    for c in lsce if c.get("error"))
    text = ("<p class='muted'>LSCE (least-squares complex exponential, "
            "<code>bayesmodal.ema</code>) uses only the measured input and outputs, not the "
            "rig model; green: inside the posterior interval, red: outside.</p>"
            if lsce else "")
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
        rows = [[_e(", ".join(h["experiments"])), _num(h["lpd"], ".1f"),
                 _num(h["lpd_per_obs"], ".4f"),
                 _e(", ".join(f"{v:.1f}" for v in _flat(h["fit_percent_median"]))),
                 _e(", ".join(f"[{a:.1f}, {b:.1f}]" for a, b in
                              zip(_flat(h["fit_percent_lo"]), _flat(h["fit_percent_hi"]),
                                  strict=True)))]]
        out += ("<h3>Held-out records</h3>"
                + _table(["records", "log predictive density", "per observation",
                          "fit % (median)", "fit % 90 % interval"], rows, left=(0,)))
    return out


def _flat(x) -> list[float]:
    out = []
    for v in x:
        out.extend(_flat(v) if isinstance(v, list) else [float(v)])
    return out


def _section_bode(folder: Path) -> str:
    return "<h2 id='bode'>Bode diagram with credible bands</h2>" + _img(folder, "bode.png")


def _section_residuals(s: dict, folder: Path) -> str:
    res = s.get("crosscheck", {}).get("residuals", [])
    rows = []
    for r in res:
        rows.append([_e(r["experiment"]), _e(", ".join(f"{1e3 * v:.4f}" for v in r["rms_m"])),
                     _e(", ".join(f"{v:.2f}" for v in r["fit_percent"])),
                     _e(", ".join(f"{v:.3f}" for v in r["acf_lag1"])),
                     _num(r["white_band"], ".3f")])
    out = ("<h2 id='residuals'>Residual diagnostics</h2>"
           + _table(["experiment", "RMS (mm)", "fit %", "lag-1 ACF", "white band"], rows))
    diag_rows = []
    for r in res:
        for d in r.get("diagnostics", []):
            if "error" in d:
                diag_rows.append([_e(r["experiment"]), _e(d["name"]), "&ndash;", "&ndash;",
                                  "", _e(d["error"])])
                continue
            diag_rows.append([_e(r["experiment"]), _e(d["name"]),
                              "<span class='bad'>yes</span>" if d["detected"] else "no",
                              _num(d["p_value"], ".2g"), _e(", ".join(d["suggests"])),
                              _e(d["summary"])])
    if diag_rows:
        out += ("<p class='muted'>Tests of <code>bayesmodal.diagnostics</code> on the residuals "
                "at the posterior median.</p>"
                + _table(["experiment", "diagnostic", "detected", "p", "suggests", "summary"],
                         diag_rows, left=(0, 1, 4, 5)))
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
        ("run", "run"), ("convergence", "convergence"), ("parameters", "parameters"),
        ("modal", "modal"), ("predictive", "predictive"), ("bode", "Bode"),
        ("residuals", "residuals")))
    body = "\n".join([
        f"<h1>bayesmodal run: {_e(name)}</h1>",
        f"<p class='muted'>{_e(s.get('damping'))} damping, {_e(s.get('noise'))} noise; "
        f"state {_e(status.get('state', '?'))}</p>",
        f"<nav>{nav}</nav>",
        _section_run(s, status, config_text, timing),
        _section_convergence(s, folder),
        _section_parameters(s, folder),
        _section_modal(s, folder),
        _section_predictive(s, folder),
        _section_bode(folder),
        _section_residuals(s, folder),
        _section_extras(s),
    ])
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>bayesmodal run {_e(name)}</title><style>{_CSS}</style></head>"
            f"<body>\n{body}\n</body></html>\n")


def write_report(run_dir: str | os.PathLike, *, state: str | None = None) -> Path:
    """Render and write ``report.html`` into the run folder (atomically); returns its path."""
    folder = Path(run_dir)
    return atomic_write_text(folder / "report.html", render_report(folder, state=state))
