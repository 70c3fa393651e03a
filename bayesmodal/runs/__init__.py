"""Posterior runs from configuration files: one folder per run, many runs in parallel.

- :func:`run_config` -- check a TOML configuration (``bayesmodal.runs.config``) against its data
  and sample it into its own folder: emcee checkpoint (``chain.h5``, atomic, resumable to
  the identical chain), ``posterior.nc``, ``summary.json`` with provenance, plots,
  ``run.log``, ``status.json`` and a self-contained ``report.html``;
- :func:`run_batch` -- many configurations on local processes or a Dask cluster;
- :func:`rerun_run` -- re-run a recorded run and check ``summary.json`` is reproduced;
- :func:`compare_runs` -- model choice across finished run folders (LOO, WAIC, evidence,
  held-out fit) with :func:`~.plots.plot_run_intervals`.

Folder mechanics (lock, status, atomic writes) are in :mod:`.folder`, the checkpoint
backend in :mod:`.checkpoint`, the report in :mod:`.report`, its first-screen verdict in
:mod:`.verdict`.
"""

from .batch import BatchItem, BatchResult, run_batch, run_one
from .checkpoint import (
    AtomicCheckpoint,
    checkpoint_iteration,
    compact_checkpoint,
    last_state,
    read_trace,
)
from .compare import RunComparison, RunRow, compare_runs, write_comparison
from .folder import RunExistsError, RunFolder, RunLockedError
from .identify import IdentifySpec, identify
from .outputs import write_modal_plot, write_run
from .report import render_report, write_report
from .rerun import RerunResult, recorded_config, rerun_run
from .runner import (
    PreparedRun,
    RunOutcome,
    default_out_dir,
    execute_run,
    parse_moves,
    prepare_run,
    run_config,
)
from .verdict import RunVerdict, run_verdict

__all__ = [
    "AtomicCheckpoint",
    "BatchItem",
    "BatchResult",
    "RunComparison",
    "RunRow",
    "compare_runs",
    "run_batch",
    "run_one",
    "write_comparison",
    "PreparedRun",
    "RunExistsError",
    "RunFolder",
    "RunLockedError",
    "RunOutcome",
    "checkpoint_iteration",
    "compact_checkpoint",
    "last_state",
    "read_trace",
    "default_out_dir",
    "execute_run",
    "parse_moves",
    "prepare_run",
    "render_report",
    "RerunResult",
    "recorded_config",
    "rerun_run",
    "run_config",
    "run_verdict",
    "RunVerdict",
    "write_report",
    "write_run",
    "write_modal_plot",
    "identify",
    "IdentifySpec",
]
