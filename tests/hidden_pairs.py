"""Synthetic rig data hiding the newer effects alone and effects in pairs (tests, benchmark).

Same record as ``hidden_effects.py`` (pulses then steps, Table 3 parameters perturbed by
up to 5 %, white noise of 0.3-1 count, rounding to counts); the data come from the
independent reference simulators of ``reference_sim.py`` and ``reference_effects.py``
(``solve_ivp``, never the package's kernels).  Sizes and locations are drawn from the seed:

==================================  ====================================================
case                                effects drawn
==================================  ====================================================
input_offset                        bias of 0.03-0.15 V, either sign
drive_deadband                      threshold 0.1-0.3 V
coulomb_directional                 one cart; one direction's level 0.3-1.0 N, the other
                                    1.5-2.5 times it; Fs 1.0-1.3 times the larger
coulomb_friction+input_offset       friction as in hidden_effects, plus an offset
coulomb_friction+drive_deadband     friction as in hidden_effects, plus a dead band
backlash+motor_lag                  backlash and a lag as in hidden_effects (gap 0.3-1 mm,
                                    motor mass 0.1-0.3 kg, tau 10-30 ms), one reference
                                    with the lagged force as a state
                                    (``simulate_backlash_ref(..., tau=)``)
==================================  ====================================================

The input stages act before the plant, so the friction pairs pass the offset or
dead-banded voltage (``reference_effects.input_chain_ref``) to the event-driven friction
reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hidden_effects import BASE, DT, SPRINGS, Q, rig_input
from reference_effects import input_chain_ref, simulate_directional_coulomb_ref
from reference_sim import simulate_backlash_ref, simulate_coulomb_ref, simulate_linear_ref

from bayesmodal.data import Experiment

CASES = ("input_offset", "drive_deadband", "coulomb_directional",
         "coulomb_friction+input_offset", "coulomb_friction+drive_deadband",
         "backlash+motor_lag")


@dataclass(frozen=True)
class HiddenCase:
    """A synthetic experiment and the effects behind it.

    Attributes
    ----------
    experiment : Experiment
    case : str
    effects : dict
        ``{effect name: 1-based location list or None}``.
    sizes : dict
        ``{effect name: drawn parameters}``.
    theta_lin : ndarray, shape (9,)
        The true linear parameters (``BASE`` perturbed by the seed), model order.
    """

    experiment: Experiment
    case: str
    effects: dict
    sizes: dict
    theta_lin: np.ndarray | None = None


def _friction(rng, n: int = 3):
    """Friction on one of ``n`` carts (drawn): ``(cart index, (Fc_1..Fc_n, Fs_1..Fs_n))``."""
    i = int(rng.integers(n))
    fc = rng.uniform(0.3, 1.5)
    w = np.zeros(2 * n)
    w[i], w[n + i] = fc, fc * rng.uniform(1.0, 1.5)
    return i, w


def input_stages(rng, names, u):
    """The drawn offset and dead band of ``names`` applied to ``u``: ``(voltage at the
    motor, {effect: None}, {effect: [size]})``."""
    effects, sizes = {}, {}
    v = np.array(u, float)
    if "input_offset" in names:
        v0 = rng.uniform(0.03, 0.15) * rng.choice([-1.0, 1.0])
        v = input_chain_ref(v, v_offset=v0)
        effects["input_offset"], sizes["input_offset"] = None, [v0]
    if "drive_deadband" in names:
        vd = rng.uniform(0.1, 0.3)
        v = input_chain_ref(v, v_dead=vd)
        effects["drive_deadband"], sizes["drive_deadband"] = None, [vd]
    return v, effects, sizes


def counts(y, rng):
    """``y`` (m) with white noise of 0.3-1 count (drawn), rounded to whole counts."""
    sigma = rng.uniform(0.3, 1.0) * Q
    return np.round((y + sigma * rng.standard_normal(y.shape)) / Q) * Q


def make_case(case: str, seed: int, n_samples: int = 2400) -> HiddenCase:
    """One experiment of ``case`` (``CASES``) drawn from ``seed``."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; known: {CASES}")
    rng = np.random.default_rng(seed)
    theta_lin = BASE * rng.uniform(0.95, 1.05, BASE.size)
    u = rig_input(n_samples)
    names = case.split("+")
    v, effects, sizes = input_stages(rng, names, u)
    if "coulomb_friction" in names:
        i, w = _friction(rng)
        effects["coulomb_friction"], sizes["coulomb_friction"] = [i + 1], w.tolist()
        y = simulate_coulomb_ref(SPRINGS, np.r_[theta_lin, w], v, DT)
    elif "coulomb_directional" in names:
        i = int(rng.integers(3))
        lo = rng.uniform(0.3, 1.0)
        hi = lo * rng.uniform(1.5, 2.5)
        fp, fn = (lo, hi) if rng.random() < 0.5 else (hi, lo)
        w = np.zeros(9)
        w[i], w[3 + i], w[6 + i] = fp, fn, max(fp, fn) * rng.uniform(1.0, 1.3)
        effects["coulomb_directional"], sizes["coulomb_directional"] = [i + 1], w.tolist()
        y = simulate_directional_coulomb_ref(SPRINGS, np.r_[theta_lin, w], v, DT)
    elif "backlash" in names:
        gap, m_p = rng.uniform(3e-4, 1e-3), rng.uniform(0.1, 0.3)
        tau = rng.uniform(0.010, 0.030)
        effects.update(backlash=[1], motor_lag=None)
        sizes.update(backlash=[gap, m_p], motor_lag=[tau])
        y = simulate_backlash_ref(SPRINGS, np.r_[theta_lin, gap, m_p], v, DT, tau=tau)
    else:
        y = simulate_linear_ref(SPRINGS, theta_lin, v, DT)
    e = Experiment(np.arange(n_samples) * DT, u, counts(y, rng), name=f"{case}-{seed}")
    return HiddenCase(e, case, effects, sizes, theta_lin)


def judge(h: HiddenCase, d) -> tuple[bool, list]:
    """Did the diagnosis name every effect of the case with its location (and nothing on
    a case without effects)?

    Returns ``(correct, found)`` with ``found`` the ``(cause, location)`` pairs of the
    final model (a refined effect counts under its refinement's name).
    """
    if not h.effects:  # null data: nothing may be named
        return d.cause == "none", []
    found = {}
    for c in d.causes:
        if c.replaces:
            found.pop(c.replaces, None)
        found[c.cause] = c.location
    ok = all(name in found and found[name] == loc for name, loc in h.effects.items())
    return ok, sorted(found.items(), key=lambda kv: kv[0])
