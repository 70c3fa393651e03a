"""Residual diagnostics: each reacts to its effect and not to clean linear data.

Synthetic experiments are generated with the independent reference simulators of
tests/reference_sim.py (not the package's extension kernels), with sensor noise and
encoder quantisation, then fitted with the linear model like measured data.  Fixed seeds.
"""

import matplotlib
import numpy as np
import pytest
from conftest import TABLE3
from reference_sim import REFERENCES, simulate_linear_ref

from bayesmodal import ConfigError, DataError
from bayesmodal.data import ECP_M_PER_COUNT, Experiment
from bayesmodal.discrepancy.checks import (
    RESIDUAL_DIAGNOSTICS,
    Diagnostic,
    amplitude_dependence,
    cross_experiment_consistency,
    decay_envelope,
    friction_signature,
    gain_error,
    input_residual_correlation,
    linear_residuals,
    ljung_box,
    residual_spectrum,
    stick_detection,
    whiteness,
)
from bayesmodal.fit import fit_lsq
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.plots.diagnostics import plot_diagnostic, plot_residuals, plot_stick

matplotlib.use("Agg")

RIG = Rig()
MODEL = LinearModel(RIG, "free")
DT = 0.005
Q = ECP_M_PER_COUNT
SPRINGS = RIG.springs_n_m


def _pulses(N, period=1000):
    u = np.zeros(N)
    for k, s in enumerate(range(1, N, period)):
        u[s : s + 9] = 3.0 if k % 2 == 0 else -3.0
    return u


def _steps(N, period=1000):
    u = np.zeros(N)
    levels = [0.3, 0.0, 0.5, 0.0]
    for k, s in enumerate(range(1, N, period)):
        u[s : s + period] = levels[k % 4]
    return u


def _measure(y, u, seed, *, noise="ar1", sigma=2 * Q, name="synthetic"):
    """Add white or AR(1) (phi 0.8) noise and quantise to encoder counts."""
    rng = np.random.default_rng(seed)
    e = sigma * rng.standard_normal(y.shape)
    if noise == "ar1":
        for k in range(1, e.shape[0]):
            e[k] += 0.8 * e[k - 1]
    y = np.round((y + e) / Q) * Q
    return Experiment(np.arange(u.size) * DT, u, y, name=name)


def _residuals(experiment):
    # start the fit near the truth to save time: the diagnostics, not the fit, are tested
    fit = fit_lsq(experiment, MODEL, theta0=np.maximum(TABLE3, 1e-3))
    return linear_residuals(experiment, MODEL, fit.theta)


@pytest.fixture(scope="module")
def clean():
    u = _pulses(4000)
    y = simulate_linear_ref(SPRINGS, TABLE3, u, DT)
    return {noise: _residuals(_measure(y, u, seed=11, noise=noise))
            for noise in ("white", "ar1")}


FRICTION = np.r_[TABLE3[:4], 0.8, 0.5, 0.6, TABLE3[7:], 0.2, 0.15, 0.15, 0.3, 0.25, 0.2]


@pytest.fixture(scope="module")
def friction():
    u = _pulses(4000)
    y = REFERENCES["coulomb_friction"](SPRINGS, FRICTION, u, DT)
    return _residuals(_measure(y, u, seed=12))


# ------------------------------------------------------------------ negative controls
@pytest.mark.parametrize("noise", ["white", "ar1"])
@pytest.mark.parametrize("name", sorted(RESIDUAL_DIAGNOSTICS))
def test_clean_linear_data_trigger_nothing(clean, name, noise):
    d = RESIDUAL_DIAGNOSTICS[name](clean[noise])
    assert isinstance(d, Diagnostic) and d.name
    assert not d.detected, d.summary
    assert d.suggests == ()
    if d.p_value is not None:
        assert 0.0 <= d.p_value <= 1.0


def test_ljung_box_calibration():
    rng = np.random.default_rng(0)
    # white noise: p-values of 200 independent series are uniform; check the rejection
    # rate at 5 % within 3 binomial standard errors
    p = np.array([ljung_box(rng.standard_normal(500), 10)[1] for _ in range(200)])
    assert abs(np.mean(p < 0.05) - 0.05) < 3 * np.sqrt(0.05 * 0.95 / 200)
    x = np.zeros(500)
    e = rng.standard_normal(500)
    for k in range(1, 500):
        x[k] = 0.5 * x[k - 1] + e[k]
    Q, pv, r = ljung_box(x, 10)
    assert pv < 1e-10 and r[0] == pytest.approx(0.5, abs=0.1)


