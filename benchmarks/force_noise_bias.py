"""Bias of the least-squares fit when the measured force carries its own sensor noise.

A rig with a force input (``[drive] input = "force"``) takes the recorded force as the
exact input: the force sensor's noise is not modelled (no errors-in-variables
likelihood).  This script measures what that costs on a synthetic hammer test: a two-cart
rig (cart 1 - k1 - cart 2 - k2 - frame, both springs unknown, masses unknown) struck on
cart 1 every 2 s, accelerometers on both carts.  Each replicate draws fresh accelerometer
noise and, for each force-noise level, fresh force-sensor noise added to the force the
model is given (the rig moved under the true force), fits ``fit_lsq`` and records the
relative error of every parameter and of the modal omega and zeta.  The bias is the
mean relative error over the replicates, with its standard error (std / sqrt(R)).

Usage::

    python benchmarks/force_noise_bias.py [--replicates 100] [--out bias.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402

from bayesmodal.data import Experiment  # noqa: E402
from bayesmodal.fit import fit_lsq  # noqa: E402
from bayesmodal.modal import state_space_modes  # noqa: E402
from bayesmodal.model.simulate import simulate_linear  # noqa: E402
from bayesmodal.model.system import (  # noqa: E402
    Cart,
    Drive,
    LinearModel,
    Rig,
    Sensor,
    Spring,
)

#: (m1, m2 kg, c1, c2, c12 N s/m, k1, k2 N/m) in LinearModel(RIG, "free").names order.
TRUTH = np.array([1.5, 1.4, 2.0, 1.5, 0.5, 774.0, 770.0])
DT = 0.002
N = 5000
PEAK_N = 100.0  #: hammer peak force, N
SIGMA_ACC = 0.05  #: accelerometer noise, m/s^2
#: Force-sensor noise levels, N (0, 0.1 %, 0.5 % and 1 % of the peak).
FORCE_NOISE_N = (0.0, 0.1, 0.5, 1.0)

RIG = Rig(carts=(Cart("1"), Cart("2")),
          springs=(Spring("1", "2", 774.0, known=False, name="k1"),
                   Spring("2", "frame", 770.0, known=False, name="k2")),
          drive=(Drive("1"),), input="force",
          sensors=(Sensor("1", "g"), Sensor("2", "g")))


def hammer(n: int = N, dt: float = DT, peak: float = PEAK_N) -> np.ndarray:
    """Half-sine impacts of 4 ms every 2 s, N."""
    f = np.zeros(n)
    width = max(int(round(0.004 / dt)), 1)
    pulse = peak * np.sin(np.pi * (np.arange(width) + 0.5) / width)
    for k0 in range(int(0.1 / dt), n - width, int(2.0 / dt)):
        f[k0 : k0 + width] = pulse
    return f


def modal(model, theta) -> np.ndarray:
    """omega (2) then zeta (2) of a parameter vector."""
    m = state_space_modes(model, theta)
    return np.r_[m.omega_rad_s, m.zeta]


def replicate(seed: int, levels=FORCE_NOISE_N) -> dict:
    """Relative errors of (parameters, omega, zeta) per force-noise level, one replicate."""
    rng = np.random.default_rng(seed)
    model = LinearModel(RIG, "free")
    f = hammer()
    t = np.arange(N) * DT
    y = simulate_linear(model, TRUTH, f, DT) + rng.normal(0.0, SIGMA_ACC, (N, 2))
    truth = np.r_[TRUTH, modal(model, TRUTH)]
    out = {}
    for level in levels:
        f_meas = f + rng.normal(0.0, level, N) if level > 0 else f
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit_lsq(Experiment(t, f_meas, y), model, theta0=TRUTH)
        est = np.r_[res.theta, modal(model, res.theta)]
        out[level] = (est - truth) / truth
    return out


def names() -> list[str]:
    return list(LinearModel(RIG, "free").names) + ["omega1", "omega2", "zeta1", "zeta2"]


def study(replicates: int, levels=FORCE_NOISE_N, seed0: int = 0) -> dict:
    """Mean relative error and its standard error per level and quantity."""
    runs = [replicate(seed0 + r, levels) for r in range(replicates)]
    table = {}
    for level in levels:
        e = np.array([r[level] for r in runs])
        table[float(level)] = {
            nm: {"bias": float(e[:, j].mean()),
                 "se": float(e[:, j].std(ddof=1) / np.sqrt(len(e)))}
            for j, nm in enumerate(names())}
    return table


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--replicates", type=int, default=100)
    p.add_argument("--out", default=None, help="write the table as JSON")
    a = p.parse_args(argv)
    table = study(a.replicates)
    print(f"relative bias (mean over {a.replicates} replicates +- standard error), "
          f"hammer peak {PEAK_N:g} N, accelerometer noise {SIGMA_ACC:g} m/s^2")
    print("force noise N | " + " | ".join(names()))
    for level, row in table.items():
        print(f"{level:g} | " + " | ".join(f"{100 * d['bias']:+.3f} +- {100 * d['se']:.3f} %"
                                          for d in row.values()))
    if a.out:
        Path(a.out).write_text(json.dumps(table, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
