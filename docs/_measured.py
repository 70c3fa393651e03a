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


def run_studies(studies: dict, summarise, out: str, markdown, *, workers: int,
                only: list[str] | None = None) -> dict:
    """Leave-one-record-out studies of the four records, one per labelled ``CrossvalSpec``.

    Each result goes through ``summarise(result, wall_s)`` into ``<out>.json`` with its
    ``stamp`` (date, commit, machine: docs/_stamp.py), written
    after every study (``only`` runs the named studies and keeps the file's others); the
    summaries through ``markdown`` into ``<out>.md``, which is also printed.
    """
    import json
    import time
    from pathlib import Path

    from _stamp import stamp  # docs/_stamp.py

    from bayesmodal.inference.crossval import crossval

    exps = measured_records()
    path = Path(out).with_suffix(".json")
    done = json.loads(path.read_text()) if only and path.exists() else {}
    for label, spec in studies.items():
        if only and label not in only:
            continue
        t0 = time.perf_counter()
        res = crossval(exps, spec, workers=workers, joint=False,
                       progress=lambda line, label=label: print(f"{label}: {line}",
                                                               file=sys.stderr))
        done[label] = {**summarise(res, time.perf_counter() - t0), "stamp": stamp()}
        path.write_text(json.dumps(done, indent=1) + "\n")
    table = markdown(done)
    Path(out).with_suffix(".md").write_text(table)
    print(table)
    return done
