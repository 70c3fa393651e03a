"""Make ``accel_hammer.csv`` and ``accel_sweep.csv``: a hammer test and a shaker sine sweep
of the two-cart rig described in ``accel_rig.toml``, measured with accelerometers.

The records of docs/accelerometers.md.  The rig: cart 1 - k1 - cart 2 - k2 - frame, the
springs known from their data sheet, the masses and dampers unknown; the input is the
force on cart 1 measured by a load cell (N); an accelerometer on each cart (m/s^2).  The
linear free-damping model with the parameters ``TRUE`` below is simulated exactly
(``simulate_linear``: accelerations at the samples, with the force held between them).

- hammer: three hits of 60 N peak (a 15 ms half-sine) 8 s apart, sampled at 4 ms for
  24 s;
- sweep: a 4 N linear sine sweep from 1 to 10 Hz over 20 s from a shaker, sampled at 4 ms.

Both carry white noise (accelerometers 0.02 m/s^2, load cell 0.02 N) and are quantised
like a 16-bit logger (1 mm/s^2 and 0.01 N steps).  CSV in SI units: ``t`` s, ``v`` the
force in N, ``x1, x2`` the accelerations of carts 1 and 2 in m/s^2.

Run from the repository root:  python data/make_accel_examples.py
"""

from pathlib import Path

import numpy as np

from bayesmodal.data import Experiment
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel

HERE = Path(__file__).resolve().parent
RIG = HERE / "accel_rig.toml"
#: The parameters the records are made with: masses (kg), dampers (N s/m).
TRUE = {"m1": 1.5, "m2": 1.2, "c1": 1.2, "c2": 0.8, "c12": 0.3}
SIGMA_ACC = 0.02  #: accelerometer noise, m/s^2
SIGMA_FORCE = 0.02  #: load-cell noise, N
STEP_ACC = 1e-3  #: logger resolution of the accelerations, m/s^2
STEP_FORCE = 1e-2  #: logger resolution of the force, N
DT = 0.004
SEED = 40


def _theta(model):
    return np.array([TRUE[name] for name in model.names])


def _measure(rng, t, force, name):
    model = LinearModel(load_rig(RIG), "free")
    acc = simulate_linear(model, _theta(model), force, DT)
    acc = acc + rng.normal(scale=SIGMA_ACC, size=acc.shape)
    f = force + rng.normal(scale=SIGMA_FORCE, size=force.shape)
    return Experiment(t, np.round(f / STEP_FORCE) * STEP_FORCE,
                      np.round(acc / STEP_ACC) * STEP_ACC, name=name,
                      source="data/make_accel_examples.py")


def hammer(rng=SEED) -> Experiment:
    """The hammer record, from the seed ``rng`` (a seed or a ``numpy.random.Generator``)."""
    rng = np.random.default_rng(rng)
    t = np.arange(6000) * DT
    force = np.zeros(t.size)
    pulse = 60.0 * np.sin(np.pi * (np.arange(4) + 0.5) / 4)  # 15 ms half-sine
    for k0 in (25, 2025, 4025):
        force[k0 : k0 + 4] = pulse
    return _measure(rng, t, force, "accel_hammer")


def sweep(rng=SEED + 1) -> Experiment:
    """The shaker sine sweep, from the seed ``rng``."""
    rng = np.random.default_rng(rng)
    t = np.arange(5000) * DT
    f0, f1, span = 1.0, 10.0, 20.0
    phase = 2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / span * t**2)
    force = 4.0 * np.sin(phase) * np.minimum(t / 0.5, 1.0)  # a 0.5 s ramp from rest
    return _measure(rng, t, force, "accel_sweep")


def write(exp: Experiment, path: Path) -> None:
    """CSV with as many digits as the logger has (the values are on its steps)."""
    arr = np.column_stack([exp.t_s, exp.v_volt, exp.y_m])
    tmp = path.with_suffix(".tmp")
    np.savetxt(tmp, arr, delimiter=",", header="t,v,x1,x2", comments="", fmt="%.6g")
    tmp.replace(path)


if __name__ == "__main__":
    for make, name in ((hammer, "accel_hammer.csv"), (sweep, "accel_sweep.csv")):
        out = HERE / name
        write(make(), out)
        print(f"wrote {out.relative_to(Path.cwd()) if out.is_relative_to(Path.cwd()) else out}")
