"""The four measured records fitted together: fit per record and cart, in sample and held
out, for each step of docs/discrepancy.md section 6.

Run from the repository root::

    python docs/make_discrepancy_table.py             # joint fits and leave-one-record-out
    python docs/make_discrepancy_table.py --no-loro   # joint fits only

Each model is fitted to the four records jointly by least squares
(``bayesmodal.discrepancy.effects.records_fit.fit_records_lsq``: shared physics, the
parameters named per record fitted per record, cost the sum over records and carts of the
squared fit deficit), each started from the previous step's estimate.  Leave-one-record-out
(``loro_lsq``) refits on three records from the joint estimate and predicts the fourth
with the training records' mean gain and offset.  Every result is cached in
``out/discrepancy_table/`` (delete it to recompute) and the numbers are written to
``docs/figures/discrepancy_table.json``.  Wall time on the shared 2-core machine: about
5 minutes for the joint fits and 20 for the folds.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt, hilbert

from bayesmodal.data import ECP_M_PER_COUNT, find_data, load_experiment
from bayesmodal.discrepancy.effects import get_extension
from bayesmodal.discrepancy.effects.records_fit import fit_records_lsq, loro_lsq, simulate_model
from bayesmodal.metrics import fit_percent
from bayesmodal.system import Rig

ROOT = Path(__file__).resolve().parents[1]
RECORDS = ("data_impulses", "data_steps", "data_sine_sweep_fast", "data_sine_sweep_slow")
SHORT = ("impulses", "steps", "sweep fast", "sweep slow")
RIG = Rig()

#: The steps of the story: label, effects (None: linear), per-record parameters, how the
#: start is made from the previous step, what the step adds.
STEPS = (
    ("linear", None, ("g_v",), "linear free-damping model, a drive gain per record"),
    ("offset", "input_offset", ("g_v", "v_offset"), "+ amplifier offset per record"),
    ("friction", "coulomb_friction+input_offset", ("g_v", "v_offset"),
     "+ stick-slip friction per cart"),
    ("friction, one gain", "coulomb_friction+input_offset", ("v_offset",),
     "the same with one drive gain for all records"),
    ("dead band, one gain", "coulomb_friction+input_offset+drive_deadband", ("v_offset",),
     "+ dead band of the drive, one drive gain for all records"),
    ("directional friction", "coulomb_directional+input_offset+drive_deadband", ("v_offset",),
     "friction levels per direction of sliding instead (joint fit only: its folds take "
     "about half an hour on the shared machine)"),
    # hypotheses tested and rejected (joint fits only)
    ("offset + motor lag", "input_offset+motor_lag", ("g_v", "v_offset"),
     "a first-order lag from voltage to force (linear plant: the lag is refused with "
     "stick-slip friction)"),
    ("friction, c1 per record", "coulomb_friction+input_offset", ("g_v", "v_offset", "c1"),
     "a cart-1 damper per record: what a back-EMF damping g_v k_e with a per-record gain "
     "could add at most"),
    ("friction + saturation", "coulomb_friction+input_offset+input_saturation",
     ("g_v", "v_offset"), "a clipped drive voltage"),
    ("friction + amplitude gain", "coulomb_friction+input_offset+amplitude_gain",
     ("g_v", "v_offset"), "a drive gain growing with the voltage"),
)
#: Steps whose leave-one-record-out folds are computed.
LORO_STEPS = ("linear", "offset", "friction", "friction, one gain", "dead band, one gain")
FINAL = "dead band, one gain"


def load_records() -> list:
    out = []
    for name in RECORDS:
        p = find_data(f"ecp210-3dof/{name}.mat")
        if p is None:
            raise FileNotFoundError(f"measured record {name}.mat not found (see "
                                    "bayesmodal.data.data_root)")
        out.append(load_experiment(p))
    return out


def _start(label: str, prev: dict) -> np.ndarray | None:
    """The start of each step, from the estimates before it."""
    if label == "linear":
        return None
    if label == "offset":
        th = np.array(prev["linear"]["theta"])
        return np.c_[th, np.zeros(len(th))]
    if label == "friction":
        # friction takes over part of the viscous damping: dampers scaled down
        th = np.array(prev["offset"]["theta"])
        lin = th[:, :9].copy()
        lin[:, 4:] *= 0.3
        fc = np.array([0.2, 0.1, 0.1])
        return np.c_[lin, np.tile(np.r_[fc, 1.2 * fc], (len(th), 1)), th[:, 9:]]
    if label == "friction, one gain":
        return np.array(prev["friction"]["theta"])
    if label == "dead band, one gain":
        th = np.array(prev["friction"]["theta"])
        return np.c_[th, np.full(len(th), 0.02)]
    if label == "directional friction":  # the same level both ways to start
        th = np.array(prev["dead band, one gain"]["theta"])
        return np.c_[th[:, :12], th[:, 9:]]
    if label == "offset + motor lag":
        return np.c_[np.array(prev["offset"]["theta"]), np.full(4, 0.003)]
    if label == "friction, c1 per record":
        return np.array(prev["friction"]["theta"])
    if label == "friction + saturation":
        return np.c_[np.array(prev["friction"]["theta"]), np.full(4, 2.5)]
    if label == "friction + amplitude gain":
        return np.c_[np.array(prev["friction"]["theta"]), np.full(4, 0.01)]
    raise ValueError(label)


def _cached(path: Path, compute):
    if path.exists():
        return json.loads(path.read_text())
    out = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out))
    return out


def _slug(label: str) -> str:
    return label.replace(",", "").replace(" ", "_")


def joint_fits(recs, cache: Path, log=print) -> dict:
    res: dict = {}
    for label, effects, per, _ in STEPS:
        ext = None if effects is None else get_extension(effects)

        def compute(label=label, ext=ext, per=per):
            t = time.time()
            f = fit_records_lsq(recs, ext, RIG, per_record=per, theta0=_start(label, res),
                                max_nfev=60)
            return {"theta": f.theta.tolist(), "names": list(f.names),
                    "per_record": list(per), "fit": np.round(f.fit_percent, 1).tolist(),
                    "cost": f.cost, "n_evaluations": f.n_evaluations,
                    "seconds": round(time.time() - t, 1)}

        res[label] = _cached(cache / f"joint_{_slug(label)}.json", compute)
        log(f"{label}: fit {res[label]['fit']}")
    return res


def loro_fits(recs, joint: dict, cache: Path, log=print) -> dict:
    res = {}
    for label, effects, per, _ in STEPS:
        if label not in LORO_STEPS:
            continue
        ext = None if effects is None else get_extension(effects)

        def compute(label=label, ext=ext, per=per):
            t = time.time()
            lo = loro_lsq(recs, ext, RIG, per_record=per,
                          theta0=np.array(joint[label]["theta"]), max_nfev=25)
            return {"fit": np.round(lo.fit_percent, 1).tolist(), "theta": lo.theta.tolist(),
                    "seconds": round(time.time() - t, 1)}

        res[label] = _cached(cache / f"loro_{_slug(label)}.json", compute)
        log(f"{label}: held out {res[label]['fit']}")
    return res


def residual_checks(recs, label: str, joint: dict) -> dict:
    """Mean and slow content of the residuals, and the sweeps' gain and phase against the
    model along the sweep (the instantaneous frequency from the input's analytic signal)."""
    effects = dict((s[0], s[1]) for s in STEPS)[label]
    ext = None if effects is None else get_extension(effects)
    theta = np.array(joint[label]["theta"])
    out = {}
    for r, e in enumerate(recs):
        yh = simulate_model(ext, RIG, theta[r:r + 1], e)[0]
        res = e.y_m - yh
        fs = 1.0 / e.dt
        b, a = butter(2, 0.5 / (fs / 2))
        slow = filtfilt(b, a, res, axis=0)
        item = {"mean_counts": np.round(res.mean(axis=0) / ECP_M_PER_COUNT, 1).tolist(),
                "slow_share": np.round((slow**2).sum(0) / (res**2).sum(0), 2).tolist()}
        if "sweep" in e.name:
            item.update(sweep_phase(e, yh))
        out[SHORT[r]] = item
    return out


def record_checks(recs, joint: dict, loro: dict | None) -> dict:
    """What each record needs: the held-out fit with the record's own offset, and where
    the impulse record's misfit sits (the first 1.5 s after each pulse)."""
    ext = get_extension(dict((s[0], s[1]) for s in STEPS)[FINAL])
    theta = np.array(joint[FINAL]["theta"])
    i_off = joint[FINAL]["names"].index("v_offset")
    out: dict = {}
    if loro and FINAL in loro:
        own = {}
        for r, e in enumerate(recs):
            th = np.array(loro[FINAL]["theta"][r])
            th[i_off] = theta[r, i_off]
            own[SHORT[r]] = np.round(
                fit_percent(e.y_m, simulate_model(ext, RIG, th[None], e)[0]), 1).tolist()
        out["held_out_with_own_offset"] = own
    e = recs[0]
    yh = simulate_model(ext, RIG, theta[:1], e)[0]
    res2 = np.sum((e.y_m - yh) ** 2, axis=1)
    starts = np.flatnonzero(np.diff((e.v_volt > 0.1).astype(int)) == 1) + 1
    pulses = []
    for s in starts:
        w = slice(s, s + int(round(1.5 / e.dt)))
        w2 = slice(s, s + int(round(0.6 / e.dt)))
        pulses.append({"volt_samples": round(float(np.sum(e.v_volt[s - 1:s + 12])), 2),
                       "share_of_squared_residual": round(float(res2[w].sum() / res2.sum()), 3),
                       "first_peak_mm": [round(float(e.y_m[w2, 0].max()) * 1e3, 2),
                                         round(float(yh[w2, 0].max()) * 1e3, 2)]})
    out["impulse_pulses"] = pulses
    return out


def sweep_phase(e, yh) -> dict:
    """Gain and phase of the measurement against the model in 1-s windows of the sweep,
    and the time delay that a straight line of phase against frequency gives (a lag or a
    delay of the drive makes the phase fall in proportion to the frequency)."""
    v = e.v_volt
    f_inst = np.gradient(np.unwrap(np.angle(hilbert(v - v.mean()))), e.dt) / (2 * np.pi)
    fs = 1.0 / e.dt
    bh, ah = butter(2, 0.4 / (fs / 2), "high")
    y, m = filtfilt(bh, ah, e.y_m, axis=0), filtfilt(bh, ah, yh, axis=0)
    W = 200  # samples: 1 s of the fast sweep, 2 s of the slow one, the same band of frequency
    rows = []
    for s in range(int(round(2.0 / e.dt)), len(v) - W, W):
        sl = slice(s, s + W)
        z = hilbert(m[:, 0])[sl]
        c = np.linalg.lstsq(np.column_stack([z.real, z.imag]), y[sl, 0], rcond=None)[0]
        g = c[0] - 1j * c[1]
        rows.append((float(np.median(f_inst[sl])), abs(g), float(np.angle(g)),
                     float(np.abs(m[sl, 0]).max())))
    f, gain, ph, amp = map(np.array, zip(*rows, strict=True))
    keep = (f > 1.0) & (f < 9.0)
    wgt = amp[keep]
    slope = np.polyfit(f[keep], np.degrees(ph[keep]), 1, w=wgt)[0]
    return {"freq_hz": np.round(f, 2).tolist(), "gain_cart1": np.round(gain, 3).tolist(),
            "phase_cart1_deg": np.round(np.degrees(ph), 1).tolist(),
            "delay_ms": round(float(-slope / 360.0 * 1e3), 2)}


def markdown(joint: dict, loro: dict | None) -> str:
    lines = ["| model | " + " | ".join(SHORT) + " |", "|---" * (len(SHORT) + 1) + "|"]
    for label, _, _, _ in STEPS:
        cells = [", ".join(f"{x:.1f}" for x in row) for row in joint[label]["fit"]]
        lines.append(f"| {label} (in sample) | " + " | ".join(cells) + " |")
        if loro and label in loro:
            cells = [", ".join(f"{x:.1f}" for x in row) for row in loro[label]["fit"]]
            lines.append(f"| {label} (held out) | " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("| model | g_v per record (N/V) | v_offset per record (mV) | other |")
    lines.append("|---|---|---|---|")
    for label, _, _, _ in STEPS:
        th, names = np.array(joint[label]["theta"]), joint[label]["names"]
        g = ", ".join(f"{x:.2f}" for x in th[:, 0])
        off = (", ".join(f"{1e3 * x:.1f}" for x in th[:, names.index("v_offset")])
               if "v_offset" in names else "-")
        other = ", ".join(f"{n} {th[0, i]:.3g}" for i, n in enumerate(names)
                          if n.startswith(("F", "v_dead", "tau", "v_sat", "kappa")))
        if "c1" in joint[label]["per_record"]:
            other += ", c1 " + ", ".join(f"{x:.2f}" for x in th[:, names.index("c1")])
        lines.append(f"| {label} | {g} | {off} | {other} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-loro", action="store_true", help="joint fits only")
    ap.add_argument("--cache", default=str(ROOT / "out" / "discrepancy_table"))
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "discrepancy_table.json"))
    args = ap.parse_args(argv)
    recs = load_records()
    cache = Path(args.cache)
    joint = joint_fits(recs, cache)
    loro = None if args.no_loro else loro_fits(recs, joint, cache)
    checks = {label: residual_checks(recs, label, joint) for label in ("friction", FINAL)}
    needs = record_checks(recs, joint, loro)
    out = {"records": list(RECORDS), "steps": [s[0] for s in STEPS],
           "joint": joint, "loro": loro, "residuals": checks, "records_need": needs}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))
    print(markdown(joint, loro))
    for label, c in checks.items():
        for rec, item in c.items():
            extra = f", equivalent delay {item['delay_ms']} ms" if "delay_ms" in item else ""
            print(f"{label} / {rec}: mean residual {item['mean_counts']} counts, "
                  f"below 0.5 Hz {item['slow_share']}{extra}")
    print(json.dumps(needs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
