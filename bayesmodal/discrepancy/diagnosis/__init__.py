"""The ``diagnose`` workflow: null-calibrated residual diagnostics, candidate extensions
fitted and scored, the named cause with its location, parameters and gain.

See ``docs/diagnose.md``.
"""

from __future__ import annotations

from ._result import CAUSES, CandidateScore, Diagnosis, Interval, TestOutcome
from .forward import Cause, ForwardResult, forward_select
from .gains import loro_gain
from .null import (
    NoiseModel,
    NullCalibration,
    calibrate_null,
    fit_noise,
    infer_quantum,
    quantise,
)
from .spec import DiagnoseSpec
from .workflow import DEFAULT_CANDIDATES, diagnose, require_diagnosable

__all__ = [
    "CAUSES",
    "CandidateScore",
    "Cause",
    "ForwardResult",
    "DEFAULT_CANDIDATES",
    "DiagnoseSpec",
    "Diagnosis",
    "Interval",
    "NoiseModel",
    "NullCalibration",
    "TestOutcome",
    "calibrate_null",
    "diagnose",
    "require_diagnosable",
    "fit_noise",
    "forward_select",
    "loro_gain",
    "infer_quantum",
    "quantise",
]
