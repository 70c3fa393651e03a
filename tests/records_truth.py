"""Known-truth records that disagree: several records of one rig, each with its own drive
gain and input offset, AR(1) noise and encoder quantisation (tests and benchmarks only).

The simulator is written independently of the package's: the matrices come from
``reference_sim.rig_matrices`` (assembled by hand from the equations of motion) and the
zero-order-hold recursion from ``scipy.signal.cont2discrete`` and ``scipy.signal.dlsim``
(the package uses a modal recursion compiled with numba).
"""

from __future__ import annotations

import numpy as np
from reference_sim import rig_matrices
from scipy.signal import cont2discrete, dlsim

from bayesmodal.data import Experiment

SPRINGS = (774.0, 770.0, 396.0)
#: Shared physics: masses (kg) and free dampers (N s/m), package order without g_v.
PHYSICS = (1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.3, 0.2)
MU_GV = 5.8          # N/V, population median of the drive gain
TAU_GV = 0.05        # relative spread of the gains
V0_SD = 0.01         # V, spread of the input offsets
SIGMA = 2e-5         # m, AR(1) innovation
PHI = 0.9
M_PER_COUNT = 0.0706 / 16000
DT = 0.005


def inputs(n: int = 2000) -> dict[str, np.ndarray]:
    """Four records of ``n`` samples at the rig's amplitudes: pulses (3 V), steps (0.5 V)
    and two chirps (0.2 V, 0.5-8 Hz up, and 8-0.5 Hz down)."""
    t = np.arange(n) * DT
    period = n * DT / 3
    pulses = 3.0 * ((t % period) < 0.05)
    steps = 0.5 * ((t % period) < period / 2)
    f = 0.5 + (8.0 - 0.5) * t / t[-1]
    up = 0.2 * np.sin(2 * np.pi * np.cumsum(f) * DT)
    down = 0.2 * np.sin(2 * np.pi * np.cumsum(f[::-1]) * DT)
    return {"pulses": pulses, "steps": steps, "chirp_up": up, "chirp_down": down}


def simulate(theta_lin, v, dt=DT):
    """Cart positions (N, 3), m, of the free-damping chain under a ZOH input."""
    M, C, K, b = rig_matrices(SPRINGS, theta_lin)
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.r_[np.zeros(n), Minv @ b][:, None]
    Cm = np.c_[np.eye(n), np.zeros((n, n))]
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, Cm, np.zeros((n, 1))), dt, method="zoh")
    _, y, _ = dlsim((Ad, Bd, Cd, Dd, dt), v[:, None])
    return y


def make_replicate(rng, n: int = 2000):
    """Records and their truths.

    Returns
    -------
    records : list of Experiment
    truth : dict
        ``g_v`` and ``v0`` per record, ``mu_gv`` and the shared physics.
    """
    out, gains, offsets = [], [], []
    for name, v in inputs(n).items():
        g = MU_GV * np.exp(TAU_GV * rng.standard_normal())
        v0 = V0_SD * rng.standard_normal()
        y = simulate(np.r_[g, PHYSICS], v + v0)
        e = np.empty_like(y)
        e[0] = SIGMA / np.sqrt(1 - PHI**2) * rng.standard_normal(3)
        w = SIGMA * rng.standard_normal(y.shape)
        for k in range(1, y.shape[0]):
            e[k] = PHI * e[k - 1] + w[k]
        y_meas = np.round((y + e) / M_PER_COUNT) * M_PER_COUNT  # encoder quantisation
        out.append(Experiment(np.arange(n) * DT, v, y_meas, name=name))
        gains.append(g)
        offsets.append(v0)
    return out, {"g_v": gains, "v0": offsets, "mu_gv": MU_GV, "physics": PHYSICS}


def true_modes():
    """Undamped natural frequencies (rad/s) and modal damping ratios of the truth."""
    from bayesmodal.inference.propagate import propagate_modes
    from bayesmodal.system import LinearModel, Rig

    ms = propagate_modes(LinearModel(Rig(SPRINGS), "free"), np.r_[MU_GV, PHYSICS][None],
                         methods=("eig",))
    return ms.omega_rad_s[0], ms.zeta[0]
