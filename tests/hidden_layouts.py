"""Synthetic records hiding effects on several rig layouts (tests and benchmark).

Layouts: one cart (``ecp210-1cart``), two carts with the frame spring at the driven cart
(``ecp210-2cart-frame-at-drive``) and the three-cart chain (``Rig()``).  The data come
from the independent reference simulators (tests/reference_sim.py, reference_effects.py,
reference_stop.py, ``solve_ivp`` on a rig assembled there by hand, ``RefLayout``), never
from the package's kernels; sizes and locations are drawn from the seed:

===============================  ========================================================
case                             effects drawn
===============================  ========================================================
none                             the linear rig
coulomb_friction                 one cart, Fc 0.3-1.5 N, Fs = Fc x 1.0-1.5
input_offset                     0.03-0.15 V, either sign
drive_deadband                   0.1-0.3 V
end_stop                         at 55-75 % of the driven cart's largest positive travel
                                 in the linear response, 1-3 kN/m
cubic_stiffness                  one spring, force change 5-15 % at its largest
                                 extension in the linear response, either sign
backlash                         gap 0.3-1 mm, motor mass 0.1-0.3 kg
coulomb_friction+input_offset    both as above (the offset before the friction rig)
coulomb_friction+drive_deadband  both as above
backlash+motor_lag               backlash as above and a lag of 10-30 ms
===============================  ========================================================

Record: ``hidden_effects.rig_input`` (pulses of 3 V and 1.5 V of both signs, then steps),
white noise of 0.3-1 count, rounding to counts; the linear parameters perturbed by up to
5 % per seed.  With ``slow_drive`` the record goes on with a slow triangle of the drive
(``slow_triangle``, half as many samples again): friction on the driven cart with a
drive offset and directional friction move the cart alike under pulses and steps and
differ only in the breakaway force, which a slow drive reaches gradually
(``bayesmodal.discrepancy.diagnosis.equivalence``).
"""

from __future__ import annotations

import numpy as np
from hidden_effects import DT, rig_input
from hidden_pairs import HiddenCase, _friction, counts, input_stages
from reference_sim import (
    RefLayout,
    simulate_backlash_ref,
    simulate_coulomb_ref,
    simulate_cubic_ref,
    simulate_linear_ref,
)
from reference_stop import simulate_stop_ref

from bayesmodal.data import Experiment
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.system import Rig

CASES = ("none", "coulomb_friction", "input_offset", "drive_deadband", "end_stop",
         "cubic_stiffness", "backlash", "coulomb_friction+input_offset",
         "coulomb_friction+drive_deadband", "backlash+motor_lag")

_K3 = Rig().springs_n_m
#: layout -> (preset or Rig, hand-assembled reference, linear parameters in model order)
LAYOUTS = {
    "one_cart": ("ecp210-1cart", RefLayout(1, [(0, -1, 396.0)]),
                 np.array([6.223, 1.565, 2.923])),
    "two_frame_at_drive": ("ecp210-2cart-frame-at-drive",
                           RefLayout(2, [(0, -1, 770.0), (0, 1, 396.0)]),
                           np.array([6.223, 1.565, 1.461, 2.923, 1.806, 0.3])),
    "three_chain": ("ecp210-3cart",
                    RefLayout(3, [(0, 1, _K3[0]), (1, 2, _K3[1]), (2, -1, _K3[2])]),
                    np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.3, 0.2])),
}


def layout_rig(layout: str) -> Rig:
    """The package's description of ``layout``."""
    return load_rig(LAYOUTS[layout][0])


def _spring_extension(ref: RefLayout, y: np.ndarray) -> np.ndarray:
    """Largest extension of every spring over the response ``y`` (N, n), m."""
    out = []
    for a, b in ref.spring_ends:
        e = (y[:, b] if b >= 0 else 0.0) - (y[:, a] if a >= 0 else 0.0)
        out.append(np.max(np.abs(e)))
    return np.array(out)


