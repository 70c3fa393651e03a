"""``bayesmodal compare``: free versus proportional damping (LOO, WAIC, evidence, test data)."""

from __future__ import annotations

from pathlib import Path

from .._errors import ConfigError
from ..inference import choose_model, load_idata
from ..runs import compare_runs, write_comparison
from ..runs.compare import check_distinct_runs
from ..runs.folder import atomic_write_json
from ._common import add_reader_arguments, load_data, print_json
from ._sample import add_sampler_args, sample_to_dir


def register(sub) -> None:
    p = sub.add_parser(
        "compare",
        help="model choice: free vs proportional damping",
        description="Run both damping models on DATA (or take two finished run folders with "
                    "--runs) and compare them by PSIS-LOO, WAIC, the Bayesian evidence "
                    "(dynesty) with its Bayes factor, and the predictive score on --test "
                    "records.  Writes model_choice.json and model_choice.md into --out.  "
                    "Given RUN_DIR folders instead of DATA (`bayesmodal run` outputs on the "
                    "same data), ranks them all by LOO and WAIC with their stored evidence "
                    "and held-out fit, writing comparison.json, comparison.md and "
                    "intervals.png (omega and zeta intervals overlaid) into --out.",
    )
    p.add_argument("data", nargs="*", metavar="DATA|RUN_DIR",
                   help="data files to fit (.mat/.txt ECP in counts, .csv in SI), or two or "
                        "more finished run folders")
    p.add_argument("--runs", nargs=2, metavar=("DIR_A", "DIR_B"), default=None,
                   help="two finished `bayesmodal sample` folders instead of DATA "
                        "(default: none)")
    p.add_argument("--test", nargs="+", default=None, metavar="TEST",
                   help="held-out data files for the predictive check (e.g. data_steps.mat; "
                        "default: none)")
    add_reader_arguments(p)
    add_sampler_args(p)
    p.add_argument("--nlive", type=int, default=250, help="dynesty live points")
    p.add_argument("--dlogz", type=float, default=0.5, help="dynesty stopping criterion dlogz")
    p.add_argument("--no-evidence", action="store_true",
                   help="skip nested sampling (the slow part: minutes per model)")
    p.add_argument("--out", default="runs/compare", metavar="DIR",
                   help="output folder (default runs/compare)")
    p.add_argument("--json", action="store_true", help="print the model_choice JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no text output")
    p.set_defaults(func=run, fresh=False, no_plots=False)


def run(args) -> int:
    out = Path(args.out)
    if args.data and any(Path(d).is_dir() for d in args.data):
        return _run_dirs(args, out)
    if args.runs:
        if args.data:
            raise ConfigError("give either DATA or --runs DIR_A DIR_B, not both (drop the "
                              "data files to compare the two runs)")

        loaded = [load_idata(Path(d) / "posterior.nc") for d in args.runs]
        check_distinct_runs(args.runs, loaded)
        idatas = {}
        for d, idt in zip(args.runs, loaded, strict=True):
            label = idt.posterior.attrs["damping"]
            idatas[label if label not in idatas else f"{label}:{d}"] = idt
    else:
        if not args.data:
            raise ConfigError("no DATA files and no --runs given: give data files to fit "
                              "both damping models, or two or more finished run folders")
        exps = load_data(args.data, args)
        idatas = {}
        for damping in ("free", "proportional"):
            _, idatas[damping] = sample_to_dir(exps, args, damping, out / damping)
    tests = None
    if args.test:
        tests = load_data(args.test, args)
    choice = choose_model(idatas, test=tests, evidence=not args.no_evidence,
                          nlive=args.nlive, dlogz=args.dlogz, rng=args.seed)
    result = {"model_choice": choice.as_dict()}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "model_choice.json", result)
    tmp = out / "model_choice.md.tmp"
    tmp.write_text(choice.to_markdown() + "\n\n" + choice.verdict + "\n")
    tmp.replace(out / "model_choice.md")
    if args.json:
        print_json(result)
    elif not args.quiet:
        print(choice.to_markdown())
        print()
        print(choice.verdict)
    return 0


def _run_dirs(args, out: Path) -> int:
    """``compare RUN_DIR...``: model choice across finished run folders."""

    dirs = [Path(d) for d in args.data]
    files = [str(d) for d in dirs if not d.is_dir()]
    if files:
        raise ConfigError(f"give either data files or run folders, not both: {files} are not "
                          "folders")
    if args.runs:
        raise ConfigError("give run folders either as arguments or with --runs, not both")
    tests = None
    if args.test:
        tests = load_data(args.test, args)
    comp = compare_runs(dirs, test=tests)
    write_comparison(comp, out)
    if args.json:
        print_json(comp.as_dict())
    elif not args.quiet:
        print(comp.to_markdown())
        print()
        print(comp.verdict)
        print(f"written to {out}/ (comparison.md, comparison.json, intervals.png)")
    return 0
