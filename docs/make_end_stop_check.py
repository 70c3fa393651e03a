"""Does the end stop of cart 1 predict pulses it was not fitted on?

The stop (``end_stop``) is met only by the 3 V pulses of ``data_impulses``, so leaving a
whole record out cannot test it: no other record reaches it.  The pulses can.  The impulse
record is cut into its four pulses (2 000 samples each, every one starting after 10 s of
rest, treated as a record starting at rest); the final model of docs/discrepancy.md with
and without the stop is fitted jointly (``fit_records_lsq``, nothing per record) on the
steps, both sweeps and two of the pulses, and predicts the other two: the short pulses 1
and 3 (9.75 and 10 samples of 3 V, which barely touch the stop) predict the long pulses 2
and 4 (10.75 samples), and the other way round.  Each fit starts from the four-record fit
of that model (``docs/figures/discrepancy_table.json``; run ``make_discrepancy_table.py``
first).

Usage (needs the measured data; about 20 minutes on one core)::

    python docs/make_end_stop_check.py

Writes ``docs/figures/end_stop_check.json`` and prints the table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from _measured import measured_records  # docs/_measured.py (run as docs/<script>.py)
from _stamp import stamp  # docs/_stamp.py

from bayesmodal.data import Experiment
from bayesmodal.fit.records import fit_records_lsq, simulate_model
from bayesmodal.metrics import fit_percent
from bayesmodal.model.effects import get_extension
from bayesmodal.model.system import Rig

ROOT = Path(__file__).resolve().parents[1]
#: The models compared, by their step label in discrepancy_table.json.
MODELS = {"dead band, one gain, one offset": "coulomb_friction+input_offset+drive_deadband",
          "+ end stop of cart 1": "coulomb_friction+input_offset+drive_deadband+end_stop"}
#: Samples per pulse of data_impulses (pulses at 0, 10, 20 and 30 s, dt = 5 ms).
PULSE = 2000
SPLITS = {"fit pulses 1, 3; predict 2, 4": ((0, 2), (1, 3)),
          "fit pulses 2, 4; predict 1, 3": ((1, 3), (0, 2))}


def pulses(imp: Experiment) -> list[Experiment]:
    """The four pulses of the impulse record as records starting at rest."""
    out = []
    for k in range(4):
        sl = slice(k * PULSE, (k + 1) * PULSE)
        out.append(Experiment(imp.t_s[sl] - imp.t_s[sl.start], imp.v_volt[sl], imp.y_m[sl],
                              name=f"pulse {k + 1}"))
    return out


def table(out: dict) -> str:
    """The stored result as the Markdown table the script prints: per model and split,
    the fit (%) of each held-out pulse on carts 1-3."""
    lines = ["| model | split | held-out pulse: fit % (carts 1-3) |", "|---|---|---|"]
    for label, splits in out.items():
        if label == "stamp":
            continue
        for split, r in splits.items():
            held = "; ".join(f"{name}: {', '.join(f'{x:.1f}' for x in fit)}"
                             for name, fit in r["held_out"].items())
            lines.append(f"| {label} | {split} | {held} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "end_stop_check.json"))
    ap.add_argument("--table", default=str(ROOT / "docs" / "figures" / "discrepancy_table.json"),
                    help="the output of make_discrepancy_table.py (its joint fits start "
                    "these)")
    args = ap.parse_args(argv)
    table = json.loads(Path(args.table).read_text())
    imp, *others = measured_records()
    parts = pulses(imp)
    rig = Rig()
    out: dict = {}
    for label, effects in MODELS.items():
        if label not in table["joint"]:
            print(f"{label!r} is not in discrepancy_table.json: run "
                  "docs/make_discrepancy_table.py first", file=sys.stderr)
            return 2
        ext = get_extension(effects)
        start = np.array(table["joint"][label]["theta"])[0]
        for split, (train, test) in SPLITS.items():
            t0 = time.time()
            fit = fit_records_lsq([parts[k] for k in train] + others, ext, rig,
                                  per_record=(), theta0=start, max_nfev=60)
            th = fit.theta[:1]
            held = {parts[k].name: np.round(fit_percent(
                parts[k].y_m, simulate_model(ext, rig, th, parts[k])[0]), 1).tolist()
                for k in test}
            out.setdefault(label, {})[split] = {
                "held_out": held, "theta": th[0].tolist(), "names": list(fit.names),
                "seconds": round(time.time() - t0)}
            print(f"{label:34s} {split}: {held}", flush=True)
    out["stamp"] = stamp()
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(table(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
