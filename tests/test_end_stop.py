"""The end stop of the driven cart (``effects.end_stop``): alone and with stick-slip friction
against the independent event-driven references of tests/reference_stop.py, within each
kernel's own step-doubling error estimate; null, batch and combination rules."""

import numpy as np
import pytest
from conftest import TABLE3, zoh_rtol
from reference_sim import RTOL
from reference_stop import simulate_coulomb_stop_ref, simulate_stop_ref

from bayesmodal import ModelError
from bayesmodal.data import ECP_M_PER_COUNT
from bayesmodal.model.effects import (
    Combined,
    CoulombFriction,
    EndStop,
    get_extension,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

RIG = Rig()
DT = 0.005
COUNT = ECP_M_PER_COUNT
STOP = np.array([0.02, 2000.0])            # 20 mm, 2 kN/m: a 3 V pulse reaches 24 mm
FRICTION = np.array([0.2, 0.1, 0.2, 0.25, 0.12, 0.3])


def _input(N=700):
    # a pulse into the stop, a held step (sticking, held forces) and a pulse the other way
    u = np.zeros(N)
    u[1:11] = 3.0
    u[200:400] = 0.4
    u[500:510] = -2.0
    return u


def _ode_tol(y):
    # DOP853 at rtol RTOL: local errors ~ RTOL |y| over a few hundred solver steps
    return 1e3 * RTOL * np.max(np.abs(y))


def _check_second_order(make, theta, y_ref, k):
    """The kernel at ``k`` sub-steps is within 1.5 times its step-doubling estimate
    (``4/3 |y_k - y_2k|``, second order) of the reference, and ``2k`` is closer."""
    y = make(k).simulate(RIG, theta, _input(), DT)
    y2 = make(2 * k).simulate(RIG, theta, _input(), DT)
    estimate = 4.0 / 3.0 * np.max(np.abs(y - y2))
    err, err2 = np.max(np.abs(y - y_ref)), np.max(np.abs(y2 - y_ref))
    assert err <= 1.5 * estimate + _ode_tol(y_ref), (err / COUNT, estimate / COUNT)
    assert err2 < err
    return err


def test_stop_alone_matches_the_event_driven_reference():
    theta = np.r_[TABLE3, STOP]
    y_ref = simulate_stop_ref(RIG.springs_n_m, theta, _input(), DT)
    y_lin = simulate_linear(LinearModel(RIG, "free"), TABLE3, _input(), DT)
    # the stop is reached and changes the response (negative control: the linear model)
    assert y_lin[:, 0].max() > STOP[0] and np.max(np.abs(y_ref - y_lin)) > 500 * COUNT
    _check_second_order(lambda k: EndStop(n_sub=k), theta, y_ref, EndStop().n_sub)


def test_stop_with_friction_matches_the_event_driven_reference():
    """Stick-slip friction and the stop in one kernel: the stop force held at its mid-step
    value, lanes near contact in sub-steps (``kernels.stop``)."""
    theta = np.r_[TABLE3, FRICTION, STOP]
    y_ref = simulate_coulomb_stop_ref(RIG.springs_n_m, theta, _input(), DT)
    y_fr = get_extension("coulomb_friction").simulate(RIG, theta[:-2], _input(), DT)
    assert np.max(np.abs(y_ref - y_fr)) > 500 * COUNT  # the stop matters here too
    _check_second_order(lambda k: Combined((CoulombFriction(n_sub=k), EndStop())), theta,
                        y_ref, CoulombFriction().n_sub)


def test_stop_with_friction_behind_the_fused_input_stages():
    """Offset and dead band applied in the friction kernel before the stop's force."""
    ext = get_extension("coulomb_friction+end_stop+input_offset+drive_deadband")
    theta = np.r_[TABLE3, FRICTION, STOP, 0.03, 0.05]
    y_ref = simulate_coulomb_stop_ref(RIG.springs_n_m, theta[:-2], _input(), DT,
                                      v_offset=0.03, v_dead=0.05)
    y = ext.simulate(RIG, theta, _input(), DT)
    fine = Combined((CoulombFriction(n_sub=8), EndStop()) + ext.effects[2:])
    y2 = fine.simulate(RIG, theta, _input(), DT)
    estimate = 4.0 / 3.0 * np.max(np.abs(y - y2))
    assert np.max(np.abs(y - y_ref)) <= 1.5 * estimate + _ode_tol(y_ref)


def test_without_stiffness_the_stop_vanishes():
    """``k_stop = 0``: friction with the stop is friction alone bit for bit (the stop adds
    an exact zero and never flags a lane), the stop alone is the linear model within the
    zero-order-hold bound of its sub-steps."""
    rng = np.random.default_rng(0)
    batch = np.tile(np.r_[TABLE3, FRICTION, 0.01, 0.0], (20, 1))
    batch[:, 9:15] *= rng.uniform(0.5, 1.5, (20, 6))
    batch[:, 9:12] = np.minimum(batch[:, 9:12], batch[:, 12:15])
    a = get_extension("coulomb_friction+end_stop").simulate(RIG, batch, _input(), DT)
    b = get_extension("coulomb_friction").simulate(RIG, batch[:, :-2], _input(), DT)
    np.testing.assert_array_equal(a, b)
    ext = EndStop()
    y = ext.simulate(RIG, np.r_[TABLE3, 0.01, 0.0], _input(), DT)
    y_lin = simulate_linear(LinearModel(RIG, "free"), TABLE3, _input(), DT)
    A, _ = LinearModel(RIG, "free").state_space(TABLE3)
    n = _input().size
    rtol = zoh_rtol(A, DT, n_steps=n) + zoh_rtol(A, DT / ext.n_sub, n_steps=n * ext.n_sub)
    np.testing.assert_allclose(y, y_lin, rtol=0, atol=rtol * np.max(np.abs(y_lin)))


def test_a_batch_gives_each_lane_its_single_run():
    rng = np.random.default_rng(1)
    batch = np.tile(np.r_[TABLE3, FRICTION, STOP], (12, 1))
    batch[:, -2] *= rng.uniform(0.8, 1.4, 12)
    batch[:, -1] *= rng.uniform(0.0, 2.0, 12)
    for name in ("coulomb_friction+end_stop", "end_stop"):
        ext = get_extension(name)
        rows = batch if "coulomb" in name else batch[:, [*range(9), -2, -1]]
        y = ext.simulate(RIG, rows, _input(), DT)
        for r in (0, 5, 11):
            np.testing.assert_array_equal(y[r], ext.simulate(RIG, rows[r], _input(), DT))


def test_the_stop_on_the_negative_side_mirrors_the_positive_one():
    """The rig is linear apart from the stop: a stop beyond -x_stop under the input -u
    gives the mirror image of the stop beyond +x_stop under u."""
    theta = np.r_[TABLE3, STOP]
    y = EndStop().simulate(RIG, theta, _input(), DT)
    y_neg = EndStop(side=-1).simulate(RIG, theta, -_input(), DT)
    np.testing.assert_allclose(y_neg, -y, rtol=0, atol=1e-12 * np.max(np.abs(y)))


def test_combination_rules_and_location():
    with pytest.raises(ModelError, match="end_stop combines with coulomb_friction or "
                                         "coulomb_directional or lugre_friction or "
                                         "cubic_stiffness only, not with backlash"):
        get_extension("backlash+end_stop")
    with pytest.raises(ModelError, match="two plant-side effects"):
        get_extension("coulomb_friction+lugre_friction+end_stop")
    lagged = get_extension("coulomb_friction+end_stop+motor_lag")
    with pytest.raises(ModelError, match="offset, sharp dead band, saturation"):
        lagged.simulate(RIG, np.r_[TABLE3, FRICTION, STOP, 0.01], _input(100), DT)
    with pytest.raises(ValueError, match="side must be"):
        EndStop(side=0)
    ext = EndStop()
    loc = ext.location_of(RIG, np.r_[TABLE3, STOP])
    assert (loc.kind, loc.index) == ("cart", 0) and "positive" in loc.label
    assert not ext.valid(RIG, np.r_[TABLE3, -0.01, 100.0])    # a stop behind rest
    assert not ext.valid(RIG, np.r_[TABLE3, 0.02, -1.0])      # a pulling stop
    # with friction the model's location is the friction's
    both = get_extension("coulomb_friction+end_stop")
    assert both.location_of(RIG, np.r_[TABLE3, FRICTION, STOP]).label == "cart 3"
    assert both.plant.name == "coulomb_friction" and both.plant_force.name == "end_stop"


def test_diagnose_takes_the_stop_as_an_extra_candidate():
    """``bayesmodal diagnose --candidates +end_stop`` tries the default catalogue and the
    stop; an unknown name is a one-line usage error naming the known ones."""
    import argparse

    from bayesmodal.cli._diagnose import _candidates
    from bayesmodal.discrepancy.diagnosis import DEFAULT_CANDIDATES

    assert _candidates("+end_stop") == [*DEFAULT_CANDIDATES, "end_stop"]
    assert _candidates("coulomb_friction,end_stop") == ["coulomb_friction", "end_stop"]
    with pytest.raises(argparse.ArgumentTypeError, match="known: .*'end_stop'"):
        _candidates("+end_stops")


@pytest.mark.slow  # a stiff Radau reference
def test_stop_with_lugre_friction_matches_the_stiff_reference():
    """LuGre friction and the stop in one kernel (the stop's force held over each sub-step
    at its mid-step value with the friction force): within 1.5 times the step-doubling
    estimate of the reference; ``k_stop = 0`` is LuGre alone bit for bit."""
    from reference_effects import LUGRE_RTOL
    from reference_stop import simulate_lugre_stop_ref

    from bayesmodal.model.effects import LuGreFriction

    lugre = np.array([0.1, 0.15, 0.08, 0.15, 0.2, 0.12, 2e4, 100.0, 0.005])
    theta = np.r_[TABLE3, lugre, STOP]
    u = _input()
    y_ref = simulate_lugre_stop_ref(RIG.springs_n_m, theta, u, DT)
    k = LuGreFriction().n_sub
    y, y2 = (Combined((LuGreFriction(n_sub=m), EndStop())).simulate(RIG, theta, u, DT)
             for m in (k, 2 * k))
    estimate = 4.0 / 3.0 * np.max(np.abs(y - y2))
    err = np.max(np.abs(y - y_ref))
    assert err <= 1.5 * estimate + 1e3 * LUGRE_RTOL * np.max(np.abs(y_ref)), (
        err / COUNT, estimate / COUNT)
    y_lugre = LuGreFriction().simulate(RIG, theta[:-2], u, DT)
    assert np.max(np.abs(y_ref - y_lugre)) > 500 * COUNT  # the stop matters
    off = theta.copy()
    off[-1] = 0.0
    np.testing.assert_array_equal(get_extension("lugre_friction+end_stop").simulate(
        RIG, off, u, DT), y_lugre)
