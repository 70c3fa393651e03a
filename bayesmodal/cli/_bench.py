"""``bayesmodal bench``: speed benchmarks against baselines measured in the same run."""

from __future__ import annotations

from ..bench import (
    COMBINED_MAX_RATIO,
    EXTENSION_MAX_RATIO,
    bench_effect_sensor_kinds,
    bench_extensions,
    bench_linear,
    bench_sensor_kinds,
    headline,
    machine_load,
)
from ..bench_sampler import SAMPLER_MIN_FRACTION, bench_sampler
from ..bench_stamps import bench_stamps
from ._common import print_json


def register(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="speed benchmarks (simulator vs scipy lsim, extensions)",
        description="Time the batched linear simulator against scipy.signal.lsim and each "
        "model-extension simulator against the linear one, as ratios measured in the "
        "same run.",
    )
    p.add_argument("--samples", type=int, default=8000, metavar="N",
                   help="record length, samples")
    p.add_argument("--batch", type=int, default=64, metavar="N",
                   help="parameter sets per simulator call")
    p.add_argument("--quick", action="store_true",
                   help="fewer timing rounds (faster, noisier)")
    p.add_argument("--no-extensions", action="store_true",
                   help="skip the model-extension simulators")
    p.add_argument("--extensions", default=None, metavar="NAMES",
                   help="comma-separated extensions or combinations to time (default: all), "
                   "e.g. coulomb_friction,coulomb_friction+input_offset")
    p.add_argument("--no-sampler", action="store_true",
                   help="skip the sampler-throughput benchmark (emcee run vs bare simulator)")
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    out = {"machine": machine_load(),
           "linear": bench_linear(args.samples, args.batch, quick=args.quick),
           "stamps": bench_stamps(args.samples, args.batch, quick=args.quick),
           "sensor_kinds": bench_sensor_kinds(args.samples, args.batch, quick=args.quick)}
    if not args.no_extensions:
        out["effect_sensor_kinds"] = bench_effect_sensor_kinds(args.samples, args.batch,
                                                               quick=args.quick)
    if not args.no_extensions:
        names = None if args.extensions is None else tuple(
            n.strip() for n in args.extensions.split(",") if n.strip())
        out["extensions"] = bench_extensions(args.samples, args.batch, quick=args.quick,
                                             names=names)
        out["headline"] = headline(out["extensions"])
    if not args.no_sampler:
        out["sampler"] = bench_sampler(args.samples, quick=args.quick)
    if args.json:
        print_json(out)
    else:
        m = out["machine"]
        if m["load_average"] is not None:
            print(f"machine: load {m['load_average'][0]:.2f} (1 min) on {m['cores']} cores"
                  + ("; BUSY (other jobs running or just finished): ratios measured "
                     "beside other jobs have come out lower than on an idle machine "
                     "(docs/performance.md)" if m["busy"] else ""))
        lin = out["linear"]
        print(f"linear simulator, N={lin['n_samples']}, batch={lin['batch']}:")
        print(f"  {lin['us_per_eval']:.1f} us/eval (reused buffer), "
              f"{lin['us_per_eval_fresh_output']:.1f} us/eval (fresh output)")
        print(f"  scipy lsim {lin['lsim_us_per_eval']:.0f} us/eval")
        print(f"  speedup {lin['speedup']:.0f}x (fresh output {lin['speedup_fresh_output']:.0f}x)")
        st = out["stamps"]
        print(f"on a logger's recorded stamps ({st['n_distinct_steps']} distinct steps): "
              f"{st['us_per_eval_stamps']:.1f} us/eval, {st['ratio']:.2f}x the uniform "
              f"simulator (target <= {st['target']:g}x)")
        sk = out["sensor_kinds"]
        print(f"acceleration outputs: {sk['us_per_eval_acceleration']:.1f} us/eval, "
              f"{sk['ratio']:.2f}x position outputs (target <= {sk['target']:g}x: "
              f"{'met' if sk['meets_target'] else 'NOT MET'})")
        for name, r in out.get("effect_sensor_kinds", {}).items():
            print(f"  through {name}: {r['us_per_eval_acceleration']:.1f} us/eval, "
                  f"{r['ratio']:.2f}x its position outputs "
                  f"({'met' if r['meets_target'] else 'NOT MET'})")
        if "extensions" in out:
            print(f"model extensions (cost per evaluation vs the linear simulator, median of "
                  f"rounds; target <= {EXTENSION_MAX_RATIO:g}x, combinations "
                  f"<= {COMBINED_MAX_RATIO:g}x), random input | rig input "
                  f"(pulses, steps, sweep):")
            for name, r in out["extensions"].items():
                flags = ["ok" if r[k] else "TOO SLOW"
                         for k in ("meets_target", "meets_target_rig_input")]
                print(f"  {name:18s}\n  {'':18s}" if len(name) > 18 else f"  {name:18s}",
                      end="")
                print(f" {r['us_per_eval']:8.1f} us/eval  "
                      f"{r['ratio_to_linear']:5.1f}x {flags[0]:8s} | "
                      f"{r['ratio_to_linear_rig_input']:5.1f}x {flags[1]}")
            labels = {"coulomb_friction": "Coulomb friction kernel",
                      "best_combined": "best combined model"}
            for key, r in out["headline"].items():
                rounds = ", ".join(f"{x:.1f}" for x in r["ratio_per_round_rig_input"])
                print(f"{labels[key]} ({r['name']}): {r['ratio_of_best_rig_input']:.1f}x the "
                      f"linear simulator on the rig-like input, best time against best "
                      f"(target <= {r['target']:g}x: "
                      f"{'met' if r['meets_target'] else 'NOT MET'}; median of the rounds "
                      f"{r['ratio_rig_input']:.1f}x: {rounds}), {r['ratio_random_input']:.1f}x "
                      "on the random input")
        if "sampler" in out:
            r = out["sampler"]
            print(f"sampler throughput, N={r['n_samples']} samples, {r['n_walkers']} walkers "
                  f"(likelihood evaluations per second; target >= "
                  f"{SAMPLER_MIN_FRACTION:g} of the bare simulator):")
            print(f"  bare simulator {r['simulator_evals_per_s']:.0f}/s, likelihood "
                  f"{r['likelihood_evals_per_s']:.0f}/s, emcee run "
                  f"{r['sampler_evals_per_s']:.0f}/s = {r['sampler_fraction']:.2f} of the "
                  f"simulator ({'ok' if r['meets_target'] else 'TOO SLOW'})")
            rr = r["records"]
            print(f"  {rr['n_records']} records, default layout, {rr['n_walkers']} walkers "
                  f"(record evaluations per second): bare simulator "
                  f"{rr['simulator_evals_per_s']:.0f}/s, likelihood "
                  f"{rr['likelihood_record_evals_per_s']:.0f}/s, emcee run "
                  f"{rr['sampler_record_evals_per_s']:.0f}/s = {rr['sampler_fraction']:.2f} "
                  f"of the simulator")
    return 0
