"""``bayesmodal ema``: the exit code says whether any mode was identified."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import measured

from bayesmodal.cli import main

SYNTHETIC = Path(__file__).resolve().parents[1] / "data" / "synthetic_impulses.csv"


def _ema(capsys, path):
    code = main(["ema", str(path), "--json"])
    cap = capsys.readouterr()
    return code, json.loads(cap.out), cap.err


def _check_exit_matches_result(code, out, err):
    if any(out["identified"]):
        assert code == 0, err
        assert "no mode identified" not in err
    else:
        assert code == 1
        lines = [ln for ln in err.strip().splitlines() if "error" in ln]
        assert len(lines) == 1
        assert lines[0].startswith("bayesmodal ema: error: no mode identified in ")
        assert "--band" in lines[0] and "impulse" in lines[0]  # names the fix


def test_impulses_identify_modes_exit_0(capsys):
    code, out, err = _ema(capsys, SYNTHETIC)
    assert any(out["identified"])  # negative control of the failure below
    _check_exit_matches_result(code, out, err)


def test_steps_without_identified_mode_exit_non_zero(capsys):
    path = measured("data_steps.mat").source
    code, out, err = _ema(capsys, path)
    _check_exit_matches_result(code, out, err)
    if any(out["identified"]):
        pytest.skip("ema now identifies a mode in data_steps: the failure branch is not "
                    "exercised by this record")
    assert main(["ema", path]) == 1  # the text output too
    assert "no mode identified" in capsys.readouterr().err
