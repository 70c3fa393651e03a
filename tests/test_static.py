"""Steady-state analysis: closed form K^-1 b, known-truth recovery, the report's Table 2."""

import numpy as np
import pytest
from conftest import EPS, solve_tol

from bayesmodal import DataError, ModelError
from bayesmodal.data import Experiment
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.static import (
    NOMINAL_G_V,
    find_plateaus,
    gains_from_levels,
    static_levels,
    steady_state,
)

#: Report Table 2 (from data): k3/k1, k3/k2 and g_v.
TABLE2_RATIOS = np.array([0.4900, 0.5227])
TABLE2_G_V = 6.0497


def _square_wave(rig, g_v, *, seed, sigma_m=20e-6, cycles=6, amplitude=0.5, ca=10.0):
    """Simulated 5 s on / 5 s off steps with white measurement noise."""
    model = LinearModel(rig, "proportional")
    theta = np.array([g_v, 1.56, 1.46, 1.15, ca, 1e-4])
    dt = 0.005
    t = np.arange(int(10 / dt) * cycles) * dt
    v = np.where((t % 10.0) < 5.0, amplitude, 0.0)
    y = simulate_linear(model, theta, v, dt)
    rng = np.random.default_rng(seed)
    return Experiment(t, v, y + sigma_m * rng.standard_normal(y.shape), name="synthetic")


# ---------------------------------------------------------------- closed forms
def test_static_levels_solve_k_x_equals_b():
    rig = Rig((774.0, 770.0, 396.0))
    x = static_levels(rig, 6.0)
    K = rig.stiffness_matrix()
    # a backward-stable solve leaves a residual of at most n eps ||K|| ||x||
    np.testing.assert_allclose(K @ x, [6.0, 0.0, 0.0], rtol=0,
                               atol=3 * EPS * np.linalg.norm(K, 2) * np.linalg.norm(x))
    # series springs (report eq. 13): the solve's bound and eq. 13's few roundings
    k1, k2, k3 = rig.springs_n_m
    np.testing.assert_allclose(x, 6.0 * np.array([1 / k1 + 1 / k2 + 1 / k3, 1 / k2 + 1 / k3,
                                                   1 / k3]), rtol=solve_tol(K) + 8 * EPS)


@pytest.mark.parametrize("springs", [(774.0, 770.0, 396.0), (500.0, 900.0, 300.0),
                                     (100.0, 200.0, 300.0, 400.0)])
def test_gains_from_levels_inverts_static_levels(springs):
    rig = Rig(springs)
    x = static_levels(rig, 4.2)
    g, r = gains_from_levels(x, springs)
    k = np.array(springs)
    # the levels carry the solve's error; the gains are built from differences of
    # neighbouring levels, which amplify it by |x_i| / |x_i - x_i+1|
    amplify = np.max(np.abs(x[:-1]) / np.abs(np.diff(x)))
    rtol = (solve_tol(rig.stiffness_matrix()) + 8 * EPS) * (1 + amplify)
    assert g == pytest.approx(4.2, rel=rtol)
    np.testing.assert_allclose(r, k[-1] / k[:-1], rtol=rtol)


def test_gains_from_levels_checks_shape():
    with pytest.raises(DataError, match="need 3"):
        gains_from_levels(np.ones(2), (1.0, 2.0, 3.0))


# ---------------------------------------------------------------- known truth
def test_synthetic_steps_recover_gain_and_ratios_within_standard_errors():
    rig = Rig()
    e = _square_wave(rig, 6.0, seed=11)
    res = steady_state(e, rig=rig)
    assert res.plateaus.on.sum() == 6 and res.plateaus.off.sum() == 6
    k = np.array(rig.springs_n_m)
    truth = k[-1] / k[:-1]
    assert np.isfinite(res.g_v_se) and res.g_v_se > 0
    assert abs(res.g_v - 6.0) < 4 * res.g_v_se
    assert np.all(np.abs(res.ratios - truth) < 4 * res.ratios_se)
    # the standard error is that of averaging noise: sigma / sqrt(window) per plateau,
    # not orders of magnitude larger (which would make the check above vacuous)
    assert res.g_v_se < 2e-3 * 6.0