# ------------------------------------------------------------------ effects
def test_friction_is_found_on_the_right_scale(friction):
    d = friction_signature(friction)
    assert d.detected and d.suggests == ("coulomb_friction",)
    fc = d.detail["fc_n"]
    truth = FRICTION[9:12]
    # stick holds less than Fc on average, so the estimate is biased low, not high
    assert np.all(fc > 0.4 * truth) and np.all(fc < 1.2 * truth), fc
    assert np.all(d.detail["fc_stderr_n"] < 0.1 * truth)
    env = decay_envelope(friction)
    assert env.detected and env.statistic > env.threshold
    st = stick_detection(friction)
    assert st.detected and st.location is not None
    assert whiteness(friction).detected
    # friction is not a delay, a cubic spring nor an extra mode (though the misfit while
    # the motor pushes is locked to the input)
    assert input_residual_correlation(friction).suggests == ()
    amp = amplitude_dependence(friction)  # damping grows towards small amplitude
    assert amp.detected and amp.suggests == ("coulomb_friction",)
    assert not residual_spectrum(friction).detected


def test_delay_and_motor_lag_correlate_residual_with_input():
    u = _pulses(4000)
    for name, value in (("input_delay", 0.008), ("motor_lag", 0.005)):
        y = REFERENCES[name](SPRINGS, np.r_[TABLE3, value], u, DT)
        res = _residuals(_measure(y, u, seed=13, name=name))
        d = input_residual_correlation(res)
        assert d.detected and "input_delay" in d.suggests
        # the measurement lags the prediction of the (delay-free) linear model
        assert np.all(d.detail["prediction_lag_s"] > 0.0)
        assert 0.0 <= d.detail["peak_lag_s"][0] <= 0.03
        assert not friction_signature(res).detected


def test_hardening_springs_raise_frequency_with_amplitude():
    u = _pulses(4000)
    y = REFERENCES["cubic_stiffness"](SPRINGS, np.r_[TABLE3, 2e5, 2e5, 2e5], u, DT)
    res = _residuals(_measure(y, u, seed=14))
    d = amplitude_dependence(res)
    assert d.detected and d.suggests == ("cubic_stiffness",)
    best = next(m for m in d.detail["modes"] if f"mode {m['mode']}" == d.location)
    assert best["slope"] > 0 and best["relative_change"] > 0.005
    assert not friction_signature(res).detected
    assert not stick_detection(res).detected


def test_unmodelled_mode_shows_as_a_spectral_peak():
    u = _pulses(4000)
    y = simulate_linear_ref(SPRINGS, TABLE3, u, DT)
    # a lightly damped 9.5 Hz resonance driven by the motor, seen by every encoder
    w, z = 2 * np.pi * 9.5, 0.01
    extra = simulate_linear_ref((w**2,), np.array([w**2 * 4e-4, 1.0, 2 * z * w]), u, DT)
    y = y + extra[:, [0]] * np.array([1.0, 0.5, 0.3])
    res = _residuals(_measure(y, u, seed=15))
    d = residual_spectrum(res)
    assert d.detected and d.suggests == ("unmodelled_mode",)
    peak = max((p for p in d.detail["peaks"] if p["near_mode_hz"] is None),
               key=lambda p: p["ratio"])
    assert peak["f_hz"] == pytest.approx(9.5, abs=0.5)


def test_sensor_gain_error_on_one_output():
    u = _steps(4000)
    y = simulate_linear_ref(SPRINGS, TABLE3, u, DT) * np.array([1.0, 1.04, 1.0])
    res = _residuals(_measure(y, u, seed=16))
    d = gain_error(res)
    assert d.detected and d.location == "output 2" and d.suggests == ("sensor_gain",)
    g, se = d.detail["gain"], d.detail["stderr"]
    # the fit of g_v rescales all outputs by a common factor; the ratio of output 2's gain
    # to the others' stays 1.04
    ratio = (1 + g[1]) / (1 + np.mean(g[[0, 2]]))
    assert ratio == pytest.approx(1.04, abs=5 * np.sqrt(se[1] ** 2 + np.mean(se[[0, 2]] ** 2)))


