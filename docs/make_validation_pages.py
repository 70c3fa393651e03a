"""Write the tables of the Validation pages (docs/validation/*.md) from the studies'
stored outputs in docs/figures/.

    python docs/make_validation_pages.py          # rewrite the generated blocks
    python docs/make_validation_pages.py --check  # exit 1 if a committed page differs

A page is written by hand around blocks between two marker comments::

    <!-- generated: NAME -->
    ...
    <!-- end generated: NAME -->

and this script replaces what lies between the markers with ``BLOCKS[NAME]`` rendered from
the stored output.  Each block ends with the stamp the script wrote into its output
(date, commit, machine: ``docs/_stamp.py``) or "not recorded" when the output has none.
The tables of the ``docs/make_*.py`` studies are rendered by the studies' own functions
(``markdown``/``table``), the ones the scripts print; nothing is computed again.
``tests/test_validation_pages.py`` renders every block in memory and compares it with the
committed page.
"""

from __future__ import annotations

import argparse
import importlib
import json
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FIGURES = HERE / "figures"
PAGES = HERE / "validation"
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

_BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w-]+) -->\n)(?P<body>.*?)"
                    r"(<!-- end generated: (?P=name) -->)", re.S)


def _json(name: str):
    return json.loads((FIGURES / name).read_text(encoding="utf-8"))


def _script(name: str):
    """The study script ``docs/<name>.py`` as a module (its renderers; nothing runs)."""
    return importlib.import_module(name)


def stamp_line(stamp: dict | None, *, what: str = "") -> str:
    """One line: the stamp of a stored output, or "not recorded"."""
    head = f"Stamp{' of ' + what if what else ''}: "
    if not stamp:
        return head + "date, commit and machine not recorded in the stored output."
    return (head + f"date {stamp.get('date') or 'not recorded'}, commit "
            f"{stamp.get('commit') or 'not recorded'}, machine "
            f"{stamp.get('machine') or 'not recorded'}.")


def _studies_stamps(out: dict) -> str:
    """Stamp lines of a file of labelled studies (one stamp per study)."""
    stamps = {label: s.get("stamp") for label, s in out.items()}
    if not any(stamps.values()):
        return stamp_line(None)
    return "\n\n".join(stamp_line(s, what=label) for label, s in stamps.items())


# ---- renderers: one per block -------------------------------------------------------

def _uncertainty() -> str:
    out = _json("uncertainty.json")
    return (_script("make_uncertainty_table").table(out).rstrip() + "\n\n"
            + _studies_stamps(out))


def _calibration() -> str:
    out = _json("calibration.json")
    return _script("make_calibration_table").markdown(out) + "\n" + _studies_stamps(out)


def _noise_scale() -> str:
    out = _json("noise_scale.json")
    return _script("make_noise_scale_table").markdown(out) + "\n" + _studies_stamps(out)


def _scaled_noise() -> str:
    out = _json("scaled_noise_check.json")
    return _script("make_scaled_noise_check").table(out) + "\n" + stamp_line(out.get("stamp"))


def _temperature() -> str:
    # the script writes this table beside its JSON from the calibration's own objects
    out = _json("temperature.json")
    text = (FIGURES / "temperature.md").read_text(encoding="utf-8").rstrip()
    return text + "\n\n" + stamp_line(out.get("stamp"))


def _discrepancy_figures() -> str:
    out = _json("discrepancy.json")
    return _script("make_discrepancy_figures").table(out) + "\n" + stamp_line(out.get("stamp"))


def _discrepancy_table() -> str:
    out = _json("discrepancy_table.json")
    return (_script("make_discrepancy_table").markdown(out["joint"], out["loro"]) + "\n\n"
            + stamp_line(out.get("stamp")))


def _end_stop() -> str:
    out = _json("end_stop_check.json")
    return _script("make_end_stop_check").table(out) + "\n" + stamp_line(out.get("stamp"))


def _cart3() -> str:
    out = _json("impulses_cart3_check.json")
    lines = [_script("make_impulses_cart3_check").table(out), stamp_line(out.get("stamp"))]
    if "multistart" in out:
        lines.append("\n" + stamp_line(out["multistart"].get("stamp"), what="the multistart"))
    return "\n".join(lines)


