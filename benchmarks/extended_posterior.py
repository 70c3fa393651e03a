"""Wall time to a converged posterior of an extended model on the four measured records.

Runs the sampler of a run configuration (default ``runs/records_friction.toml``: LuGre
friction and one input offset on the impulses, steps and both sweeps, per-record drive
gain hierarchical, walkers started from the Laplace approximation at the posterior mode)
and prints what issue 16 asks for: wall time, CPU time, the largest R-hat, the smallest
bulk ESS, likelihood evaluations per second, and the machine's load while it ran.

``--ensembles K`` runs K independent ensembles (seeds ``seed .. seed + K - 1``) in K
processes and pools them: the numba kernels are single-threaded, so on 2 cores two
ensembles use both, and R-hat then also compares ensembles started from different draws.

When the run converges, the line ``converged from`` gives the shortest prefix of the
chain from which every longer checked prefix (every ``--every`` steps) is converged
(``bayesmodal.inference.converged_from``: what a shorter run with the same seeds would
have reported) and the wall time to that step, the start plus the sampling's wall time in
proportion to its steps: the run length the configuration could have asked for.

When the run falls short, the line ``extrapolated`` gives the steps per walker that the
measured autocorrelation time says are needed for bulk ESS > 400 over all walkers
(``ESS ~ n_walkers * kept_steps / tau``) and their CPU time at the measured CPU cost per
evaluation: on an idle machine wall time = CPU time / (cores used).  Load from other
processes only stretches wall time; the CPU figures do not depend on it.

Usage::

    python benchmarks/extended_posterior.py                         # the config as it is
    python benchmarks/extended_posterior.py --steps 600 --burn 200  # a short probe
    python benchmarks/extended_posterior.py --init ball             # the old start
    python benchmarks/extended_posterior.py runs/records_friction.toml --ensembles 2 \
        --save chain.npz        # keep the chain to dissect a run that falls short
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(_ROOT))

ESS_TARGET = 400.0
RHAT_TARGET = 1.05
MIN_N_OVER_TAU = 50.0


def _load() -> str:
    from bayesmodal.bench import machine_load

    load = machine_load()["load_average"]
    if load is None:
        return "load average unavailable"
    return "load average (1, 5, 15 min) " + " ".join(f"{x:.2f}" for x in load)


def _one(job: dict) -> dict:
    """One ensemble: its post-burn-in chain in sampling coordinates and its costs."""
    from bayesmodal.inference import sample_posterior
    from bayesmodal.inference.threads import resolve_threads
    from bayesmodal.runs.config import load_config
    from bayesmodal.runs.runner import prepare_run

    cfg = load_config(job["config"])
    prep = prepare_run(cfg)
    threads = resolve_threads(job["threads"] or cfg.sampler.threads)
    steps = job["steps"] or cfg.sampler.steps
    burn = cfg.sampler.burn if job["burn"] is None else job["burn"]
    walkers = job["walkers"] or cfg.sampler.walkers
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        smp = cfg.sampler
        run = sample_posterior(
            list(prep.experiments), prep.model, noise=prep.noise or cfg.likelihood.noise,
            priors=prep.priors, n_walkers=walkers, n_steps=steps, burn=burn,
            moves=prep.moves, rng=job["seed"], warn=False, extension=prep.extension,
            restart=smp.restart if smp.restart is not None and smp.restart < burn else None,
            prune=smp.prune if smp.prune is not None and smp.prune < burn else None,
            layout=cfg.layout, temperature=cfg.likelihood.temperature,
            init=job["init"] or smp.init,
            backend=job["backend"], progress=job["progress"],
            threads=threads)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    z = run.priors.to_sampling(run.chain[run.burn :])
    return {"z": z, "lp": run.log_prob[run.burn :], "acceptance": run.acceptance,
            "names": run.names, "wall_s": wall,
            "cpu_s": cpu, "sampling_s": run.elapsed_s, "n_evaluations": run.n_evaluations,
            "walkers": walkers, "steps": steps, "burn": burn,
            "extension": run.extension_name, "seed": job["seed"],
            "median": np.median(run.flat_draws, axis=0),
            "threads": threads}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default=str(_ROOT / "runs/records_friction.toml"))
    ap.add_argument("--steps", type=int, default=None, help="steps per walker (config's)")
    ap.add_argument("--burn", type=int, default=None, help="burn-in steps (config's)")
    ap.add_argument("--walkers", type=int, default=None, help="ensemble size (config's)")
    ap.add_argument("--init", choices=["ball", "laplace"], default=None,
                    help="walker start (config's [sampler] init)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--ensembles", type=int, default=1,
                    help="independent ensembles run in parallel processes and pooled")
    ap.add_argument("--threads", default=None,
                    help="threads per ensemble, an integer or auto (config's [sampler] "
                         "threads)")
    ap.add_argument("--backend", default=None,
                    help="HDF checkpoint (one ensemble): resume or extend a run")
    ap.add_argument("--progress", action="store_true")
    ap.add_argument("--every", type=int, default=500,
                    help="spacing of the chain prefixes checked for lasting convergence, "
                         "steps")
    ap.add_argument("--json", default=None, help="write the figures to this file")
    ap.add_argument("--save", default=None, metavar="FILE.npz",
                    help="save the pooled post-burn-in chain (sampling coordinates, "
                         "steps x walkers x parameters), its log posterior and the names")
    args = ap.parse_args(argv)
    from bayesmodal.inference import converged_from
    from bayesmodal.inference.sampling import convergence_diagnostics

    jobs = [{"config": args.config, "steps": args.steps, "burn": args.burn,
             "walkers": args.walkers, "init": args.init, "seed": args.seed + k,
             "backend": args.backend if args.ensembles == 1 else None,
             "threads": args.threads,
             "progress": args.progress and k == 0} for k in range(args.ensembles)]
    load_before = _load()
    t0 = time.perf_counter()
    if args.ensembles == 1:
        res = [_one(jobs[0])]
    else:
        with ProcessPoolExecutor(args.ensembles) as pool:
            res = list(pool.map(_one, jobs))
    wall = time.perf_counter() - t0
    z = np.concatenate([r["z"] for r in res], axis=1)  # walkers of all ensembles as chains
    acc = np.concatenate([r["acceptance"] for r in res])
    names = res[0]["names"]
    if args.save:
        np.savez_compressed(args.save, z=z, log_prob=np.concatenate([r["lp"] for r in res],
                                                                     axis=1),
                            names=np.array(names), ensembles=args.ensembles)
    d = convergence_diagnostics(z, acc, names, min_ess=ESS_TARGET, max_rhat=RHAT_TARGET)
    n_eval = sum(r["n_evaluations"] for r in res)
    cpu = sum(r["cpu_s"] for r in res)
    sampling_cpu = sum(r["sampling_s"] for r in res)  # wall of sampling per process
    walkers_total = z.shape[1]
    tau_max = float(np.max(d.tau))
    # ESS ~ walkers * kept / tau; R-hat with walkers as chains needs each walker about
    # MIN_N_OVER_TAU autocorrelation times long (the package's own check, which binds
    # first for an ensemble).  A short chain underestimates tau: a lower bound then.
    need_kept = int(np.ceil(max(ESS_TARGET * tau_max / walkers_total,
                                MIN_N_OVER_TAU * tau_max))) if np.isfinite(tau_max) else None
    cpu_per_eval = cpu / n_eval
    out = {
        "config": args.config, "extension": res[0]["extension"],
        "init": args.init or "config", "ensembles": args.ensembles,
        "threads_per_ensemble": res[0]["threads"],
        "walkers_per_ensemble": res[0]["walkers"], "steps": res[0]["steps"],
        "burn": res[0]["burn"], "parameters": len(names),
        "wall_s": wall, "cpu_s": cpu, "evaluations": n_eval,
        "evaluations_per_s_wall": n_eval / sum(r["sampling_s"] for r in res) * len(res),
        "evaluations_per_cpu_s": n_eval / cpu,
        "max_rhat": d.max_rhat, "worst_rhat": names[int(np.nanargmax(d.rhat))],
        "min_ess_bulk": d.min_ess, "worst_ess": names[int(np.nanargmin(d.ess_bulk))],
        "tau_max_steps": tau_max, "acceptance": d.acceptance,
        "converged": bool(d.max_rhat < RHAT_TARGET and d.min_ess > ESS_TARGET),
        "problems": list(d.problems), "load_before": load_before, "load_after": _load(),
        "cores": os.cpu_count(), "sampling_wall_s_per_process": sampling_cpu / len(res),
    }
    if out["converged"]:
        rl = converged_from(z, names, every=min(args.every, z.shape[0]),
                            max_rhat=RHAT_TARGET, min_ess=ESS_TARGET)
        if rl.lasting is not None:
            steps = res[0]["steps"]
            frac = (res[0]["burn"] + rl.lasting) / steps
            # per process: its start (mode search, Laplace draws) then the sampling
            wall_to = max(r["wall_s"] - r["sampling_s"] + r["sampling_s"] * frac for r in res)
            out["converged_from"] = {
                "steps_per_walker": res[0]["burn"] + rl.lasting, "kept_steps": rl.lasting,
                "wall_s_estimate": wall_to + (wall - max(r["wall_s"] for r in res)),
                "checked_kept_steps": rl.kept_steps.tolist(),
                "max_rhat": rl.max_rhat.tolist(), "min_ess": rl.min_ess.tolist()}
    if need_kept is not None:
        need_steps = need_kept + res[0]["burn"]
        evals = need_steps * walkers_total
        out["extrapolated"] = {"kept_steps_per_walker": need_kept,
                               "steps_per_walker": need_steps,
                               "cpu_s": evals * cpu_per_eval,
                               "idle_wall_s_on_2_cores": evals * cpu_per_eval
                               / min(2, args.ensembles * res[0]["threads"])}
    print(f"{out['extension']} on {len(names)} parameters, init {out['init']}, "
          f"{args.ensembles} x {res[0]['walkers']} walkers x {res[0]['steps']} steps "
          f"(burn {res[0]['burn']}), {res[0]['threads']} thread(s) per ensemble")
    print(f"wall time      {wall:9.1f} s   ({out['load_before']} before; "
          f"{out['load_after']} after; {out['cores']} cores)")
    print(f"CPU time       {cpu:9.1f} s   ({cpu_per_eval * 1e3:.2f} ms per evaluation)")
    print(f"evaluations/s  {out['evaluations_per_s_wall']:9.1f}     (per CPU s "
          f"{out['evaluations_per_cpu_s']:.1f})")
    print(f"R-hat max      {d.max_rhat:9.3f}     ({out['worst_rhat']})")
    print(f"bulk ESS min   {d.min_ess:9.0f}     ({out['worst_ess']})")
    print(f"tau max        {tau_max:9.1f} steps, acceptance {d.acceptance:.2f}")
    print(f"converged      {out['converged']} (R-hat < {RHAT_TARGET}, bulk ESS > "
          f"{ESS_TARGET:.0f})")
    if "converged_from" in out:
        c = out["converged_from"]
        print(f"converged from {c['steps_per_walker']} steps per walker of "
              f"{res[0]['steps']} (every longer prefix checked every {args.every} steps "
              f"too): about {c['wall_s_estimate'] / 60:.1f} min wall to there")
    if "extrapolated" in out:
        x = out["extrapolated"]
        print(f"extrapolated   {x['steps_per_walker']} steps per walker for ESS > "
              f"{ESS_TARGET:.0f} and {MIN_N_OVER_TAU:.0f} tau: {x['cpu_s'] / 60:.1f} CPU min, "
              f"{x['idle_wall_s_on_2_cores'] / 60:.1f} min wall on 2 idle cores")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    from bayesmodal._errors import ConfigError

    try:
        raise SystemExit(main())
    except ConfigError as exc:  # a bad --steps/--burn/config: one line, not a traceback
        raise SystemExit(f"extended_posterior.py: error: {exc}") from None
