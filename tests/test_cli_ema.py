"""``bayesmodal ema``: the exit code says whether any mode was identified."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

from conftest import measured

from bayesmodal.cli import main

SYNTHETIC = Path(__file__).resolve().parents[1] / "data" / "synthetic_impulses.csv"


def _ema(capsys, path):
    code = main(["ema", str(path), "--json"])
    cap = capsys.readouterr()
    return code, json.loads(cap.out), cap.err


def test_impulses_identify_modes_exit_0(capsys):
    code, out, err = _ema(capsys, SYNTHETIC)
    assert any(out["identified"]) and code == 0, err


def test_steps_identify_modes_through_the_step_differences(capsys):
    """The record that used to give no mode and exit 0: the steps' differences are
    impulses, and modes 2 and 3 are identified (the no-mode exit 2 is tested on synthetic
    records in test_ema_records.py)."""
    path = measured("data_steps.mat").source
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # the CLI shows "2 of the 3 modes" as one line
        code, out, err = _ema(capsys, path)
    assert code == 0, err
    assert sum(out["identified"]) >= 2
    assert "warning: " in err and "modes sought identified" in err