def _target_front() -> str:
    out = _json("target_front.json")
    return _script("make_target_front").table(out) + "\n" + stamp_line(out.get("stamp"))


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _detection() -> str:
    """benchmarks/detection.py's printed table: rate and standard error per effect."""
    out = _json("detection.json")
    lines = ["| hidden effect | data sets | rate | standard error | wrong answers |",
             "|---|---|---|---|---|"]
    for eff, t in out["table"].items():
        label = "none: false positives" if eff == "none" else eff
        rate = 1 - t["rate"] if eff == "none" else t["rate"]
        lines.append(f"| {label} | {t['n']} | {_pct(rate)} | {_pct(t['se'])} | "
                     f"{', '.join(t['confusions']) or '-'} |")
    lines.append("")
    lines.append(f"Settings: {out['seeds']} seeds per effect, {out['nulls']} null data sets, "
                 f"{out['calibration_nulls']} calibration nulls, {out['samples']} samples; "
                 f"complete: {'yes' if out['complete'] else 'no'}; wall time "
                 f"{out['wall_seconds'] / 60:.0f} min.")
    return "\n".join(lines) + "\n\n" + stamp_line(out.get("stamp"))


def _pairs(name: str) -> Callable[[], str]:
    """benchmarks/detection_pairs.py's printed table of one stored run."""
    def render() -> str:
        out = _json(name)
        lines = ["| case | data sets | rate | one-sided 95 % bound | median time per data set |",
                 "|---|---|---|---|---|"]
        for case, t in out["table"].items():
            if case == "none":
                lines.append(f"| null data: false positives | {t['n']} | {_pct(t['rate'])} | "
                             f"upper {_pct(t['upper_95'])} | {t['median_seconds']:.0f} s |")
            else:
                lines.append(f"| {case} | {t['n']} | {_pct(t['rate'])} | "
                             f"lower {_pct(t['lower_95'])} | {t['median_seconds']:.0f} s |")
        a = out["args"]
        lines.append("")
        lines.append(f"Settings: {a['seeds']} seeds per case, {a['nulls']} null data sets, "
                     f"{a.get('records', 1)} training record(s) per data set, at most "
                     f"{a['max_effects']} effects, {a['samples']} samples; complete: "
                     f"{'yes' if out['complete'] else 'no'}; wall time "
                     f"{out['wall_seconds'] / 60:.0f} min.")
        stamp = out.get("stamp")
        if not stamp and "code" in out:
            lines.append("")
            lines.append("Stamp: date and machine not recorded in the stored output; the "
                         "commits are recorded per group of rows under `code`.")
            return "\n".join(lines)
        return "\n".join(lines) + "\n\n" + stamp_line(stamp)
    return render


def _rows_table(name: str) -> Callable[[], str]:
    """The rows of benchmarks/detection_layouts.py or detection_accel.py: rate and exact
    one-sided 95 % bound per layout and case, with what was named where it was missed."""
    return lambda: _layouts(name)


def _layouts(name: str) -> str:
    from scipy import stats

    out = _json(name)
    lines = ["| layout | case | data sets | rate | one-sided 95 % bound | named instead |",
             "|---|---|---|---|---|---|"]
    keys = sorted({(r["layout"], r["case"]) for r in out["rows"]},
                  key=lambda k: (k[0], k[1] != "none", k[1]))
    for layout, case in keys:
        rows = [r for r in out["rows"] if (r["layout"], r["case"]) == (layout, case)]
        n, k = len(rows), sum(bool(r["correct"]) for r in rows)
        missed = sorted({" + ".join(f"{e}{'' if w is None else ' ' + str(w)}"
                                    for e, w in r["found"]) or "none"
                         for r in rows if not r["correct"]})
        if case == "none":  # the rate of false positives and its upper bound
            fp = n - k
            upper = 1.0 if fp == n else float(stats.beta.ppf(0.95, fp + 1, n - fp))
            lines.append(f"| {layout} | null data: false positives | {n} | {_pct(fp / n)} | "
                         f"upper {_pct(upper)} | {', '.join(missed) or '-'} |")
        else:
            lower = 0.0 if k == 0 else float(stats.beta.ppf(0.05, k, n - k + 1))
            lines.append(f"| {layout} | {case} | {n} | {_pct(k / n)} | lower {_pct(lower)} | "
                         f"{', '.join(missed) or '-'} |")
    lines.append("")
    slow = (", then half as many of a slow triangle of the drive"
            if any(r.get("slow_drive") for r in out["rows"]) else "")
    lines.append(f"Settings: {out['samples']} samples per record{slow}; median time per data "
                 f"set {np.median([r['seconds'] for r in out['rows']]):.0f} s.")
    return "\n".join(lines) + "\n\n" + stamp_line(out.get("stamp"))


