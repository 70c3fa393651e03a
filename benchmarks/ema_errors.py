"""Do the multi-mode fit's stated errors hold?  Hammer tests of a two-cart rig.

Each replicate makes a hammer test with the independent reference simulator of
``tests/accel_reference.py`` (three hits 4 s apart, accelerometers with white noise and a
logger's quantisation, the force quantised), estimates the accelerance H1 over the hits
(``ema.impact_frf``), fits both modes (``ema.multimode_fit``) and records the z-score
``(estimate - truth) / stated error`` of each mode's omega and zeta.  The truth is the
eigenvalue problem of the reference's own equations of motion.  A stated error that
holds gives z-scores of mean 0 and standard deviation 1, and ``|z| < 1.645`` (the 90 %
interval) in 80-97 % of the replicates (binomial standard error 3 % at 100).

``--frf auto`` runs each hammer test through ``ema.identify`` as ``bayesmodal ema --rig``
does (the force and accelerometer kinds given, the FRF estimate chosen from the record:
a hammer test's hits are found and ``impact_frf`` is used), and records which estimate it
chose; ``--frf welch`` forces the generic Welch estimate (Hann window) on the same
records, the control.

``--case mixed``: the rig driven by a motor through 2 V pulses 12 s apart (three pulses),
read by an encoder on cart 1 and an accelerometer on cart 2
(``accel_reference.mixed_record``); the multi-mode fit reads each FRF in its own form
(``derivative_orders=(0, 2)``, as ``ema.identify(..., output_kinds=("position",
"acceleration"))`` does): the receptance in the continuous basis, the accelerance in the
sampled-data basis, from the pulse FRF without zero padding.

Usage::

    python benchmarks/ema_errors.py --replicates 100
    python benchmarks/ema_errors.py --replicates 100 --time-base continuous  # the control
    python benchmarks/ema_errors.py --replicates 100 --tau 2                 # a window
    python benchmarks/ema_errors.py --replicates 100 --frf auto    # through ema.identify
    python benchmarks/ema_errors.py --replicates 100 --frf welch   # Welch, the control
    python benchmarks/ema_errors.py --replicates 100 --case mixed   # encoder, accelerometer
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]
sys.path.insert(0, str(_HERE.parent / "tests"))

import numpy as np  # noqa: E402
from _replicates import map_replicates  # noqa: E402
from accel_reference import TRUTH as REFERENCE_RIG  # noqa: E402
from accel_reference import measured_record, mixed_record  # noqa: E402

#: (m1, m2 kg, c1, c2, c12 N s/m, k1, k2 N/m): the reference's rig.
TRUTH = np.array(REFERENCE_RIG)
QUANTITIES = ("omega_1", "omega_2", "zeta_1", "zeta_2")


@dataclass(frozen=True)
class Config:
    n_samples: int = 3000      # 12 s at 4 ms: three hits
    dt: float = 0.004
    band: tuple = (5.0, 60.0)  # rad/s
    tau_s: float | None = None  # exponential window, s (None: none)
    time_base: str = "auto"
    case: str = "hammer"       # or "mixed": pulses through a motor, encoder + accelerometer
    every_s: float = 12.0      # the mixed case's pulse spacing, s
    g_v: float = 6.0           # the mixed case's drive gain, N/V
    frf: str = "impact_frf"    # or "auto", "welch": ema.identify with that frf_method


def true_modes(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Omega (rad/s) and zeta of the reference's equations of motion, by frequency: the
    eigenvalues of its first-order form, written here from its free-body diagram."""
    m1, m2, c1, c2, c12, k1, k2 = p
    M = np.diag([m1, m2])
    C = np.array([[c1 + c12, -c12], [-c12, c2 + c12]])
    K = np.array([[k1, -k1], [-k1, k1 + k2]])
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -Minv @ C]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(lam.imag)]
    return np.abs(lam), -lam.real / np.abs(lam)


def replicate(args: tuple[Config, int]) -> dict:
    """One hammer test: the z-scores of omega and zeta of both modes."""
    cfg, seed = args
    from bayesmodal.ema import correct_exponential_window, impact_frf, multimode_fit

    chosen = cfg.frf
    if cfg.case == "mixed":
        est = _mixed_estimate(cfg, seed)
    elif cfg.frf != "impact_frf":
        est, chosen = _identified_estimate(cfg, seed)
    else:
        _, f, y = measured_record(TRUTH, np.random.default_rng([seed, 41]), n=cfg.n_samples,
                                  dt=cfg.dt)
        frf = impact_frf(f, y, cfg.dt, tau_s=cfg.tau_s, derivative_order=2,
                         units="m/s^2/N")
        est = multimode_fit(frf, band=cfg.band, n_modes=2, time_base=cfg.time_base).estimate
    if cfg.tau_s is not None:
        est = correct_exponential_window(est, cfg.tau_s)
    omega, zeta = true_modes(TRUTH)
    z = np.r_[(est.omega_rad_s - omega) / est.omega_se, (est.zeta - zeta) / est.zeta_se]
    return {"seed": seed, "z": z.tolist(), "frf_method": chosen,
            "se": np.r_[est.omega_se, est.zeta_se].tolist()}