@pytest.mark.parametrize("share", [1.0, -1.0])
def test_gain_on_a_rig_other_than_the_chain(share):
    """Two carts with the frame spring at the driven cart (and the reversed drive): the
    gain from the levels and the known springs, x / v = g_v C K^-1 d, within 4 standard
    errors; no stiffness ratios (they are the chain's)."""
    import dataclasses

    from bayesmodal.model.rigs import load_rig
    from bayesmodal.model.system import Drive

    rig = load_rig("ecp210-2cart-frame-at-drive")
    rig = dataclasses.replace(rig, drive=(Drive("1", share),))
    model = LinearModel(rig, "proportional")
    dt = 0.005
    t = np.arange(int(10 / dt) * 6) * dt
    v = np.where((t % 10.0) < 5.0, 0.5, 0.0)
    y = simulate_linear(model, np.array([6.0, 1.5, 1.3, 10.0, 1e-4]), v, dt)
    e = Experiment(t, v, y + 20e-6 * np.random.default_rng(3).standard_normal(y.shape))
    res = steady_state(e, rig=rig)
    assert res.ratio_names == () and res.ratios.size == 0
    assert np.isfinite(res.g_v_se) and 0 < res.g_v_se < 2e-3 * 6.0
    assert abs(res.g_v - 6.0) < 4 * res.g_v_se


def test_static_gain_needs_known_springs():
    from bayesmodal.model.rigs import rig_from_dict

    rig = rig_from_dict({"carts": [{"name": "1"}], "drive": {"carts": ["1"]},
                         "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0,
                                      "known": False}]})
    e = Experiment(np.arange(10) * 0.01, np.ones(10), np.ones((10, 1)))
    with pytest.raises(ModelError, match="k1 are unknown"):
        steady_state(e, rig=rig)


def test_a_logger_s_jittered_stamps_give_the_same_plateaus(tmp_path):
    # the plateaus are means over samples, whatever their instants: a record kept on its
    # jittered stamps (steps 2 to 8 ms around 5 ms) is analysed as it comes
    import json

    from conftest import run_cli

    from bayesmodal.data import save_csv

    rig = Rig()
    rng = np.random.default_rng(3)
    n = 8000
    t = np.arange(n) * 0.005 + 0.005 * rng.uniform(-0.3, 0.3, n)
    v = np.where((t % 10.0) < 5.0, 0.5, 0.0)
    y = simulate_linear(LinearModel(rig, "proportional"),
                        np.array([6.0, 1.56, 1.46, 1.15, 10.0, 1e-4]), v, np.diff(t))
    y = y + 20e-6 * rng.standard_normal(y.shape)
    save_csv(Experiment(t, v, y, recorded_stamps=True), tmp_path / "logger.csv")
    code, out, err = run_cli(["static", str(tmp_path / "logger.csv"), "--json"])
    assert code == 0 and len(err) == 1 and "kept as recorded" in err[0], err
    res = json.loads(out)["zero"]
    k = np.array(rig.springs_n_m)
    assert abs(res["g_v"] - 6.0) < 4 * res["g_v_se"]
    ratios = np.array(list(res["ratios"].values()))
    ses = np.array(list(res["ratios_se"].values()))
    assert np.all(np.abs(ratios - k[-1] / k[:-1]) < 4 * ses)
    # durations in seconds become sample counts by the mean step (no uniform grid needed)
    e = Experiment(t, v, y, recorded_stamps=True)
    assert steady_state(e, rig=rig, smooth_s=0.1, min_duration_s=1.0).plateaus.on.sum() == 4


def test_synthetic_steps_previous_reference_agrees():
    rig = Rig()
    e = _square_wave(rig, 6.0, seed=12)
    res = steady_state(e, rig=rig, reference="previous")
    assert res.n_steps == 6
    assert abs(res.g_v - 6.0) < 4 * res.g_v_se
    k = np.array(rig.springs_n_m)
    assert np.all(np.abs(res.ratios - k[-1] / k[:-1]) < 4 * res.ratios_se)


def test_negative_control_other_springs_give_other_ratios():
    # data from a rig with different first two springs: the ratios must move away from the
    # nominal ones (by many standard errors) and onto the true ones
    true_rig = Rig((900.0, 650.0, 396.0))
    e = _square_wave(true_rig, 6.0, seed=13)
    res = steady_state(e, rig=Rig())  # analysed with the nominal rig
    k = np.array(true_rig.springs_n_m)
    truth = k[-1] / k[:-1]
    assert np.all(np.abs(res.ratios - truth) < 4 * res.ratios_se)
    assert np.all(np.abs(res.ratios - res.nominal_ratios) > 20 * res.ratios_se)
    # g_v only needs k3, which is right
    assert abs(res.g_v - 6.0) < 4 * res.g_v_se


def test_wrong_k3_scales_the_gain():
    e = _square_wave(Rig(), 6.0, seed=14)
    res = steady_state(e, rig=Rig((774.0, 770.0, 2 * 396.0)))
    assert res.g_v == pytest.approx(12.0, rel=1e-3)


