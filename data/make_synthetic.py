"""Make ``synthetic_impulses.csv``: a stand-in for the measured impulse test.

The README's main job runs on the measured data in ``../shared/data`` when present and on
this file otherwise.  It is the linear free-damping model with the report's Table 3
parameters, driven by 3 V pulses 50 ms wide every 10 s (as in ``data_impulses``), with
AR(1) output noise (phi = 0.9, innovation sd 2e-5 m) and encoder quantisation
(0.0706/16000 m), sampled at 5 ms for 20 s.

Run from the repository root:  python data/make_synthetic.py
"""

from pathlib import Path

import numpy as np

from bayesmodal.data import ECP_M_PER_COUNT, Experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

TABLE3 = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])
SEED = 20161
DT = 0.005
N = 4001


def make(rng=SEED) -> Experiment:
    rng = np.random.default_rng(rng)
    t = np.arange(N) * DT
    v = np.where((t % 10.0) < 0.05, 3.0, 0.0)
    v[0] = 0.0
    y = simulate_linear(LinearModel(Rig(), "free"), TABLE3, v, DT)
    phi, sd = 0.9, 2e-5
    e = rng.normal(scale=sd, size=y.shape)
    noise = np.zeros_like(y)
    noise[0] = e[0] / np.sqrt(1 - phi**2)
    for k in range(1, N):
        noise[k] = phi * noise[k - 1] + e[k]
    y = np.round((y + noise) / ECP_M_PER_COUNT) * ECP_M_PER_COUNT
    return Experiment(t, v, y, name="synthetic_impulses", source="data/make_synthetic.py")


if __name__ == "__main__":
    out = Path(__file__).with_name("synthetic_impulses.csv")
    save_csv(make(), out)
    print(f"wrote {out}")