def _identified_estimate(cfg: Config, seed: int):
    """The multi-mode estimate of a hammer test by ``ema.identify`` with the rig's input
    and sensor kinds, and the FRF estimate it used."""
    from bayesmodal.data import Experiment
    from bayesmodal.ema import identify

    t, f, y = measured_record(TRUTH, np.random.default_rng([seed, 41]), n=cfg.n_samples,
                              dt=cfg.dt)
    res = identify(Experiment(t, f, y), "multimode", n_modes=2, band=cfg.band,
                   frf_method=cfg.frf, output_kinds=("acceleration", "acceleration"),
                   input_kind="force")
    return res.estimate, res.frf_method


def _mixed_estimate(cfg: Config, seed: int):
    """The multi-mode estimate of a voltage-pulse record read by an encoder and an
    accelerometer."""
    from bayesmodal.data import Experiment
    from bayesmodal.ema import frf_from_experiment, multimode_fit

    n = int(round(3 * cfg.every_s / cfg.dt))
    t, v, y = mixed_record(TRUTH, cfg.g_v, np.random.default_rng([seed, 43]), n=n,
                           dt=cfg.dt, every_s=cfg.every_s)
    frf = frf_from_experiment(Experiment(t, v, y), pad=1)
    return multimode_fit(frf, band=cfg.band, n_modes=2, time_base=cfg.time_base,
                         derivative_orders=(0, 2)).estimate


def run(cfg: Config, replicates: int, processes: int = 1, seed0: int = 0,
        progress: bool = False) -> list[dict]:
    return map_replicates(replicate, [(cfg, seed0 + r) for r in range(replicates)],
                          processes, progress)


def tabulate(results: list[dict]) -> dict:
    """Per quantity: coverage of ``+-1.645`` stated errors, mean and sd of the z-scores."""
    z = np.array([x["z"] for x in results])
    r = z.shape[0]
    return {"replicates": r, "se": float(np.sqrt(0.9 * 0.1 / r)),
            **{q: {"coverage": float(np.mean(np.abs(z[:, j]) < 1.645)),
                   "mean_z": float(np.mean(z[:, j])), "sd_z": float(np.std(z[:, j]))}
               for j, q in enumerate(QUANTITIES)}}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--replicates", type=int, default=100)
    p.add_argument("--processes", type=int, default=min(2, os.cpu_count() or 1))
    p.add_argument("--tau", type=float, default=None, help="exponential window, s")
    p.add_argument("--time-base", default="auto", choices=("auto", "continuous", "discrete"))
    p.add_argument("--case", default="hammer", choices=("hammer", "mixed"))
    p.add_argument("--frf", default="impact_frf", choices=("impact_frf", "auto", "welch"),
                   help="hammer case: impact_frf by hand (default), or ema.identify with "
                   "this FRF estimate")
    p.add_argument("--out", default=None, help="write the raw results and table as JSON")
    a = p.parse_args(argv)
    if a.frf != "impact_frf" and (a.tau is not None or a.case != "hammer"):
        p.error("--frf auto/welch is a hammer case without a window (ema.identify takes no "
                "tau)")
    cfg = Config(tau_s=a.tau, time_base=a.time_base, case=a.case, frf=a.frf)
    res = run(cfg, a.replicates, a.processes, progress=True)
    table = tabulate(res)
    print(f"{table['replicates']} {cfg.case} records, time base {cfg.time_base}, window "
          f"{'none' if cfg.tau_s is None else f'tau {cfg.tau_s:g} s'}; binomial se "
          f"{100 * table['se']:.1f} %")
    if cfg.case == "hammer" and cfg.frf != "impact_frf":
        used = sorted({x["frf_method"] for x in res})
        print(f"ema.identify with frf_method {cfg.frf!r}: the FRF estimate used was "
              f"{', '.join(used)}")
    print("  quantity  coverage  mean z  sd z")
    for q in QUANTITIES:
        t = table[q]
        print(f"  {q:8s}  {100 * t['coverage']:6.0f} %  {t['mean_z']:+6.2f}  {t['sd_z']:5.2f}")
    if a.out:
        Path(a.out).write_text(json.dumps({"config": asdict(cfg), "table": table,
                                           "results": res}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