def slow_triangle(n_samples: int, peak: float = 1.5) -> np.ndarray:
    """A slow triangle of the drive, V: at rest for 5 % of ``n_samples``, up to ``peak``
    at 30 %, down to ``-peak`` at 80 %, back to 0 at 95 %, then at rest (1.5 V over
    ``0.25 n_samples`` samples: 1.2 V/s over 1 200 samples of 5 ms)."""
    t = np.arange(n_samples) / n_samples
    return np.interp(t, [0.0, 0.05, 0.3, 0.8, 0.95, 1.0], [0.0, 0.0, peak, -peak, 0.0, 0.0])


def make_layout_case(layout: str, case: str, seed: int, n_samples: int = 2400,
                     slow_drive: bool = False) -> HiddenCase:
    """One record of ``case`` (``CASES``) on ``layout`` (``LAYOUTS``) drawn from ``seed``:
    ``n_samples`` of pulses and steps, then with ``slow_drive`` ``n_samples // 2`` of
    ``slow_triangle``.

    ``effects`` of the result maps each effect to its location: the cart numbers (friction,
    end stop, backlash: the driven cart 1), the spring's place in the rig description
    (cubic stiffness, 1-based) or None (the input stages).
    """
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; known: {CASES}")
    _, ref, base = LAYOUTS[layout]
    rng = np.random.default_rng(seed)
    theta_lin = base * rng.uniform(0.95, 1.05, base.size)
    u = rig_input(n_samples)
    if slow_drive:
        u = np.concatenate([u, slow_triangle(n_samples // 2)])
    n_samples = u.size
    names = [] if case == "none" else case.split("+")
    n = ref.n
    v, effects, sizes = input_stages(rng, names, u)
    if "coulomb_friction" in names:
        i, w = _friction(rng, n)
        effects["coulomb_friction"], sizes["coulomb_friction"] = [i + 1], w.tolist()
        y = simulate_coulomb_ref(ref, np.r_[theta_lin, w], v, DT)
    elif "end_stop" in names:
        y_lin = simulate_linear_ref(ref, theta_lin, v, DT)
        x_stop = rng.uniform(0.55, 0.75) * np.max(y_lin[:, ref.driven])
        k_stop = rng.uniform(1e3, 3e3)
        effects["end_stop"], sizes["end_stop"] = [ref.driven + 1], [x_stop, k_stop]
        y = simulate_stop_ref(ref, np.r_[theta_lin, x_stop, k_stop], v, DT)
    elif "cubic_stiffness" in names:
        y_lin = simulate_linear_ref(ref, theta_lin, v, DT)
        q = len(ref.springs)
        i = int(rng.integers(q))
        d = _spring_extension(ref, y_lin)[i]
        frac = rng.uniform(0.05, 0.15) * rng.choice([-1.0, 1.0])
        k3 = np.zeros(q)
        k3[i] = frac * ref.springs[i][2] / d**2
        effects["cubic_stiffness"], sizes["cubic_stiffness"] = [i + 1], k3.tolist()
        y = simulate_cubic_ref(ref, np.r_[theta_lin, k3], v, DT)
    elif "backlash" in names:
        gap, m_p = rng.uniform(3e-4, 1e-3), rng.uniform(0.1, 0.3)
        tau = rng.uniform(0.010, 0.030) if "motor_lag" in names else 0.0
        effects["backlash"], sizes["backlash"] = [ref.driven + 1], [gap, m_p]
        if tau:
            effects["motor_lag"], sizes["motor_lag"] = None, [tau]
        y = simulate_backlash_ref(ref, np.r_[theta_lin, gap, m_p], v, DT, tau=tau)
    else:
        y = simulate_linear_ref(ref, theta_lin, v, DT)
    e = Experiment(np.arange(n_samples) * DT, u, counts(y[:, ref.outputs], rng),
                   name=f"{layout}-{case}-{seed}")
    return HiddenCase(e, case, effects, sizes, theta_lin)

