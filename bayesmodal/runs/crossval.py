"""Writing a leave-one-record-out study to a folder: JSON, table and plots."""

from __future__ import annotations

import os
from pathlib import Path

from ..plots.crossval import plot_forest, plot_heldout_band
from .folder import atomic_savefig, atomic_write_json, atomic_write_text

__all__ = ["write_crossval"]


def write_crossval(result, out_dir: str | os.PathLike, *, plots: bool = True,
                   calibration=None) -> Path:
    """Write ``crossval.json``, ``crossval.txt`` and the plots of a ``CrossvalResult``.

    With ``calibration`` (a ``TemperatureCalibration``) the JSON has a
    ``temperature_calibration`` entry (chosen temperature and coverage curve) and the
    text file starts with the curve.

    Returns
    -------
    pathlib.Path
        The JSON file.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = result.to_dict()
    text = result.table() + "\n"
    if calibration is not None:
        d["temperature_calibration"] = calibration.to_dict()
        text = calibration.table() + "\n\n" + text
    path = atomic_write_json(out / "crossval.json", d)
    atomic_write_text(out / "crossval.txt", text)
    if plots:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt


        for f in result.folds:
            fig = plot_heldout_band(f)
            atomic_savefig(fig, out / f"heldout_{f.heldout}.png", dpi=150)
            plt.close(fig)
        fig = plot_forest(result)
        atomic_savefig(fig, out / "forest.png", dpi=150)
        plt.close(fig)
    return path
