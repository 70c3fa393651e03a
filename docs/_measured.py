"""The four measured ECP 210 records that the docs scripts study, loaded or a clear exit."""

from __future__ import annotations

import sys

from bayesmodal.data import Experiment, find_data, load_experiment

#: Record stems in ``ecp210-3dof`` (the data root: ``$BAYESMODAL_DATA`` or ../shared/data).
RECORDS = ("data_impulses", "data_steps", "data_sine_sweep_fast", "data_sine_sweep_slow")


def measured_records() -> list[Experiment]:
    """The four records as Experiments; exits with status 2 and the fix when absent."""
    paths = [find_data(f"ecp210-3dof/{n}.mat") for n in RECORDS]
    if any(p is None for p in paths):
        print("the measured records (ecp210-3dof) are not found: set BAYESMODAL_DATA",
              file=sys.stderr)
        raise SystemExit(2)
    return [load_experiment(p) for p in paths]
