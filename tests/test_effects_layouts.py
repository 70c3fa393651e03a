"""Every effect on every layout: 1 cart, 2 carts with the frame spring at the driven cart
(free, and with cart 2 clamped), the 3-cart chain, 4 carts driven at cart 2 with three
sensors, and a reversed drive, each against the independent references of
tests/reference_sim.py, reference_effects.py and reference_stop.py run on a rig assembled
there by hand (``RefLayout``).

Tolerances are the schemes' own errors: the exact simulators (linear in the state) agree
to the reference's integration tolerance; the second-order schemes to 1.5 times their
step-doubling estimate (the error of a second-order scheme is 4/3 of the difference
between it and its run with half the sub-step) plus that tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from reference_effects import NEW_REFERENCES
from reference_sim import REFERENCES, RTOL, RefLayout, simulate_linear_ref
from reference_stop import simulate_stop_ref

from bayesmodal import ModelError
from bayesmodal.model.effects import EXTENSIONS
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import Cart, Drive, LinearModel, Rig, Sensor, Spring

DT = 0.005
COUNT = 4.4125e-06  # m per encoder count: the effects must show at this resolution
REFS = {**REFERENCES, **NEW_REFERENCES, "end_stop": simulate_stop_ref}

_TWO = load_rig("ecp210-2cart-frame-at-drive")  # frame - k1 - cart 1 (motor) - k2 - cart 2


def _four() -> Rig:
    carts = tuple(Cart(str(i)) for i in range(1, 5))
    springs = (Spring("1", "frame", 800.0), Spring("1", "2", 450.0), Spring("2", "3", 400.0),
               Spring("3", "4", 350.0), Spring("4", "frame", 600.0))
    return Rig(carts=carts, springs=springs, drive=(Drive("2"),),
               sensors=tuple(Sensor(c, "count", COUNT) for c in ("1", "2", "4")))


#: name -> (rig, hand-assembled reference layout, linear parameters)
LAYOUTS = {
    "one_cart": (load_rig("ecp210-1cart"), RefLayout(1, [(0, -1, 396.0)]),
                 [6.0, 1.3, 2.5]),
    "two_frame_at_drive": (_TWO, RefLayout(2, [(0, -1, 770.0), (0, 1, 396.0)]),
                           [6.0, 1.5, 1.3, 2.8, 2.0, 0.3]),
    "two_cart2_clamped": (dataclasses.replace(_TWO, clamped=("2",), dampers=None,
                                              sensors=(Sensor("1", "count", COUNT),)),
                          RefLayout(1, [(0, -1, 770.0), (0, -1, 396.0)]), [6.0, 1.5, 2.8]),
    "four_driven_at_2": (_four(), RefLayout(
        4, [(0, -1, 800.0), (0, 1, 450.0), (1, 2, 400.0), (2, 3, 350.0), (3, -1, 600.0)],
        driven=1, outputs=[0, 1, 3]), [6.0, 1.4, 1.5, 1.2, 1.1, 2.5, 2.0, 1.8, 2.2, 0.3,
                                       0.2, 0.25]),
    "reversed_drive": (dataclasses.replace(_TWO, drive=(Drive("1", -1.0),)),
                       RefLayout(2, [(0, -1, 770.0), (0, 1, 396.0)], share=-1.0),
                       [6.0, 1.5, 1.3, 2.8, 2.0, 0.3]),
}
_CHAIN = Rig()
LAYOUTS["three_chain"] = (_CHAIN, RefLayout(3, [(0, 1, _CHAIN.springs_n_m[0]),
                                                (1, 2, _CHAIN.springs_n_m[1]),
                                                (2, -1, _CHAIN.springs_n_m[2])]),
                          [6.2, 1.56, 1.46, 1.15, 2.9, 1.8, 2.0, 0.3, 0.2])


def _effect_values(name: str, rig: Rig) -> np.ndarray:
    """Effect parameters of realistic size for ``rig`` (per cart, per spring or global)."""
    n = rig.n_carts
    ramp = np.linspace(1.0, 0.7, n)
    if name == "coulomb_friction":
        return np.r_[0.12 * ramp, 0.2 * ramp]
    if name == "coulomb_directional":
        return np.r_[0.12 * ramp, 0.06 * ramp, 0.2 * ramp]
    if name == "lugre_friction":
        return np.r_[0.12 * ramp, 0.2 * ramp, 2e4, 100.0, 0.005]
    if name == "sensor_gain":
        return np.linspace(1.04, 0.96, rig.n_outputs - 1)
    if name == "cubic_stiffness":
        q = len(EXTENSIONS[name].specs(rig))
        return 1e5 * np.where(np.arange(q) % 2, -0.5, 1.0)
    return np.array({"motor_lag": [0.01], "input_delay": [0.0123], "backlash": [6e-4, 0.2],
                     "input_saturation": [2.5], "input_offset": [0.15],
                     "drive_deadband": [0.3], "amplitude_gain": [0.03],
                     "end_stop": [0.012, 2000.0]}[name])


def _input(N=600):
    # a 3 V pulse, a held step and a negative pulse: sticking, reversals, held forces
    u = np.zeros(N)
    u[1:10] = 3.0
    u[200:300] = 0.4
    u[400:410] = -2.5
    return u


def _case(layout: str, name: str):
    rig, ref_layout, lin = LAYOUTS[layout]
    theta = np.r_[lin, _effect_values(name, rig)]
    return rig, ref_layout, theta


#: the quick cases of the default suite; every other pair runs with -m slow (each new
#: layout size compiles its own friction, cubic and backlash kernels)
QUICK = {("two_frame_at_drive", "coulomb_friction"), ("reversed_drive", "end_stop"),
         ("four_driven_at_2", "motor_lag"), ("two_cart2_clamped", "input_offset"),
         ("one_cart", "drive_deadband")}
CASES = [pytest.param(lay, name, id=f"{lay}-{name}",
                      marks=() if (lay, name) in QUICK else pytest.mark.slow)
         for lay in LAYOUTS for name in sorted(EXTENSIONS)
         if EXTENSIONS[name].unsupported(LAYOUTS[lay][0]) is None]  # sensor_gain: 2 sensors


def test_reference_layouts_match_the_package_linear_model():
    """The hand-assembled references and the rig descriptions are the same linear rig."""
    u = _input(300)
    for layout, (rig, ref_layout, lin) in LAYOUTS.items():
        y = simulate_linear(LinearModel(rig, "free"), np.asarray(lin), u, DT)
        y_ref = simulate_linear_ref(ref_layout, np.asarray(lin), u, DT)[:, ref_layout.outputs]
        tol = 1e3 * RTOL * np.max(np.abs(y_ref))
        assert np.max(np.abs(y - y_ref)) < tol, layout


@pytest.mark.parametrize(("layout", "name"), CASES)
def test_effect_matches_reference_on_layout(layout, name):
    rig, ref_layout, theta = _case(layout, name)
    ext = EXTENSIONS[name]
    u = _input()
    y_ref = REFS[name](ref_layout, theta, u, DT)[:, ref_layout.outputs]
    y = ext.simulate(rig, theta, u, DT)
    p = LinearModel(rig, "free").n_params
    y_lin = simulate_linear(LinearModel(rig, "free"), theta[:p], u, DT)
    assert np.max(np.abs(y_ref - y_lin)) > 20 * COUNT, "the effect must be visible"
    ode_tol = 1e3 * RTOL * np.max(np.abs(y_ref))
    tol = ode_tol
    if not ext.exact and hasattr(ext, "n_sub"):
        fine = dataclasses.replace(ext, n_sub=2 * ext.n_sub).simulate(rig, theta, u, DT)
        tol += 1.5 * 4.0 / 3.0 * np.max(np.abs(y - fine))
    err = np.max(np.abs(y - y_ref))
    assert err < tol, f"{layout} {name}: error {err / COUNT:.3g} counts, tol {tol / COUNT:.3g}"


def test_effects_at_the_driven_cart_need_exactly_one_drive():
    """Backlash, the end stop and the motor lag act at the driven cart: a rig whose motor
    drives two carts is refused with the fix; friction and the input stages are not."""
    rig = dataclasses.replace(_TWO, drive=(Drive("1"), Drive("2", 0.5)))
    lin = np.array([6.0, 1.5, 1.3, 2.8, 2.0, 0.3])
    u = _input(50)
    for name in ("backlash", "end_stop", "motor_lag"):
        ext = EXTENSIONS[name]
        assert "exactly one cart" in ext.unsupported(rig)
        with pytest.raises(ModelError, match="exactly one cart"):
            ext.simulate(rig, np.r_[lin, _effect_values(name, rig)], u, DT)
    for name in ("input_offset", "coulomb_friction"):  # negative control
        assert EXTENSIONS[name].unsupported(rig) is None


def test_per_cart_names_follow_the_carts_of_a_clamped_rig():
    """Friction parameters carry the cart numbers, not the degree of freedom's: with cart
    2 of three clamped, the free carts are 1 and 3."""
    rig = dataclasses.replace(_CHAIN, springs_n_m=None, clamped=("2",), dampers=None,
                              sensors=(Sensor("1"), Sensor("3")))
    assert EXTENSIONS["coulomb_friction"].extension_names(rig) == ("Fc1", "Fc3", "Fs1", "Fs3")