def test_amplitude_does_not_matter():
    rig = Rig()
    e = _square_wave(rig, 5.0, seed=15, amplitude=-1.25)
    res = steady_state(e, rig=rig)
    assert abs(res.g_v - 5.0) < 4 * res.g_v_se


def test_unsettled_steps_are_reported_not_used():
    # an almost undamped rig does not settle in 5 s: no plateau may be claimed
    e = _square_wave(Rig(), 6.0, seed=16, ca=0.05, sigma_m=1e-6)
    p = find_plateaus(e)
    assert p.n_plateaus == 0 and len(p.unsettled) == 12
    with pytest.raises(DataError, match="no settled on-plateau"):
        steady_state(e, plateaus=p)


def test_validation():
    t = np.arange(100) * 0.01
    zeros = Experiment(t, np.zeros(100), np.zeros((100, 3)))
    with pytest.raises(DataError, match="all zeros"):
        find_plateaus(zeros)
    e = _square_wave(Rig(), 6.0, seed=1, cycles=1)
    with pytest.raises(ModelError, match="reference"):
        steady_state(e, reference="mean")
    with pytest.raises(DataError, match="outputs"):
        steady_state(e, rig=Rig((1.0, 2.0)))
    with pytest.raises(DataError, match="n_sigma"):
        find_plateaus(e, n_sigma=-1)


# ---------------------------------------------------------------- measured data
def test_plateau_picker_on_data_steps(steps):
    p = find_plateaus(steps)
    assert p.on.sum() == 4
    assert p.off.sum() == 4  # one rest after each of the four steps
    np.testing.assert_array_equal(p.v_volt[p.on], 0.5)
    # windows lie inside their constant-input segments, after the transient
    assert np.all(p.start >= p.segment_start) and np.all(p.stop <= p.segment_stop)
    assert np.all(p.stop - p.start >= 10)
    for a, b in zip(p.start, p.stop, strict=True):
        assert np.ptp(steps.v_volt[a:b]) == 0
        # settled: the outputs move by less than 0.1 % of their range inside a window
        assert np.all(np.ptp(steps.y_m[a:b], axis=0) < 1e-3 * np.ptp(steps.y_m, axis=0) + 1e-9)


def test_table2_from_data_steps(steps):
    res = steady_state(steps)
    assert res.n_steps == 4
    assert res.g_v == pytest.approx(TABLE2_G_V, rel=0.01)
    np.testing.assert_allclose(res.ratios, TABLE2_RATIOS, rtol=0.02)
    assert res.ratio_names == ("k3/k1", "k3/k2")
    # errata 6: relative error, e.g. g_v (6.05 - 5.25) / 5.25 = +15.2 %
    assert res.g_v_error_percent == pytest.approx(100 * (res.g_v - NOMINAL_G_V) / NOMINAL_G_V)
    assert res.g_v_error_percent == pytest.approx(15.2, abs=0.5)
    np.testing.assert_allclose(res.nominal_ratios, [396 / 774, 396 / 770])
    np.testing.assert_allclose(
        res.ratios_error_percent, 100 * (res.ratios - res.nominal_ratios) / res.nominal_ratios
    )


def test_previous_reference_on_data_steps(steps):
    res = steady_state(steps, reference="previous")
    zero = steady_state(steps)
    assert res.n_steps == 4
    # the first step starts from the recorded rest level (zero): both conventions agree
    assert res.g_v_each[0] == pytest.approx(zero.g_v_each[0])
    # friction offsets of a few tenths of a mm move the later steps by about 1-3 %
    assert res.g_v == pytest.approx(zero.g_v, rel=0.02)
    assert not np.allclose(res.g_v_each[1:], zero.g_v_each[1:], rtol=1e-3)


def test_plot_steady_state(steps):
    import matplotlib.pyplot as plt

    from bayesmodal.plots.static import plot_steady_state

    ax = plot_steady_state(steady_state(steps))
    assert ax.get_xlabel() == "time [s]" and "[mm]" in ax.get_ylabel()
    plt.close(ax.figure)


def test_plot_fit_labels_and_shape_check():
    import matplotlib.pyplot as plt

    from bayesmodal.plots.fit import plot_fit

    e = _square_wave(Rig(), 6.0, seed=2, cycles=1)
    axes = plot_fit(e, e.y_m * 0.98)
    assert len(axes) == 3 and axes[-1].get_xlabel() == "time [s]"
    assert "fit" in axes[0].get_title(loc="left")
    with pytest.raises(DataError, match="shape"):
        plot_fit(e, e.y_m[:, :2])
    plt.close("all")
