"""``bayesmodal sample``: posterior of the rig parameters with emcee, written to a folder."""

from __future__ import annotations

import contextlib
import shutil
import sys
from pathlib import Path

from .._format import param_unit, sig
from ..inference import sample_posterior, to_inference_data
from ..inference.noise_spec import accepted_noise
from ..inference.record_layout import parse_layout
from ..inference.record_scale import NOISE_SCALES
from ..model.rigs import rig_to_dict
from ..model.system import LinearModel, Rig
from ..runs import checkpoint_iteration
from ..runs.description import (
    DataSection,
    LikelihoodSection,
    ModelSection,
    RecordsSection,
    RunConfig,
    SamplerSection,
)
from ..runs.outputs import write_run
from ._common import (
    add_data_args,
    add_initial_state_argument,
    add_rig_argument,
    damping_of,
    load_args,
    load_rig,
    print_json,
)


def register(sub) -> None:
    p = sub.add_parser(
        "sample",
        help="posterior sampling (emcee) with modal credible intervals",
        description="Sample the posterior of g_v, masses, damping and noise parameters; write "
                    "posterior.nc (ArviZ InferenceData), summary.json, plots and the emcee "
                    "checkpoint chain.h5 into --out.  Re-running the same command resumes "
                    "from the checkpoint.",
    )
    add_data_args(p, many=True)
    add_rig_argument(p)
    add_initial_state_argument(p)
    add_sampler_args(p)
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default runs/sample-<damping>-<noise>)")
    p.add_argument("--fresh", action="store_true",
                   help="discard an existing checkpoint in --out instead of resuming")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--json", action="store_true", help="print summary.json to stdout")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no text output")
    p.set_defaults(func=run)


def add_sampler_args(p) -> None:
    """Options shared by ``sample`` and ``compare``."""
    p.add_argument("--damping", choices=["free", "proportional"], default=None,
                   help="damping model: free (c1, c2, c3, c12, c23) or proportional "
                   "(C = ca M + cb K)"
                   " (default: the rig's [dampers] proportional declaration, else free)")
    p.add_argument("--noise", default=LikelihoodSection.noise, metavar="MODEL",
                   help=f"residual model: {accepted_noise()}")
    p.add_argument("--per-record", default="none", metavar="NAME=KIND,...",
                   help="several DATA records, one physical system: parameters with one "
                   "value per record, KIND independent or hierarchical, e.g. "
                   "g_v=hierarchical,v0=hierarchical; none shares every parameter")
    p.add_argument("--noise-scale", choices=NOISE_SCALES, default="none",
                   help="response: each record's noise level times the relative size of "
                   "the model's response to its input; power: times that size to a sampled "
                   "power in [0, 1] (default none: one level in m)")
    p.add_argument("--walkers", type=int, default=SamplerSection.walkers,
                   help="ensemble size")
    p.add_argument("--steps", type=int, default=SamplerSection.steps,
                   help="steps per walker")
    p.add_argument("--burn", type=int, default=None,
                   help="burn-in steps to discard (default steps/5)")
    p.add_argument("--thin", type=int, default=None,
                   help="keep every N-th step (default: about 1000 retained draws)")
    p.add_argument("--seed", type=int, default=SamplerSection.seed, help="random seed")
    p.add_argument("--init", choices=["ball", "laplace"], default="ball",
                   help="walker start: a small ball at the posterior mode, or draws of the "
                   "Laplace approximation there (shorter burn-in; default ball)")
    p.add_argument("--threads", default="1", metavar="N|auto",
                   help="threads evaluating each half-ensemble (auto: one per core); the "
                   "same chain, faster for a costly likelihood (default 1)")


