"""The tables of docs/uncertainty.md: leave-one-record-out on the four measured records.

One command produces every number of the page::

    python docs/make_uncertainty_table.py --workers 2          # about 40 min on 2 cores

For each configuration (model, noise model, per-record layout) it samples the posterior on
three records and predicts the fourth, for each record in turn (``bayesmodal.inference.
crossval``), and writes ``docs/figures/uncertainty.json`` and the markdown tables
``docs/figures/uncertainty.md``.  ``--only NAME`` runs one configuration (the others keep
their stored results).  The first configuration is the single-record model: the impulse record
alone, AR(1) noise, every parameter shared, predicting the other three records.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _stamp import stamp  # noqa: E402

RECORDS = ("data_impulses", "data_steps", "data_sine_sweep_fast", "data_sine_sweep_slow")

#: name -> (noise, per-record layout text, description)
CONFIGS = {
    "shared_ar1": ("ar1", "none", "every parameter shared, AR(1) noise"),
    "gain_offset_ar1": ("ar1", "g_v=hierarchical,v0=hierarchical",
                        "g_v and v0 per record (populations), AR(1) noise"),
    "gain_offset_white": ("white", "g_v=hierarchical,v0=hierarchical",
                          "g_v and v0 per record (populations), white noise"),
    "gain_offset_arp": ("ar:auto", "g_v=hierarchical,v0=hierarchical",
                        "g_v and v0 per record (populations), AR(p) noise, p by BIC (<= 8)"),
    "gain_process": ("process", "g_v=hierarchical",
                     "g_v per record (population), process noise (Kalman filter)"),
}


def _load():
    from bayesmodal.data import find_data, load_experiment

    paths = [find_data(f"ecp210-3dof/{n}.mat") for n in RECORDS]
    if any(p is None for p in paths):
        sys.exit("the measured records are not found: set BAYESMODAL_DATA")
    return [load_experiment(p) for p in paths]


def single_record_baseline(exps, steps: int, seed: int) -> dict:
    """Yesterday's setup: the impulse record alone, AR(1), predicting the other records."""
    from bayesmodal.inference import sample_posterior
    from bayesmodal.inference.predictive import predict_new_record, score_samples
    from bayesmodal.model.system import LinearModel, Rig

    t0 = time.perf_counter()
    run = sample_posterior(exps[:1], LinearModel(Rig(), "free"), noise="ar1", n_walkers=32,
                           n_steps=steps, burn=steps // 2, rng=seed, warn=False)
    rng = np.random.default_rng(seed)
    flat = run.flat_draws
    draws = flat[rng.choice(flat.shape[0], 200, replace=False)]
    out = []
    for e in exps[1:]:
        _, y_pred, ll = predict_new_record(run.likelihood, draws, e, rng=rng)
        out.append(score_samples(e.name, e.y_m, y_pred, ll).to_dict())
    return {"records": out, "max_rhat": float(run.diagnostics.max_rhat),
            "wall_time_s": time.perf_counter() - t0}


def run_config(exps, name: str, steps: int, workers: int, seed: int) -> dict:
    from bayesmodal.inference.crossval import CrossvalSpec, crossval
    from bayesmodal.inference.record_layout import parse_layout

    noise, layout, _ = CONFIGS[name]
    spec = CrossvalSpec(noise=noise, layout=parse_layout(layout), n_walkers=48,
                        n_steps=steps, seed=seed)
    res = crossval(exps, spec, workers=workers, joint=False,
                   progress=lambda line: print(f"  {name}: {line}", flush=True))
    d = res.to_dict()
    d["evaluations_per_s"] = [f.evaluations_per_s for f in res.folds]
    return d


def table(results: dict) -> str:
    lines = []
    for name, res in results.items():
        desc = "impulses alone, AR(1), every parameter shared (the single-record model)" \
            if name == "single_impulses" else CONFIGS[name][2]
        lines.append(f"**{name}**: {desc}\n")
        lines.append("| held-out record | 90 % band covers (carts 1, 2, 3) | 50 % band covers "
                     "| width / sd | fit % of median | CRPS / sd | lpd (nats) | max R-hat |")
        lines.append("|---|---|---|---|---|---|---|---|")
        for r in res["records"]:
            pct = lambda xs: ", ".join(f"{100 * x:.0f}" for x in xs)  # noqa: E731
            rh = r.get("max_rhat", res.get("max_rhat", float("nan")))
            lines.append(f"| {r['name']} | {pct(r['coverage_90'])} | {pct(r['coverage_50'])} "
                         f"| {', '.join(f'{w:.2f}' for w in r['width_90'])} "
                         f"| {', '.join(f'{f:.1f}' for f in r['fit_percent'])} "
                         f"| {', '.join(f'{c:.3f}' for c in r['crps'])} "
                         f"| {r['lpd']:.0f} | {rh:.2f} |")
        if "total" in res:
            t = res["total"]
            lines.append(f"\nsummed held-out lpd {t['lpd']:.0f} +- {t['lpd_se']:.0f} nats "
                         f"over {t['n_records']} records; wall time "
                         f"{res.get('wall_time_s', float('nan')) / 60:.1f} min\n")
        else:
            lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000, help="steps per walker per fold")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--only", action="append", default=None,
                    help="configuration(s) to (re)run: single_impulses or one of "
                    + ", ".join(CONFIGS))
    args = ap.parse_args(argv)
    out_json = HERE / "figures" / "uncertainty.json"
    results = json.loads(out_json.read_text()) if out_json.is_file() else {}
    exps = _load()
    names = args.only or ["single_impulses", *CONFIGS]
    for name in names:
        t0 = time.perf_counter()
        print(f"{name} ...", flush=True)
        if name == "single_impulses":
            results[name] = single_record_baseline(exps, args.steps, args.seed)
        else:
            results[name] = run_config(exps, name, args.steps, args.workers, args.seed)
        results[name]["settings"] = {"steps": args.steps, "seed": args.seed}
        results[name]["stamp"] = stamp()
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)
        out_json.write_text(json.dumps(results, indent=1))
        (HERE / "figures" / "uncertainty.md").write_text(table(results))
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
