"""Synthetic rig data with one hidden effect, for the diagnose tests and the benchmark.

The data come from the independent reference simulators of ``reference_sim.py`` (not the
package's kernels).  The effect's size and location are drawn from the seed, within the
realistic ranges below, and returned only as the truth to check against; the package
sees nothing but the experiment.

====================  ==========================================================
effect                size drawn
====================  ==========================================================
coulomb_friction      one cart (drawn), Fc 0.3-1.5 N, Fs = Fc x 1.0-1.5
motor_lag             tau 10-30 ms
input_delay           10-30 ms
backlash              gap 0.3-1 mm, reflected motor mass 0.1-0.3 kg (drive of cart 1)
cubic_stiffness       one spring (drawn), hardening or softening, force change
                      5-15 % at the record's largest extension of that spring
input_saturation      60-85 % of the peak input
====================  ==========================================================

Input: pulses (3 V and 1.5 V, both signs, 45 ms like the ECP impulse files) followed by
steps of several levels (0.3-0.8 V), so that amplitude-dependent effects show.  Sensor
noise: white, 0.3-1 encoder count, then rounding to whole counts (0.0706/16000 m).
Linear parameters: the report's Table 3 with small dampers between carts, perturbed by
up to 5 % per seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from reference_sim import REFERENCES, simulate_linear_ref

from bayesmodal.data import ECP_M_PER_COUNT, Experiment

DT = 0.005
Q = ECP_M_PER_COUNT
SPRINGS = (774.0, 770.0, 396.0)
#: Table 3 with visible dampers between carts, free damping order.
BASE = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.3, 0.2])
EFFECTS = ("coulomb_friction", "motor_lag", "input_delay", "backlash", "cubic_stiffness",
           "input_saturation")


@dataclass(frozen=True)
class Hidden:
    """A synthetic experiment and the truth behind it."""

    experiment: Experiment
    effect: str
    location: list | None
    theta_extension: np.ndarray
    theta_linear: np.ndarray


def rig_input(n_samples: int = 3600) -> np.ndarray:
    """Pulses of two amplitudes and both signs, then steps of several levels, V.

    Pulse spacing 11 % and step length 9.2 % of the record (2 s and 1.7 s at 3600
    samples of 5 ms).
    """
    u = np.zeros(n_samples)
    gap, hold = int(0.11 * n_samples), int(0.092 * n_samples)
    k = 1
    for a in (3.0, -1.5, 1.5, -3.0):
        u[k : k + 9] = a
        k += gap
    for a in (0.5, 0.0, -0.3, 0.0, 0.8, 0.0):
        u[k : k + hold] = a
        k += hold
    return u[:n_samples]


def _extensions(springs, theta_lin, u):
    """Largest extension of every spring in the linear response, m."""
    y = simulate_linear_ref(springs, theta_lin, u, DT)
    ext = np.column_stack([y[:, 1] - y[:, 0], y[:, 2] - y[:, 1], -y[:, 2]])
    return np.max(np.abs(ext), axis=0)


def make(effect: str | None, seed: int, n_samples: int = 3600) -> Hidden:
    """One experiment with ``effect`` (None: the linear rig) drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    theta_lin = BASE * rng.uniform(0.95, 1.05, BASE.size)
    u = rig_input(n_samples)
    location = None
    if effect is None:
        ext = np.zeros(0)
        y = simulate_linear_ref(SPRINGS, theta_lin, u, DT)
    else:
        if effect == "coulomb_friction":
            i = int(rng.integers(3))
            fc = rng.uniform(0.3, 1.5)
            ext = np.zeros(6)
            ext[i] = fc
            ext[3 + i] = fc * rng.uniform(1.0, 1.5)
            location = [i + 1]
        elif effect == "motor_lag":
            ext = np.array([rng.uniform(0.010, 0.030)])
        elif effect == "input_delay":
            ext = np.array([rng.uniform(0.010, 0.030)])
        elif effect == "backlash":
            ext = np.array([rng.uniform(3e-4, 1e-3), rng.uniform(0.1, 0.3)])
            location = [1]
        elif effect == "cubic_stiffness":
            i = int(rng.integers(3))
            d = _extensions(SPRINGS, theta_lin, u)[i]
            frac = rng.uniform(0.05, 0.15) * rng.choice([-1.0, 1.0])
            ext = np.zeros(3)
            ext[i] = frac * SPRINGS[i] / d**2
            location = [i + 1]
        elif effect == "input_saturation":
            ext = np.array([rng.uniform(0.60, 0.85) * np.max(np.abs(u))])
        else:
            raise ValueError(f"unknown effect {effect!r}")
        y = REFERENCES[effect](SPRINGS, np.r_[theta_lin, ext], u, DT)
    sigma = rng.uniform(0.3, 1.0) * Q
    y = np.round((y + sigma * rng.standard_normal(y.shape)) / Q) * Q
    e = Experiment(np.arange(n_samples) * DT, u, y, name=f"{effect or 'linear'}-{seed}")
    return Hidden(e, effect or "none", location, ext, theta_lin)
