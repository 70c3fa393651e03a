"""Make ``two_carts.csv``: a small record of the rig described in ``two_carts_rig.toml``.

The record of docs/getting_started.md.  The linear free-damping model of the two-cart rig
with the parameters ``TRUE`` below, driven by two 3 V pulses 50 ms wide, 5 s apart,
sampled at 5 ms for 10 s, with white measurement noise of 10 micrometres on each cart.
The file is CSV in SI units (``t`` s, ``v`` V, ``x1, x2`` m), the form a lab's logger
export takes after ``bayesmodal inspect`` has shown its columns.

Run from the repository root:  python data/make_two_carts.py
"""

from pathlib import Path

import numpy as np

from bayesmodal.data import Experiment, save_csv
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel

HERE = Path(__file__).resolve().parent
RIG = HERE / "two_carts_rig.toml"
#: The parameters the record is made with: drive gain (N/V), masses (kg), dampers (N s/m).
TRUE = {"g_v": 6.0, "m1": 1.6, "m2": 1.2, "c1": 3.0, "c2": 1.5, "c12": 0.3}
NOISE_SD_M = 1e-5
SEED = 41
DT = 0.005
N = 2001


def make(rng=SEED) -> Experiment:
    """The record, from the seed ``rng`` (a seed or a ``numpy.random.Generator``)."""
    rng = np.random.default_rng(rng)
    model = LinearModel(load_rig(RIG), "free")
    theta = np.array([TRUE[name] for name in model.names])
    t = np.arange(N) * DT
    v = np.where((t % 5.0 >= 0.1) & (t % 5.0 < 0.15), 3.0, 0.0)
    y = simulate_linear(model, theta, v, DT)
    y = y + rng.normal(scale=NOISE_SD_M, size=y.shape)
    return Experiment(t, v, y, name="two_carts", source="data/make_two_carts.py")


if __name__ == "__main__":
    out = HERE / "two_carts.csv"
    save_csv(make(), out)
    print(f"wrote {out.relative_to(Path.cwd()) if out.is_relative_to(Path.cwd()) else out}")
