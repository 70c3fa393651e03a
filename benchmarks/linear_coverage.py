"""Frequentist coverage of the posterior 90 % intervals on replicated synthetic data.

Each replicate simulates the rig (known parameters, impulse-like input) with a fresh noise
record, samples the posterior with emcee, and records whether the 90 % equal-tailed
intervals of omega (3), zeta (3), g_v and the masses (3) contain the true values.  Three
settings:

``ar1/ar1``    AR(1) noise, AR(1) likelihood (matching)
``white/white``  white noise, white likelihood (matching)
``ar1/white``  AR(1) noise, white likelihood (mismatched: overconfident)

Usage::

    python benchmarks/linear_coverage.py --replicates 100 --processes 2 --out coverage.json

The coverage of one quantity over R replicates has binomial standard error
``sqrt(0.9 * 0.1 / R)`` (0.03 for R = 100).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

# Run as a script, this file's folder is sys.path[0], and its name shadows the
# ``coverage`` package that numba probes at import; drop the folder from the path.
_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]
sys.path.insert(0, str(_HERE.parent / "tests"))

import numpy as np  # noqa: E402
from _replicates import map_replicates  # noqa: E402

#: True parameters (proportional damping; free damping uses TRUTH_FREE).
TRUTH_PROPORTIONAL = (6.2, 1.57, 1.46, 1.14, 1.6, 1e-4)
TRUTH_FREE = (6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.3, 0.2)
#: AR(1) noise: innovation standard deviations (m) and coefficients per output.
SIGMA = (2e-5, 2e-5, 2e-5)
PHI = (0.9, 0.8, 0.85)
#: White-noise standard deviation per output, m (the stationary AR(1) level of output 1).
SIGMA_WHITE = (4.6e-5, 4.6e-5, 4.6e-5)

SETTINGS = ("ar1/ar1", "white/white", "ar1/white")


@dataclass(frozen=True)
class Config:
    damping: str = "proportional"
    n_samples: int = 1500
    n_walkers: int = 24
    n_steps: int = 1500
    burn: int = 500
    dt: float = 0.005


def truth_for(damping: str) -> np.ndarray:
    return np.array(TRUTH_PROPORTIONAL if damping == "proportional" else TRUTH_FREE)


def make_experiment(cfg: Config, noise: str, seed: int):
    """One synthetic record: two voltage pulses, ZOH simulation plus a noise draw."""
    from bayesmodal.data import Experiment
    from bayesmodal.inference import simulate_noise
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig

    model = LinearModel(Rig(), cfg.damping)
    t = np.arange(cfg.n_samples) * cfg.dt
    v = np.zeros(cfg.n_samples)
    v[(t >= 0.1) & (t < 0.15)] = 3.0
    v[(t >= 3.0) & (t < 3.05)] = -3.0
    rng = np.random.default_rng([seed, 20240611])
    if noise == "ar1":
        e = simulate_noise(np.array(SIGMA)[None], np.array(PHI)[None], cfg.n_samples, rng)[0]
    else:
        e = simulate_noise(np.array(SIGMA_WHITE)[None], None, cfg.n_samples, rng)[0]
    y = simulate_linear(model, truth_for(cfg.damping), v, cfg.dt) + e
    return model, Experiment(t, v, y, name=f"synthetic-{noise}-{seed}")


def quantities(model, theta: np.ndarray) -> dict[str, np.ndarray]:
    """omega, zeta, g_v and masses of parameter draws, shape (S, ...)."""
    from bayesmodal.inference import propagate_modes

    ms = propagate_modes(model, theta, methods=("eig",))
    n = model.n_carts
    return {"omega": ms.omega_rad_s, "zeta": ms.zeta, "g_v": theta[:, :1],
            "mass": theta[:, 1 : 1 + n]}


def replicate(args: tuple[Config, str, int]) -> dict:
    """Run one replicate; return interval hits per quantity group."""
    cfg, setting, seed = args
    from bayesmodal.inference import credible_interval, sample_posterior

    data_noise, lik_noise = setting.split("/")
    model, exp = make_experiment(cfg, data_noise, seed)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # short chains; convergence is recorded below
        run = sample_posterior(exp, model, noise=lik_noise, n_walkers=cfg.n_walkers,
                               n_steps=cfg.n_steps, burn=cfg.burn, rng=seed, warn=False)
    draws = run.flat_draws[:, : model.n_params]
    post = quantities(model, draws)
    true = quantities(model, truth_for(cfg.damping)[None])
    hits, width = {}, {}
    for k, s in post.items():
        iv = credible_interval(s, 0.9)
        hits[k] = iv.contains(true[k][0]).tolist()
        width[k] = (iv.hi - iv.lo).tolist()
    return {"setting": setting, "seed": seed, "hits": hits, "width": width,
            "converged": run.diagnostics.converged, "max_rhat": run.diagnostics.max_rhat,
            "seconds": time.perf_counter() - t0}


def run_coverage(cfg: Config, settings, replicates: int, processes: int = 1,
                 seed0: int = 0, progress: bool = False) -> list[dict]:
    tasks = [(cfg, s, seed0 + r) for s in settings for r in range(replicates)]
    return map_replicates(replicate, tasks, processes, progress)


def tabulate(results: list[dict]) -> dict:
    """Coverage per setting and quantity group (pooled over components and per component)."""
    table = {}
    for s in sorted({r["setting"] for r in results}, key=SETTINGS.index):
        rs = [r for r in results if r["setting"] == s]
        row = {"replicates": len(rs),
               "converged_fraction": float(np.mean([r["converged"] for r in rs]))}
        for k in rs[0]["hits"]:
            h = np.array([r["hits"][k] for r in rs], dtype=float)  # (R, n_components)
            row[k] = {"coverage": float(h.mean()), "per_component": h.mean(axis=0).tolist(),
                      "se": float(np.sqrt(0.9 * 0.1 / len(rs))),
                      "median_width": np.median([r["width"][k] for r in rs], axis=0).tolist()}
        table[s] = row
    return table


def markdown(table: dict) -> str:
    groups = ["omega", "zeta", "g_v", "mass"]
    lines = ["| data / likelihood | replicates | " + " | ".join(groups) + " |",
             "|---|---|" + "---|" * len(groups)]
    for s, row in table.items():
        cells = []
        for g in groups:
            pc = ", ".join(f"{100 * c:.0f}" for c in row[g]["per_component"])
            cells.append(f"{100 * row[g]['coverage']:.0f} % ({pc})")
        lines.append(f"| {s} | {row['replicates']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--replicates", type=int, default=100)
    p.add_argument("--processes", type=int, default=min(2, os.cpu_count() or 1))
    p.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=SETTINGS)
    p.add_argument("--damping", choices=["proportional", "free"], default="proportional")
    p.add_argument("--samples", type=int, default=Config.n_samples)
    p.add_argument("--walkers", type=int, default=Config.n_walkers)
    p.add_argument("--steps", type=int, default=Config.n_steps)
    p.add_argument("--burn", type=int, default=Config.burn)
    p.add_argument("--out", default=None, help="write the raw results and table as JSON")
    a = p.parse_args(argv)
    cfg = Config(damping=a.damping, n_samples=a.samples, n_walkers=a.walkers,
                 n_steps=a.steps, burn=a.burn)
    t0 = time.perf_counter()
    res = run_coverage(cfg, a.settings, a.replicates, a.processes, progress=True)
    table = tabulate(res)
    print(markdown(table))
    print(f"\n{len(res)} replicates in {time.perf_counter() - t0:.0f} s; binomial standard "
          f"error of one coverage {100 * np.sqrt(0.09 / a.replicates):.1f} points")
    if a.out:
        tmp = a.out + ".tmp"
        with open(tmp, "w") as fh:
            json.dump({"config": cfg.__dict__, "table": table, "results": res}, fh, indent=1)
        os.replace(tmp, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
