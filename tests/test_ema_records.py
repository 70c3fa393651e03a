"""EMA on the records people have: single steps, short records, exact rectangular pulses.

Every record is simulated with the package's linear model (so the modes are known) and
its positions are rounded to whole encoder counts, as a rig measures them.  The
identified frequencies must lie within half the frequency resolution of the record
(``pi / T`` for a transient of length ``T``) of the truth, the damping ratios within the
half-power bandwidth that resolution allows (``Delta omega / (2 omega)``).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from test_bad_inputs import _cli
from test_data_layouts import MAP, THETA_2, TWO_CARTS, logger_mat

from bayesmodal.data import ECP_M_PER_COUNT, Experiment
from bayesmodal.ema import (
    METHODS,
    frf_from_experiment,
    identify,
    is_step_input,
    mode_indicator,
    pick_peaks,
    step_increments,
)
from bayesmodal.modal import complex_modes
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

THETA_3 = np.array([6.223, 1.565, 1.461, 1.146, 2.923, 1.806, 2.002, 0.00221, 0.00001])
RIG3 = LinearModel(Rig(), "free")
DT = 0.005


def _truth(model, theta):
    modes = complex_modes(model.state_space(theta)[0])
    return np.asarray(modes.omega_rad_s), np.asarray(modes.zeta)


def _record(v, model=RIG3, theta=THETA_3, name="record"):
    y = simulate_linear(model, theta, v, DT)
    y = np.round(y / ECP_M_PER_COUNT) * ECP_M_PER_COUNT  # whole encoder counts
    return Experiment(np.arange(v.size) * DT, v, y, name=name)


def _step(duration_s: float, at_s: float = 0.5, volts: float = 1.0):
    t = np.arange(int(round(duration_s / DT))) * DT
    return np.where(t >= at_s, volts, 0.0)


def _pulses(duration_s: float, width_s: float, period_s: float, volts: float = 1.0):
    t = np.arange(int(round(duration_s / DT))) * DT
    return np.where((t >= 0.5) & ((t - 0.5) % period_s < width_s - DT / 2), volts, 0.0)


def _check(est, omega, zeta, transient_s):
    """Every true mode identified within the resolution of a transient of this length."""
    dw = 2 * np.pi / transient_s
    found = np.flatnonzero(est.identified)
    assert found.size == omega.size, (est.omega_rad_s, est.identified, est.notes)
    k = found[np.argmin(np.abs(est.omega_rad_s[found][None, :] - omega[:, None]), axis=1)]
    assert np.all(np.abs(est.omega_rad_s[k] - omega) <= dw / 2), (est.omega_rad_s[k], omega)
    assert np.all(np.abs(est.zeta[k] - zeta) <= dw / (2 * omega)), (est.zeta[k], zeta)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("duration_s", [10.0, 4.0])
def test_single_step_and_short_record(method, duration_s):
    exp = _record(_step(duration_s), name=f"step {duration_s} s")
    assert is_step_input(exp.v_volt)
    omega, zeta = _truth(RIG3, THETA_3)
    res = identify(exp, method)
    # the default band is taken from the data and holds every mode
    assert res.band[0] < omega.min() and res.band[1] > omega.max()
    _check(res.estimate, omega, zeta, duration_s - 0.5)


def test_step_increments_give_the_exact_frf_of_the_record():
    # the FRF of the increments is the FRF of the system: compare with the model's
    # H(j w) = C (j w I - A)^-1 B where the step excites it, without count rounding
    v = _step(10.0)
    y = simulate_linear(RIG3, THETA_3, v, DT)
    frf = frf_from_experiment(Experiment(np.arange(v.size) * DT, v, y), method="step")
    A, B = RIG3.state_space(THETA_3)
    sel = (frf.omega_rad_s > 2) & (frf.omega_rad_s < 60)
    w = frf.omega_rad_s[sel]
    exact = np.array([np.linalg.solve(1j * wi * np.eye(6) - A, B)[:3] for wi in w])
    # what is left is the truncation of the slowest decay at the end of the record,
    # exp(-zeta_1 omega_1 * 9.5 s) of the response, and the ZOH alias terms
    omega, zeta = _truth(RIG3, THETA_3)
    tail = np.exp(-zeta[0] * omega[0] * 9.5)
    rel = np.linalg.norm(frf.H[sel] - exact) / np.linalg.norm(exact)
    assert rel < 10 * tail + 1e-3, (rel, tail)
    du, dy = step_increments(v, y)
    assert np.count_nonzero(du) == 1 and dy.shape == y.shape


@pytest.mark.parametrize("method", METHODS)
def test_exact_rectangular_pulse_train(method):
    # 0.2 s pulses every 5 s: the input spectrum is zero at multiples of 31.4 rad/s,
    # between modes 2 and 3; this record gave 'the FRF shows no resonance peak'
    exp = _record(_pulses(20.0, 0.2, 5.0), name="pulses")
    omega, zeta = _truth(RIG3, THETA_3)
    res = identify(exp, method)
    _check(res.estimate, omega, zeta, 5.0)


def test_notches_no_longer_set_the_mode_indicator():
    exp = _record(_pulses(20.0, 0.2, 5.0))
    frf = frf_from_experiment(exp)
    omega, _ = _truth(RIG3, THETA_3)
    notch = 2 * np.pi / 0.2
    step = frf.omega_rad_s[1] - frf.omega_rad_s[0]
    # negative control: with every frequency trusted the largest value of the mode
    # indicator sits on a zero of the pulse spectrum, far above every resonance
    raw = mode_indicator(frf, reliable=np.ones(frf.omega_rad_s.size, bool))
    w_max = frf.omega_rad_s[np.argmax(raw)]
    assert abs(w_max / notch - np.round(w_max / notch)) * notch <= step
    # ... and the resonances fall below the 0.1 % level under which peaks are ignored
    at_modes = np.interp(omega, frf.omega_rad_s, raw)
    assert np.all(at_modes < 1e-3 * raw.max()), at_modes / raw.max()
    # with the notches left out, the three strongest peaks are the modes
    pk = pick_peaks(frf, 3)
    np.testing.assert_allclose(pk.omega_rad_s, omega, atol=2 * np.pi / 5.0)


# ------------------------------------------------------------------ the command line
def _no_resonance_record(tmp_path):
    # a first-order lag (time constant 0.2 s) has no mode at all
    t = np.arange(2000) * DT
    v = np.where(t >= 0.5, 1.0, 0.0)
    y = np.where(t >= 0.5, 1e-2 * (1 - np.exp(-(t - 0.5) / 0.2)), 0.0)
    counts = np.round(y / ECP_M_PER_COUNT)
    p = tmp_path / "lag.txt"
    np.savetxt(p, np.column_stack([t, counts, counts, v]), fmt="%.10g")
    return p


@pytest.mark.parametrize("extra", [[], ["--band", "5", "60"]])
def test_no_mode_exits_non_zero_with_one_line(tmp_path, extra):
    p = _no_resonance_record(tmp_path)
    code, out, err = _cli(["ema", str(p), *extra])
    assert code == 2 and out == "" and len(err) == 1, (code, out, err)
    assert err[0].startswith("bayesmodal ema: error: ") and "no mode identified" in err[0]
    assert str(p) in err[0] and "--band" in err[0]


def test_two_cart_logger_record_with_one_command_line(tmp_path):
    # the record: microcontroller variable names, a struct of run parameters,
    # counts, converter units, time rounded to whole milliseconds, one step
    p = tmp_path / "rec.mat"
    t, v, y = logger_mat(p)
    cols = ",".join(f"{k}={val}" for k, val in MAP.items())
    code, out, err = _cli(["ema", str(p), "--columns", cols, "--input-scale", "5/4096",
                           "--json"])
    assert code == 0, err
    assert len(err) == 1 and "warning: " in err[0] and "rounded to 0.001 s" in err[0]
    res = json.loads(out)
    omega, zeta = _truth(TWO_CARTS, THETA_2)
    ident = np.array(res["identified"])
    assert ident.sum() == 2
    got = np.array(res["omega_rad_s"])[ident]
    transient = t[-1] - 0.1
    assert np.all(np.abs(np.sort(got) - omega) <= np.pi / transient), (got, omega)


def test_cli_reader_options_are_checked(tmp_path):
    p = tmp_path / "rec.mat"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        logger_mat(p)
    code, out, err = _cli(["ema", str(p), "--columns", "t=time,v=target_v", "--input-scale",
                           "5/4096"])
    assert code == 2 and len(err) == 1 and "role(s) ['x1'] missing" in err[0]
    code, out, err = _cli(["ema", str(p), "--columns", "t=time,v=target_v,x1=enc1",
                           "--input-scale", "five"])
    assert code == 2 and len(err) == 1 and "--input-scale: 'five' is not a number" in err[0]


def test_frequencies_without_input_energy_keep_the_grid_whole():
    # rectangular pulses of 1 s every 3 s seen as one transient: the input spectrum has
    # exact zeros on the FFT grid; the FRF keeps them (H = 0, input power 0) so that the
    # IRF of LSCE still has its uniform grid, and FRF.reliable leaves them out
    exp = _record(_pulses(20.0, 1.0, 3.0))
    frf = frf_from_experiment(exp, method="transient")
    steps = np.diff(frf.omega_rad_s)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-9)
    dead = frf.input_power == 0
    assert np.any(dead) and np.all(frf.H[dead] == 0)
    assert not np.any(frf.reliable_mask()[dead])
    res = identify(exp, "lsce", frf_method="transient")
    assert res.estimate.n_modes >= 1
