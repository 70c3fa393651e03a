"""A posterior run's folder: ``posterior.nc``, ``summary.json``, the least-squares
comparison and the figures, each written atomically.

The summaries come from ``bayesmodal.inference.summary`` (numbers only); this module
writes them and draws the run's figures (``bayesmodal.plots``): inference neither writes
files nor draws.
"""

from __future__ import annotations

from pathlib import Path

from ..inference.idata import model_from_idata, save_idata
from ..inference.propagate import ModalSamples, propagate_modes
from ..inference.summary import (
    comparison_markdown,
    lsq_theta,
    lsq_vs_posterior,
    mechanical_names,
    posterior_modes,
    summary_dict,
)
from ..plots.posterior import (
    plot_bode_bands,
    plot_corner,
    plot_modal_intervals,
    plot_predictive,
    plot_trace,
)
from .folder import atomic_savefig, atomic_write_json, atomic_write_text

__all__ = ["write_run", "write_modal_plot", "PLOT_DPI", "TRACE_DPI"]


def write_run(idata, out_dir, *, prob: float = 0.9, plots: bool = True) -> dict:
    """Write a run folder: ``posterior.nc``, ``summary.json``, ``lsq_vs_posterior.md`` and
    the plots (``trace.png``, ``corner.png``, ``predictive.png``, ``bode.png``,
    ``modal_intervals.png``).  Files are written atomically.

    Returns
    -------
    dict
        The summary (as in ``summary.json``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    save_idata(idata, out / "posterior.nc")
    modal = posterior_modes(idata)
    summary = summary_dict(idata, prob=prob, modal=modal)
    atomic_write_json(out / "summary.json", summary)
    rows = lsq_vs_posterior(idata, prob=prob, modal=modal)
    if rows:
        atomic_write_text(out / "lsq_vs_posterior.md", comparison_markdown(rows) + "\n")
    if plots:
        _write_plots(idata, modal, out, prob)
    return summary


#: Resolution of the run plots (dots per inch).
PLOT_DPI = 160
#: Resolution of the trace plot: one row per parameter (21 rows, 34 inches, for the main
#: job), thin lines that need no more.
TRACE_DPI = 90


def _save(fig, path, dpi: float = PLOT_DPI) -> None:
    atomic_savefig(fig, path, dpi=dpi)


def _write_plots(idata, modal, out, prob) -> None:
    model = model_from_idata(idata)
    theta = lsq_theta(idata)
    ref = None if theta is None else propagate_modes(model, theta[None], methods=("eig",))
    refd = None if theta is None else dict(zip(mechanical_names(idata, model),
                                               theta.tolist(), strict=True))
    _save(plot_trace(idata).flat[0].figure, out / "trace.png", dpi=TRACE_DPI)
    _save(plot_corner(idata, reference=refd).flat[0].figure, out / "corner.png")
    if "posterior_predictive" in idata.groups():
        _save(plot_predictive(idata, prob=prob)[0].figure, out / "predictive.png")
    _save(plot_bode_bands(idata, prob=prob)[0].figure, out / "bode.png")
    _save(plot_modal_intervals(modal, reference=ref, prob=prob).flat[0].figure,
          out / "modal_intervals.png")


def write_modal_plot(idata, out_dir, *, prob: float = 0.9, lsce=None,
                     modal: ModalSamples | None = None) -> None:
    """(Re)write ``modal_intervals.png`` of a run folder, with LSCE estimates when given.

    Parameters
    ----------
    idata : InferenceData
    out_dir : path
    prob : float
    lsce : sequence of (str, ndarray, ndarray), optional
        Per record: name, matched natural frequencies (rad/s) and damping ratios of the
        model-free LSCE estimate (see ``plot_modal_intervals``).
    modal : ModalSamples, optional
        Posterior modal samples (computed if omitted).
    """
    model = model_from_idata(idata)
    theta = lsq_theta(idata)
    ref = None if theta is None else propagate_modes(model, theta[None], methods=("eig",))
    modal = posterior_modes(idata) if modal is None else modal
    _save(plot_modal_intervals(modal, reference=ref, lsce=lsce, prob=prob).flat[0].figure,
          Path(out_dir) / "modal_intervals.png")