def _records_coverage() -> str:
    """benchmarks/records_coverage.py's summary: coverage of the 90 % intervals."""
    out = _json("records_coverage.json")["summary"]
    qs = list(out["joint"])
    lines = ["| model | " + " | ".join(qs) + " |", "|---" * (len(qs) + 1) + "|"]
    for label, name in (("joint", "four records, gain per record from its population"),
                        ("single", "one record at a time, one gain")):
        lines.append(f"| {name} | " + " | ".join(f"{out[label][q]:.2f}" for q in qs) + " |")
    lines.append("")
    lines.append(f"{out['replicates']} replicates (binomial standard error "
                 f"{out['binomial_se']:.2f}); wall time {out['wall_time_s'] / 60:.0f} min.")
    return "\n".join(lines) + "\n\n" + stamp_line(out.get("stamp"))


def _coverage_window() -> str:
    """benchmarks/coverage_window.py's printed table."""
    rows = _json("coverage_window.json")
    lines = ["| AR(1) phi | coverage q05, q50, q95 | P(80-95 %) one output | "
             "P(80-95 %) three outputs | calibrated reference q05, q50, q95 |",
             "|---|---|---|---|---|"]
    for r in rows:
        q, rq = r["coverage_q05_q50_q95"], r["reference_q05_q50_q95"]
        lines.append(f"| {r['phi']} | {q[0]:.3f}, {q[1]:.3f}, {q[2]:.3f} | "
                     f"{r['p_window_one_output']:.3f} | {r['p_window_three_outputs']:.3f} | "
                     f"{rq[0]:.3f}, {rq[1]:.3f}, {rq[2]:.3f} |")
    lines.append("")
    lines.append(f"{rows[0]['records']} simulated records of {rows[0]['n_samples']} samples "
                 "per row.")
    return "\n".join(lines) + "\n\n" + stamp_line(None)


def _threads() -> str:
    """benchmarks/threads.py: one ensemble's log-posterior, serial and in threads."""
    out = _json("threads.json")
    lines = ["| configuration | effects | walkers per call | serial (ms, per round) | "
             "threaded (ms, per round) | speed-up (median round) | same numbers |",
             "|---|---|---|---|---|---|---|"]
    for c in out["configs"]:
        lines.append(f"| {Path(c['config']).name} | {', '.join(c['extensions']) or '-'} | "
                     f"{c['walkers_per_call']} | "
                     f"{', '.join(f'{x:.1f}' for x in c['serial_ms'])} | "
                     f"{', '.join(f'{x:.1f}' for x in c['threaded_ms'])} | "
                     f"{c['speedup']:.2f} | {'yes' if c['equal_bit_for_bit'] else 'no'} |")
    m = out["machine"]
    lines.append("")
    lines.append(f"{out['threads']} threads; machine: {m['cores']} cores, load "
                 f"{', '.join(f'{x:.2f}' for x in m['load_average'])} (1, 5, 15 min) at the "
                 "start.")
    return "\n".join(lines) + "\n\n" + stamp_line(out.get("stamp"))


