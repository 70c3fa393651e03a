"""What the fits' threads buy a diagnosis: one thread against several, the same result.

Runs ``diagnose`` on the same records with one thread and with ``--threads`` (the local
searches from several starts, the generations of the global search and the folds of the
leave-one-record-out gains side by side; ``bayesmodal.fit._threads``), in turn
``--rounds`` times (order alternating), and prints each wall time, the speedup (median of
the per-round ratios) and whether the two diagnoses are equal number for number, which is
the promise that lets ``diagnose`` and ``identify`` use every core by default.

Records: ``synthetic`` (default): four records of one rig with stick-slip friction on
every cart, a drive dead band and an amplifier offset from the independent reference
simulators of ``tests/identify_records.py`` (the known truth of ``identify``), diagnosed
with the workflow's options (records weighed by their spread, the end stop a candidate,
19 null sets, up to 4 effects); ``measured``: the four measured ECP records with the same
options (about half an hour a diagnosis on one thread).

Usage::

    python benchmarks/diagnose_threads.py --layout two_frame_at_drive --json out.json
    python benchmarks/diagnose_threads.py --records measured --rounds 1
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent))

from identify_records import write_records  # noqa: E402

from bayesmodal.bench import machine_load  # noqa: E402
from bayesmodal.data import find_data, load_experiment  # noqa: E402
from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES, DiagnoseSpec, diagnose  # noqa: E402
from bayesmodal.inference import resolve_threads  # noqa: E402
from bayesmodal.model.rigs import load_rig  # noqa: E402
from bayesmodal.model.system import Rig  # noqa: E402

PRESETS = {"one_cart": "ecp210-1cart", "two_frame_at_drive": "ecp210-2cart-frame-at-drive",
           "three_chain": "ecp210-3cart"}
MEASURED = ("ecp210-3dof/data_impulses.mat", "ecp210-3dof/data_steps.mat",
            "ecp210-3dof/data_sine_sweep_fast.mat", "ecp210-3dof/data_sine_sweep_slow.mat")


def _records(kind: str, layout: str, seed: int, folder: Path):
    """The records and their rig."""
    if kind == "measured":
        paths = [find_data(p) for p in MEASURED]
        if not all(paths):
            raise SystemExit("the measured records are not here: set BAYESMODAL_DATA")
        return [load_experiment(p) for p in paths], Rig()
    rng = np.random.default_rng(seed)
    rig = load_rig(PRESETS[layout])
    friction = {c + 1: (fc, fc * rng.uniform(1.0, 1.3))
                for c, fc in enumerate(rng.uniform(0.2, 0.6, rig.n_carts))}
    paths, _ = write_records(folder, layout, seed, n_records=4, n_samples=2400,
                             v_offset=rng.uniform(0.02, 0.05) * rng.choice([-1, 1]),
                             v_dead=rng.uniform(0.02, 0.05), friction=friction)
    return [load_experiment(p) for p in paths], rig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", choices=("synthetic", "measured"), default="synthetic")
    ap.add_argument("--layout", choices=sorted(PRESETS), default="two_frame_at_drive")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", default="auto", help="threads to compare with one")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--json", default=None, help="write the figures to this file")
    args = ap.parse_args(argv)
    n = resolve_threads(args.threads)
    out = {"machine": machine_load(), "threads": n, "records": args.records,
           "layout": None if args.records == "measured" else args.layout, "rounds": []}
    print(f"load average at start: {out['machine']['load_average']}; {n} threads against 1")
    with tempfile.TemporaryDirectory() as tmp:
        exps, rig = _records(args.records, args.layout, args.seed, Path(tmp))
        spec = DiagnoseSpec(posterior=False, n_null=19, max_effects=4, weights="spread",
                            candidates=tuple(DEFAULT_CANDIDATES) + ("end_stop",))
        results = {}
        for r in range(args.rounds):
            for threads in ((1, n) if r % 2 == 0 else (n, 1)):
                t0 = time.perf_counter()
                d = diagnose(exps, spec, rig=rig, train=tuple(range(len(exps))),
                             rng=args.seed, threads=threads)
                wall = time.perf_counter() - t0
                results.setdefault(threads, []).append(wall)
                text = json.dumps(d.as_dict(), sort_keys=True, default=str)
                out.setdefault("diagnoses", {}).setdefault(threads, text)
                print(f"round {r + 1}, {threads} thread(s): {wall:.1f} s, found "
                      f"{[c.cause for c in d.causes] or d.cause}", flush=True)
    ratios = [a / b for a, b in zip(results[1], results[n], strict=True)]
    equal = out.pop("diagnoses")
    out.update(serial_s=results[1], threaded_s=results[n], speedup=float(np.median(ratios)),
               speedup_rounds=ratios, equal=len(set(equal.values())) == 1)
    print(f"speedup {out['speedup']:.2f}x (rounds {', '.join(f'{x:.2f}' for x in ratios)}); "
          f"the diagnoses are {'equal' if out['equal'] else 'NOT EQUAL'} number for number")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0 if out["equal"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
