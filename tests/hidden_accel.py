"""Synthetic accelerometer records hiding effects on the two-cart rig (tests and benchmark).

The rig: frame - k1 - cart 1 (motor) - k2 - cart 2 (``hidden_layouts`` layout
``two_frame_at_drive``) read by an accelerometer on each cart (m/s^2).  The records come
from the independent reference simulators (tests/reference_sim.py, reference_stop.py:
``solve_ivp`` on the rig assembled by hand), never from the package's kernels; the
acceleration at each sample is the reference's own right-hand side at the sampled state
with the input held from that sample (what ``simulate_linear`` calls an acceleration
output):

================  =====================================================================
case              effect drawn from the seed (as in ``hidden_layouts``)
================  =====================================================================
none              the linear rig
coulomb_friction  one cart, Fc 0.3-1.5 N, Fs = Fc x 1.0-1.5
end_stop          at 55-75 % of the driven cart's largest positive travel in the linear
                  response, 1-3 kN/m
cubic_stiffness   one spring, force change 5-15 % at its largest extension in the
                  linear response, either sign
================  =====================================================================

Record: ``hidden_effects.rig_input`` (pulses of 3 V and 1.5 V of both signs, then steps),
white accelerometer noise of 0.01-0.03 m/s^2 (drawn), a 16-bit converter over +-4 g
(a step of 8 g / 2^16 = 1.2e-3 m/s^2); the linear parameters perturbed by up to 5 % per
seed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hidden_effects import DT, rig_input
from hidden_layouts import LAYOUTS, _spring_extension, layout_rig
from hidden_pairs import HiddenCase, _friction
from reference_sim import (
    rig_matrices,
    simulate_coulomb_ref,
    simulate_cubic_ref,
    simulate_linear_ref,
)
from reference_stop import _stop_force, simulate_stop_ref

from bayesmodal.data import Experiment
from bayesmodal.model.elements import Sensor
from bayesmodal.model.system import Rig

CASES = ("none", "coulomb_friction", "end_stop", "cubic_stiffness")
LAYOUT = "two_frame_at_drive"
G = 9.80665
#: Step of a 16-bit converter over +-4 g, m/s^2.
ADC_STEP = 8 * G / 2**16


def accel_rig() -> Rig:
    """The two-cart rig of ``LAYOUT`` read by an accelerometer on each cart (m/s^2)."""
    rig = layout_rig(LAYOUT)
    return replace(rig, sensors=tuple(Sensor(s.cart, "m/s^2") for s in rig.sensors))


def adc(a: np.ndarray, rng) -> np.ndarray:
    """``a`` (m/s^2) with white noise of 0.01-0.03 m/s^2 (drawn), rounded to ``ADC_STEP``."""
    sigma = rng.uniform(0.01, 0.03)
    return np.round((a + sigma * rng.standard_normal(a.shape)) / ADC_STEP) * ADC_STEP


def _friction_accelerations(ref, theta, z, v):
    """Accelerations (N, n) of the stick-slip reference at its sampled states ``z`` (N, 2n):
    a held cart (velocity exactly 0, net force below Fs) reads 0, a sliding one
    ``(F - Fc sign(x')) / m``, one breaking away ``(F - Fc sign(F)) / m``."""
    p = ref.n_linear
    M, C, K, b = rig_matrices(ref, theta[:p])
    n = M.shape[0]
    fc, fs = np.asarray(theta[p : p + n]), np.asarray(theta[p + n : p + 2 * n])
    x, xd = z[:, :n], z[:, n:]
    F = v[:, None] * b[None] - x @ K.T - xd @ C.T
    held = (xd == 0.0) & (np.abs(F) < fs)
    d = np.where(xd != 0.0, np.sign(xd), np.sign(F))
    return np.where(held, 0.0, (F - fc * d) / np.diag(M))


def _stop_accelerations(ref, theta, z, v):
    """Accelerations (N, n) of the end-stop reference at its sampled states (N, 2n)."""
    p = ref.n_linear
    M, C, K, b = rig_matrices(ref, theta[:p])
    n = M.shape[0]
    x, xd = z[:, :n], z[:, n:]
    F = v[:, None] * b[None] - x @ K.T - xd @ C.T
    j = ref.driven
    F[:, j] += [_stop_force(xj, 1, theta[p], theta[p + 1]) for xj in x[:, j]]
    return F / np.diag(M)


def make_accel_case(case: str, seed: int, n_samples: int = 2400) -> HiddenCase:
    """One accelerometer record of ``case`` (``CASES``) drawn from ``seed``.

    ``effects`` of the result maps each effect to its location as in
    ``hidden_layouts.make_layout_case`` (cart numbers, or the spring's 1-based place).
    """
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; known: {CASES}")
    _, ref, base = LAYOUTS[LAYOUT]
    rng = np.random.default_rng(seed)
    theta_lin = base * rng.uniform(0.95, 1.05, base.size)
    u = rig_input(n_samples)
    effects, sizes = {}, {}
    if case == "coulomb_friction":
        i, w = _friction(rng, ref.n)
        effects[case], sizes[case] = [i + 1], w.tolist()
        theta = np.r_[theta_lin, w]
        z = simulate_coulomb_ref(ref, theta, u, DT, states=True)
        a = _friction_accelerations(ref, theta, z, u)
    elif case == "end_stop":
        y_lin = simulate_linear_ref(ref, theta_lin, u, DT)
        x_stop = rng.uniform(0.55, 0.75) * np.max(y_lin[:, ref.driven])
        k_stop = rng.uniform(1e3, 3e3)
        effects[case], sizes[case] = [ref.driven + 1], [x_stop, k_stop]
        theta = np.r_[theta_lin, x_stop, k_stop]
        a = _stop_accelerations(ref, theta, simulate_stop_ref(ref, theta, u, DT, states=True),
                                u)
    elif case == "cubic_stiffness":
        y_lin = simulate_linear_ref(ref, theta_lin, u, DT)
        q = len(ref.springs)
        i = int(rng.integers(q))
        d = _spring_extension(ref, y_lin)[i]
        frac = rng.uniform(0.05, 0.15) * rng.choice([-1.0, 1.0])
        k3 = np.zeros(q)
        k3[i] = frac * ref.springs[i][2] / d**2
        effects[case], sizes[case] = [i + 1], k3.tolist()
        a = simulate_cubic_ref(ref, np.r_[theta_lin, k3], u, DT, accelerations=True)
    else:
        a = simulate_linear_ref(ref, theta_lin, u, DT, accelerations=True)
    e = Experiment(np.arange(n_samples) * DT, u, adc(a[:, ref.outputs], rng),
                   name=f"accel-{case}-{seed}")
    return HiddenCase(e, case, effects, sizes, theta_lin)