def _extended_posterior() -> str:
    """benchmarks/extended_posterior.py --json: the friction model's posterior run."""
    d = _json("extended_posterior_lugre.json")
    ext = d["extrapolated"]
    rows = [("configuration", f"`{d['config']}` ({d['extension']})"),
            ("ensembles x walkers x steps (burn)",
             f"{d['ensembles']} x {d['walkers_per_ensemble']} x {d['steps']} ({d['burn']})"),
            ("parameters", str(d["parameters"])),
            ("wall time", f"{d['wall_s'] / 60:.1f} min ({d['wall_s']:.0f} s)"),
            ("CPU time", f"{d['cpu_s']:.0f} s"),
            ("evaluations per CPU second", f"{d['evaluations_per_cpu_s']:.0f}"),
            ("largest R-hat", f"{d['max_rhat']:.3f} (`{d['worst_rhat']}`)"),
            ("smallest bulk ESS", f"{d['min_ess_bulk']:.0f} (`{d['worst_ess']}`)"),
            ("largest autocorrelation time", f"{d['tau_max_steps']:.0f} steps"),
            ("acceptance", f"{d['acceptance']:.2f}"),
            ("converged", "yes" if d["converged"] else "no"),
            ("remarks", "; ".join(d["problems"]) or "-"),
            ("load before, after", f"{d['load_before']}; {d['load_after']}"),
            ("steps per walker for 50 autocorrelation times",
             f"{ext['steps_per_walker']} (about {ext['idle_wall_s_on_2_cores'] / 60:.0f} min "
             "on 2 idle cores)")]
    lines = ["| quantity | value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
    return "\n".join(lines) + "\n\n" + stamp_line(d.get("stamp"))


@dataclass(frozen=True)
class Block:
    """A generated block: the page it sits in, its renderer and the outputs it reads."""

    page: str
    render: Callable[[], str]
    sources: tuple[str, ...]


BLOCKS: dict[str, Block] = {
    "uncertainty": Block("coverage.md", _uncertainty, ("uncertainty.json",)),
    "calibration": Block("coverage.md", _calibration, ("calibration.json",)),
    "records-coverage": Block("coverage.md", _records_coverage, ("records_coverage.json",)),
    "coverage-window": Block("coverage.md", _coverage_window, ("coverage_window.json",)),
    "noise-scale": Block("noise_level.md", _noise_scale, ("noise_scale.json",)),
    "scaled-noise": Block("noise_level.md", _scaled_noise, ("scaled_noise_check.json",)),
    "temperature": Block("noise_level.md", _temperature,
                         ("temperature.json", "temperature.md")),
    "discrepancy-figures": Block("discrepancy.md", _discrepancy_figures,
                                 ("discrepancy.json",)),
    "discrepancy-table": Block("discrepancy.md", _discrepancy_table,
                               ("discrepancy_table.json",)),
    "end-stop": Block("discrepancy.md", _end_stop, ("end_stop_check.json",)),
    "impulses-cart3": Block("discrepancy.md", _cart3, ("impulses_cart3_check.json",)),
    "target-front": Block("discrepancy.md", _target_front, ("target_front.json",)),
    "detection": Block("detection.md", _detection, ("detection.json",)),
    "detection-pairs": Block("detection.md", _pairs("detection_pairs_20.json"),
                             ("detection_pairs_20.json",)),
    "detection-two-records": Block("detection.md", _pairs("detection_pairs_2records.json"),
                                   ("detection_pairs_2records.json",)),
    "detection-layouts": Block("detection.md", _rows_table("detection_layouts.json"),
                               ("detection_layouts.json",)),
    "detection-one-slow": Block("detection.md", _rows_table("detection_one_slow.json"),
                                ("detection_one_slow.json",)),
    "detection-accel": Block("detection.md", _rows_table("detection_accel.json"),
                             ("detection_accel.json",)),
    "threads": Block("performance.md", _threads, ("threads.json",)),
    "extended-posterior": Block("performance.md", _extended_posterior,
                                ("extended_posterior_lugre.json",)),
}


def blocks_in(text: str) -> dict[str, str]:
    """name -> body of every generated block of a page."""
    return {m.group("name"): m.group("body") for m in _BLOCK.finditer(text)}


def render_page(text: str) -> str:
    """``text`` with every generated block rewritten from the stored outputs."""
    def repl(m: re.Match) -> str:
        name = m.group("name")
        if name not in BLOCKS:
            raise KeyError(f"unknown generated block {name!r}")
        return m.group(1) + "\n" + BLOCKS[name].render().rstrip() + "\n\n" + m.group(4)
    return _BLOCK.sub(repl, text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 on a difference")
    args = ap.parse_args(argv)
    stale = []
    for page in sorted({b.page for b in BLOCKS.values()}):
        path = PAGES / page
        text = path.read_text(encoding="utf-8")
        new = render_page(text)
        if new != text:
            stale.append(page)
            if not args.check:
                path.write_text(new, encoding="utf-8")
    if args.check and stale:
        print("stale: " + ", ".join(stale) + " (run python docs/make_validation_pages.py)")
        return 1
    print(("rewrote " if stale else "up to date: ") + ", ".join(stale or ["every page"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
