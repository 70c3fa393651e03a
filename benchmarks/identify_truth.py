"""Known truth for ``identify``: does the workflow name the hidden effects, and do its
90 % intervals of the natural frequencies and damping ratios cover the truth?

Each replicate draws one rig (tests/identify_records.py: the independent reference
simulators, noise and counts) with stick-slip friction on every cart, a drive dead band
and an amplifier offset, optionally a per-record change of every spring
(``--stiffness-sd``, drawn per replicate from 0.5-2 % when given as ``auto``), writes four
records and runs the whole workflow on them.  It reports, over the replicates, how often
the diagnosis names exactly the hidden effects and how often each interval covers the
truth, with the binomial standard error of that rate.

    python benchmarks/identify_truth.py --layout one_cart --replicates 100 --out out/truth
    python benchmarks/identify_truth.py --layout one_cart --replicates 100 \\
        --stiffness-sd auto --population --out out/truth_population

The issue's target: 80-97 % coverage of the 90 % intervals over at least 100 replicates.
A replicate takes minutes (the diagnosis and two posteriors); ``--steps`` shortens the
final posterior for a quick look (its intervals are then those of an unconverged chain).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from identify_records import write_records  # noqa: E402

from bayesmodal.inference.propagate import propagate_modes  # noqa: E402
from bayesmodal.model.rigs import load_rig  # noqa: E402
from bayesmodal.model.system import LinearModel  # noqa: E402
from bayesmodal.runs.config import load_config  # noqa: E402
from bayesmodal.runs.identify import identify, spec_from_config  # noqa: E402

HIDDEN = {"coulomb_friction", "drive_deadband", "input_offset"}
PRESETS = {"one_cart": "ecp210-1cart", "two_frame_at_drive": "ecp210-2cart-frame-at-drive",
           "three_chain": "ecp210-3cart"}


def _config(paths, preset: str, steps: int, population: bool) -> str:
    files = ", ".join(f'"{p}"' for p in paths)
    burn = steps // 6
    return (f'[data]\nfiles = [{files}]\n[rig]\nfile = "{preset}"\n'
            "[records]\nper_record = { g_v = \"hierarchical\" }\n"
            "[sampler]\nwalkers = 32\nsteps = 3000\nburn = 1000\nthin = 20\nseed = 1\n"
            "[outputs]\npredictive_draws = 20\npointwise_loglik = false\nplots = false\n"
            "[crossval]\nenabled = false\n"
            f"[identify]\nenabled = true\nmax_effects = 3\nsteps = {steps}\n"
            f"burn = {burn}\nprune = {burn // 2}\n"
            f"population = {'true' if population else 'false'}\n")


def replicate(layout: str, seed: int, out: Path, *, steps: int, stiffness_sd,
              population: bool) -> dict:
    """One rig, four records, the whole workflow; what it found and what it covered."""
    rng = np.random.default_rng(seed)
    preset = PRESETS[layout]
    rig = load_rig(preset)
    n = rig.n_carts
    friction = {c + 1: (fc, fc * rng.uniform(1.0, 1.3))
                for c, fc in enumerate(rng.uniform(0.2, 0.6, n))}
    v_dead, v_off = rng.uniform(0.02, 0.05), rng.uniform(0.02, 0.05) * rng.choice([-1, 1])
    sd = rng.uniform(0.005, 0.02) if stiffness_sd == "auto" else float(stiffness_sd)
    folder = out / f"{layout}-{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    paths, theta = write_records(folder, layout, seed, n_records=4, n_samples=2400,
                                 v_offset=v_off, v_dead=v_dead, friction=friction,
                                 stiffness_sd=sd)
    cfg_path = folder / "identify.toml"
    cfg_path.write_text(_config(paths, preset, steps, population))
    t0 = time.perf_counter()
    res = identify(spec_from_config(load_config(cfg_path)), folder / "out")
    truth = propagate_modes(LinearModel(rig, "free"), theta[None], methods=("eig",))
    fin = res.summary["final"]["modal"]
    covered = {}
    for key, true in (("omega_rad_s", truth.omega_rad_s[0]), ("zeta", truth.zeta[0])):
        iv = fin[key]
        covered[key] = [bool(lo <= t <= hi) for t, lo, hi in
                        zip(true, iv["lo"], iv["hi"], strict=True)]
    return {"seed": seed, "found": sorted(res.summary["found"]),
            "named": set(res.summary["found"]) == HIDDEN, "covered": covered,
            "stiffness_sd": sd, "wall_s": time.perf_counter() - t0,
            "converged": res.summary["final"]["converged"]}


def summarize(rows: list[dict]) -> dict:
    """Rates over the replicates with their binomial standard errors."""
    def rate(flags):
        k, m = int(np.sum(flags)), len(flags)
        p = k / m if m else float("nan")
        return {"k": k, "n": m, "rate": p, "se": float(np.sqrt(p * (1 - p) / m)) if m
                else float("nan")}
    out = {"named": rate([r["named"] for r in rows])}
    for key in ("omega_rad_s", "zeta"):
        out[key] = rate([c for r in rows for c in r["covered"][key]])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", choices=sorted(PRESETS), default="one_cart")
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--seed0", type=int, default=1)
    ap.add_argument("--steps", type=int, default=6000,
                    help="steps of the final posterior (default %(default)s)")
    ap.add_argument("--stiffness-sd", default="0",
                    help="relative sd of the per-record spring change, or auto (0.5-2 %%)")
    ap.add_argument("--population", action="store_true",
                    help="the final model's masses per record from a population")
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    out = Path(args.out)
    rows = []
    for seed in range(args.seed0, args.seed0 + args.replicates):
        rows.append(replicate(args.layout, seed, out, steps=args.steps,
                              stiffness_sd=args.stiffness_sd, population=args.population))
        print(json.dumps(rows[-1]), flush=True)
    summary = summarize(rows)
    (out / "summary.json").write_text(json.dumps({"args": vars(args), "rows": rows,
                                                  "summary": summary}, indent=1))
    for key, r in summary.items():
        print(f"{key}: {r['k']} of {r['n']} ({100 * r['rate']:.0f} +- {100 * r['se']:.0f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