def test_cross_experiment_consistency():
    u1, u2 = _pulses(3000), _steps(4000)
    lin = [_measure(simulate_linear_ref(SPRINGS, TABLE3, u, DT), u, seed=17 + i, name=nm)
           for i, (u, nm) in enumerate(((u1, "pulses"), (u2, "steps")))]
    def fit(es):  # started near the truth to save time
        return fit_lsq(es, MODEL, theta0=np.maximum(TABLE3, 1e-3)).theta

    d = cross_experiment_consistency(lin, model=MODEL, fit=fit)
    assert not d.detected and d.statistic < 1.0
    fr = [_measure(REFERENCES["coulomb_friction"](SPRINGS, FRICTION, u, DT), u, seed=19 + i,
                   name=nm) for i, (u, nm) in enumerate(((u1, "pulses"), (u2, "steps")))]
    d = cross_experiment_consistency(fr, model=MODEL, fit=fit)
    assert d.detected and d.statistic > d.threshold
    assert d.detail["fit_matrix"].shape == (2, 2)
    with pytest.raises(DataError, match="two experiments"):
        cross_experiment_consistency(lin[:1])


# ------------------------------------------------------------------ API and plots
def test_result_is_frozen_and_validated(clean):
    d = whiteness(clean["white"])
    with pytest.raises(AttributeError):
        d.detected = True
    with pytest.raises(TypeError):
        d.detail["Q"] = 0
    with pytest.raises(ConfigError):
        friction_signature(clean["white"], velocity="guessed")
    short = Experiment(np.arange(20) * DT, np.ones(20), np.zeros((20, 3)))
    with pytest.raises(DataError, match="too few"):
        linear_residuals(short, MODEL, TABLE3)


def test_plots_label_their_axes(friction):
    import matplotlib.pyplot as plt

    for fn in RESIDUAL_DIAGNOSTICS.values():
        ax = plot_diagnostic(fn(friction))
        assert ax.get_xlabel() and ax.get_ylabel()
        plt.close(ax.figure)
    ax = plot_stick(stick_detection(friction), friction)
    assert "time" in ax.get_xlabel()
    ax = plot_residuals(friction)
    assert "counts" in ax.get_ylabel()
    plt.close("all")


def test_measured_impulses_show_friction_and_stick(impulses):
    res = _residuals(impulses)
    d = friction_signature(res)
    assert d.detected and np.all(d.detail["fc_n"] > 0.05)
    assert stick_detection(res).detected
    assert decay_envelope(res).detected


def test_detected_means_significant(friction):
    # "effect found" only with a p-value below the diagnostic's own level: in particular
    # amplitude_dependence reports the p of the damping test when dry friction decided
    for name, fn in RESIDUAL_DIAGNOSTICS.items():
        d = fn(friction)
        if d.detected and d.p_value is not None:
            assert d.p_value < d.detail.get("alpha", 0.01), (name, d.summary)
    amp = amplitude_dependence(friction)
    mode = next(m for m in amp.detail["modes"] if f"mode {m['mode']}" == amp.location)
    # the damping change reads as a factor of the fitted end values, the same mode is named
    ratio = mode["zeta_small_amplitude"] / mode["zeta_large_amplitude"]
    assert ratio > 1.5
    assert f"mode {mode['mode']} damping grows towards small amplitude x{ratio:.2g}" \
        in amp.summary


def test_lag_phrase_names_the_late_signal():
    from bayesmodal.discrepancy.checks import input_correlation as ic

    assert ic.lag_phrase(-0.0049) == "prediction lags measurement by 4.9 ms"
    assert ic.lag_phrase(0.008) == "measurement lags prediction by 8.0 ms"
    assert ic.lag_phrase(0.0005, 0.00125).startswith("measurement and prediction aligned")


def test_amplitude_dependence_reports_the_deciding_test_on_measured_data(impulses):
    # on the rig, dry friction makes mode 2's damping grow at small amplitude while its
    # frequency trend is not significant: the diagnostic fires for friction, so its p-value
    # must be the damping test's, and it must name the mode whose damping it reports
    # (parameters: a least-squares fit of the impulse record, free damping)
    theta = np.array([6.2226, 1.5648, 1.4613, 1.1457, 2.921, 1.807, 2.006, 0.0, 0.0])
    d = amplitude_dependence(linear_residuals(impulses, MODEL, theta))
    assert d.detected and d.suggests == ("coulomb_friction",)
    assert d.p_value < d.detail["alpha"]
    named = int(d.location.split()[1])
    mode = d.detail["modes"][named - 1]
    assert mode["damping_p"] * len(d.detail["modes"]) == pytest.approx(d.p_value)
    assert f"mode {named} damping grows" in d.summary