def description_from_args(args, rig: Rig, damping: str) -> RunConfig:
    """The run description of ``bayesmodal sample``'s flags (the same object a run's TOML
    file makes, ``bayesmodal.runs.RunConfig``).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags (``add_data_args``, ``add_rig_argument``, ``add_sampler_args``).
    rig : Rig
        The rig of ``--rig`` (``load_rig``); written into the description only when the
        flag names one.
    damping : {"free", "proportional"}
        The damping model (``damping_of``).

    Returns
    -------
    RunConfig
    """
    layout = parse_layout(getattr(args, "per_record", "none"),
                          noise_scale=getattr(args, "noise_scale", "none"))
    paths = args.data if isinstance(args.data, list) else [args.data]
    return RunConfig(
        name="sample", source="bayesmodal sample",
        data=DataSection(files=tuple(str(p) for p in paths)),
        model=ModelSection(
            rig=None if getattr(args, "rig", None) is None else rig_to_dict(rig),
            damping=damping),
        records=RecordsSection(per_record=dict(layout.per_record),
                               noise_scale=layout.noise_scale),
        likelihood=LikelihoodSection(noise=args.noise,
                                     initial_state=getattr(args, "initial_state", "rest")),
        sampler=SamplerSection(walkers=args.walkers, steps=args.steps, burn=args.burn,
                               thin=args.thin, seed=args.seed,
                               init=getattr(args, "init", "ball"),
                               threads=getattr(args, "threads", "1")))


def sample_to_dir(exps, args, damping: str, out: Path):
    """Sample one model into ``out``; return (summary, idata) (shared with ``compare``)."""

    model = LinearModel(load_rig(args), damping)
    for e in exps:  # checked before the output folder is made
        model.check_record(e)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    ckpt = out / "chain.h5"
    if getattr(args, "fresh", False) and ckpt.exists():
        ckpt.unlink()
    try:
        run = sample_posterior(exps, description_from_args(args, model.rig, damping),
                               progress=not args.quiet, backend=ckpt)
    except Exception:
        # a start that failed before any step leaves no folder behind (nothing to resume)
        with contextlib.suppress(Exception):
            if created and checkpoint_iteration(ckpt) == 0:
                shutil.rmtree(out)
        raise
    idata = to_inference_data(run, rng=args.seed)
    summary = write_run(idata, out, plots=not getattr(args, "no_plots", False))
    return summary, idata


def _print_text(summary: dict, out: Path, kinds: tuple[str, ...] = ()) -> None:
    print(f"damping: {summary['damping']}, noise: {summary['noise']}  -> {out}")
    print(f"{'parameter':>10s} {'median':>12s}   90 % interval")
    # a noise level is in its sensor's SI unit
    sensor_unit = {"velocity": "m/s", "acceleration": "m/s^2"}
    for nm, d in summary["parameters"].items():
        unit = param_unit(nm)
        j = nm[6:]
        if nm.startswith("sigma_") and j.isdigit() and int(j) <= len(kinds):
            unit = sensor_unit.get(kinds[int(j) - 1], unit)
        print(f"{nm:>10s} {sig(d['median'], 5):>12s}   [{sig(d['lo'], 5)}, {sig(d['hi'], 5)}] "
              f"{unit}".rstrip())
    for key, label in (("omega_rad_s", "natural frequencies (rad/s)"),
                       ("zeta", "damping ratios")):
        d = summary[key]
        cells = ", ".join(f"{sig(m, 5)} [{sig(lo, 5)}, {sig(hi, 5)}]"
                          for m, lo, hi in zip(d["median"], d["lo"], d["hi"], strict=True))
        print(f"{label}: {cells}")
    dg = summary["diagnostics"]
    perf = summary["performance"]
    print(f"diagnostics: max R-hat {dg['max_rhat']:.3f}, min ESS {dg['min_ess']:.0f}, "
          f"N/tau {dg['n_over_tau']:.0f}, acceptance {dg['acceptance']:.2f}, "
          f"converged {dg['converged']}")
    if perf["n_evaluations"] and perf["evaluations_per_s"]:
        print(f"performance: {perf['evaluations_per_s']:.0f} likelihood evaluations/s, "
              f"{perf['ess_per_s']:.1f} effective samples/s, {perf['sampling_time_s']:.1f} s")
    else:  # a checkpoint finished before its sampling time was recorded
        print("performance: not measured (the chain was read from its checkpoint)")
    if summary["lsq_outside_interval"]:
        print("LSQ outside the 90 % interval:", ", ".join(summary["lsq_outside_interval"]))


def run(args) -> int:
    exps = load_args(args)
    rig = load_rig(args)
    damping = damping_of(args, rig)
    out = Path(args.out or f"runs/sample-{damping}-{args.noise}")
    summary, _ = sample_to_dir(exps, args, damping, out)
    if args.json:
        print_json(summary)
    elif not args.quiet:
        _print_text(summary, out, rig.output_kinds)
        sys.stdout.flush()
    return 0
