"""Effects that combine: naming, the physical order of the input stages, per-lane inputs
through the compiled plant kernels, independent references, and the path from a TOML
configuration to the likelihood."""

import numpy as np
import pytest
from conftest import TABLE3
from reference_effects import (
    LUGRE_RTOL,
    input_chain_ref,
    simulate_linear_chain_ref,
    simulate_lugre_ref,
)
from reference_sim import RTOL, simulate_coulomb_ref

from bayesmodal import ConfigError, ModelError
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, save_csv
from bayesmodal.inference import Likelihood
from bayesmodal.model.effects import EXTENSIONS, Combined, get_extension
from bayesmodal.model.effects.lugre import LuGreFriction
from bayesmodal.model.system import LinearModel, Rig

RIG = Rig()
DT = 0.005
COUNT = ECP_M_PER_COUNT
LIN_NAMES = LinearModel(RIG, "free").names
LUGRE = [0.1, 0.15, 0.08, 0.15, 0.2, 0.12, 2e4, 100.0, 0.005]


def _input(N=300):
    u = np.zeros(N)
    u[1:10] = 3.0
    u[100:180] = 0.4
    u[220:228] = -2.0
    return u


def test_names_are_linear_then_each_effect_in_order():
    a = get_extension("coulomb_friction+input_offset")
    b = get_extension(["coulomb_friction", "input_offset"])
    assert isinstance(a, Combined) and a == b
    assert a.name == "coulomb_friction+input_offset"
    assert a.names(RIG) == (LIN_NAMES + EXTENSIONS["coulomb_friction"].extension_names(RIG)
                            + ("v_offset",))
    rev = get_extension("input_offset+coulomb_friction")
    assert rev.names(RIG)[9] == "v_offset"
    assert get_extension(a.name) == a  # the name round-trips (stored in run files)
    assert get_extension(["motor_lag"]) is EXTENSIONS["motor_lag"]
    np.testing.assert_array_equal(a.null_values(RIG), np.zeros(7))


@pytest.mark.parametrize("names,match", [
    (["coulomb_friction", "backlash"], "two plant-side effects"),
    (["input_offset", "input_offset"], "repeated"),
    (["input_offset", "friction"], "unknown model extension"),
])
def test_unsupported_combinations_are_refused(names, match):
    with pytest.raises(ModelError, match=match):
        get_extension(names)


def test_validity_is_every_effects_rule():
    ext = get_extension("coulomb_friction+input_saturation")
    good = np.r_[TABLE3, 0.1, 0.1, 0.1, 0.2, 0.2, 0.2, 2.0]
    assert ext.valid(RIG, good)
    bad_fs = good.copy()
    bad_fs[12] = 0.05
    bad_sat = good.copy()
    bad_sat[-1] = -1.0
    assert not ext.valid(RIG, bad_fs) and not ext.valid(RIG, bad_sat)
    with pytest.raises(ModelError, match="input_saturation"):
        ext.simulate(RIG, bad_sat, np.ones(10), DT)


def test_linear_input_chain_matches_reference():
    """Offset, dead band, saturation, lag and delay on the linear plant: exact ZOH against
    the ODE reference (tolerance from its rtol), whatever the order the effects are named."""
    names = ["input_delay", "input_saturation", "motor_lag", "amplitude_gain",
             "drive_deadband", "input_offset"]
    ext = get_extension(names)
    own = {"input_offset": 0.2, "drive_deadband": 0.3, "input_saturation": 2.0,
           "amplitude_gain": 0.03, "motor_lag": 0.01, "input_delay": 0.0123}
    theta = np.r_[TABLE3, [own[n] for n in names]]
    u = _input()
    y = ext.simulate(RIG, theta, u, DT)
    y_ref = simulate_linear_chain_ref(RIG.springs_n_m, TABLE3, u, DT, v_offset=0.2,
                                      v_dead=0.3, v_sat=2.0, kappa=0.03, tau=0.01,
                                      delay=0.0123)
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e3 * RTOL * np.max(np.abs(y_ref)))
    # a negative control: the stages in another order (saturation before the offset)
    # give a different model, which the reference tells apart
    wrong = simulate_linear_chain_ref(RIG.springs_n_m, TABLE3, np.clip(u, -2.0, 2.0), DT,
                                      v_offset=0.2, v_dead=0.3, kappa=0.03, tau=0.01,
                                      delay=0.0123)
    assert np.max(np.abs(wrong - y_ref)) > 20 * COUNT
    # the same physics with the effects named in another order
    perm = get_extension(sorted(names))
    theta_p = np.r_[TABLE3, [own[n] for n in sorted(names)]]
    np.testing.assert_allclose(perm.simulate(RIG, theta_p, u, DT), y, rtol=0, atol=1e-15)


@pytest.mark.parametrize("plant,own", [
    ("cubic_stiffness", [1e5, -5e4, 1e5]),
    ("backlash", [3e-4, 0.2]),
    ("lugre_friction", LUGRE),
    pytest.param("coulomb_friction", [0.1, 0.15, 0.08, 0.15, 0.2, 0.12],
                 marks=pytest.mark.slow),  # compiles the largest kernel (minutes when busy)
])
def test_per_lane_inputs_through_plant_kernels_equal_single_runs(plant, own):
    """Each lane of a batch with its own offset and dead band gives exactly the plant
    effect's own simulation under that lane's transformed voltage (shared-input kernel):
    the per-lane kernels change where the input is read, nothing else."""
    ext = get_extension([plant, "input_offset", "drive_deadband"])
    u = _input(400)
    rng = np.random.default_rng(5)
    nb = 20  # more than the friction kernel's packed group of 16
    offsets = rng.uniform(-0.3, 0.3, nb)
    dead = rng.uniform(0.0, 0.4, nb)
    lin = TABLE3 * (1 + 0.03 * rng.standard_normal((nb, 9)))
    lin[:, 7:] = np.abs(lin[:, 7:])
    theta = np.c_[lin, np.tile(own, (nb, 1)), offsets, dead]
    y = ext.simulate(RIG, theta, u, DT)
    single = EXTENSIONS[plant]
    for j in range(nb):
        v = input_chain_ref(u, v_offset=offsets[j], v_dead=dead[j])
        y1 = single.simulate(RIG, np.r_[lin[j], own], v, DT)
        np.testing.assert_array_equal(y[j], y1)


@pytest.mark.parametrize("plant,own", [
    ("lugre_friction", LUGRE),
    # compiles the friction kernel with its input stages (minutes when busy)
    pytest.param("coulomb_friction", [0.1, 0.15, 0.08, 0.15, 0.2, 0.12],
                 marks=pytest.mark.slow),
])
def test_friction_kernel_input_stages_equal_the_numpy_transforms(plant, own):
    """The friction kernels apply offset, saturation and amplitude gain to the shared
    input themselves (no per-lane input block): each lane gives bit for bit the friction
    simulation under that lane's voltage transformed by the effects' own numpy code."""
    names = ["input_offset", "input_saturation", "amplitude_gain"]
    ext = get_extension([plant, *names])
    assert ext.plant.fuses_input_stages
    u = _input(400)
    rng = np.random.default_rng(6)
    nb = 20  # more than the friction kernel's packed group of 16
    lin = TABLE3 * (1 + 0.03 * rng.standard_normal((nb, 9)))
    lin[:, 7:] = np.abs(lin[:, 7:])
    stage = np.c_[rng.uniform(-0.3, 0.3, nb), rng.uniform(0.3, 2.5, nb),
                  rng.uniform(-0.05, 0.05, nb)]
    y = ext.simulate(RIG, np.c_[lin, np.tile(own, (nb, 1)), stage], u, DT)
    for j in range(nb):
        v = u
        for name, value in zip(names, stage[j], strict=True):  # offset, clip, gain
            v = EXTENSIONS[name].transform_input(v, np.array([[value]]))[0]
        y1 = EXTENSIONS[plant].simulate(RIG, np.r_[lin[j], own], v, DT)
        np.testing.assert_array_equal(y[j], y1)
    clipped = np.clip(u + stage[:, :1], -stage[:, 1:2], stage[:, 1:2])
    assert np.any(clipped != u + stage[:, :1])  # the clip acts on some lanes


def test_lugre_with_dead_band_and_offset_matches_reference():
    ext = get_extension("lugre_friction+drive_deadband+input_offset")
    u = _input()
    theta = np.r_[TABLE3, LUGRE, 0.2, -0.1]
    y_ref = simulate_lugre_ref(RIG.springs_n_m, np.r_[TABLE3, LUGRE], u, DT, v_offset=-0.1,
                               v_dead=0.2)
    y = ext.simulate(RIG, theta, u, DT)
    # as LuGre alone (test_effects_new): within 1.5 times the step-doubling estimate of
    # the sub-step error (second order), plus the stiff reference's own tolerance
    k = EXTENSIONS["lugre_friction"].n_sub
    fine = Combined((LuGreFriction(n_sub=2 * k), EXTENSIONS["drive_deadband"],
                     EXTENSIONS["input_offset"]))
    estimate = 4.0 / 3.0 * np.max(np.abs(y - fine.simulate(RIG, theta, u, DT)))
    err = np.max(np.abs(y - y_ref))
    assert err <= 1.5 * estimate + 1e3 * LUGRE_RTOL * np.max(np.abs(y_ref)), (
        err / COUNT, estimate / COUNT)


@pytest.mark.slow
def test_coulomb_with_offset_matches_event_driven_reference():
    ext = get_extension("coulomb_friction+input_offset")
    own = [0.1, 0.15, 0.08, 0.15, 0.2, 0.12]
    u = _input()
    y = ext.simulate(RIG, np.r_[TABLE3, own, 0.15], u, DT)
    y_ref = simulate_coulomb_ref(RIG.springs_n_m, np.r_[TABLE3, own], u + 0.15, DT)
    assert np.max(np.abs(y - y_ref)) < 0.75 * COUNT  # the friction kernel's own accuracy


def test_fit_hooks_and_location_split_by_effect():
    ext = get_extension("coulomb_friction+input_offset")
    own = np.array([0.1, 0.15, 0.08, 0.15, 0.3, 0.12, -0.05])
    w = ext.to_opt(RIG, own)
    np.testing.assert_allclose(w[3:6], own[3:6] - own[:3])  # Coulomb's (Fc, Fs - Fc)
    np.testing.assert_allclose(ext.from_opt(RIG, w), own)
    lo, hi = ext.opt_bounds(RIG)
    assert lo.shape == hi.shape == (7,) and lo[-1] == -np.inf
    loc = ext.location_of(RIG, np.r_[TABLE3, own])
    assert (loc.kind, loc.index) == ("cart", 1)
    grid = ext.start_grid(RIG)
    assert grid.shape[1] == 7 and np.all(ext.valid(RIG, np.c_[np.tile(TABLE3, (len(grid), 1)),
                                                              grid]))


def _config(tmp_path, extensions: str) -> str:
    u = _input(400)
    y = get_extension("input_offset").simulate(RIG, np.r_[TABLE3, 0.1], u, DT)
    save_csv(Experiment(np.arange(u.size) * DT, u, y, name="rec"), tmp_path / "rec.csv")
    path = tmp_path / "run.toml"
    path.write_text(f'[data]\nfiles = ["rec.csv"]\n[model]\nextensions = {extensions}\n'
                    "[sampler]\nwalkers = 60\nsteps = 20\nburn = 5\n")
    return path


def test_config_with_two_effects_builds_a_combined_likelihood(tmp_path):
    from bayesmodal.runs import prepare_run
    from bayesmodal.runs.config import load_config

    prep = prepare_run(load_config(_config(tmp_path, '["coulomb_friction", "input_offset"]')))
    assert prep.extension == "coulomb_friction+input_offset"
    assert "v_offset" in prep.priors.names and "Fs3" in prep.priors.names
    lik = Likelihood(prep.model, prep.experiments, extension=prep.extension)
    assert isinstance(lik.extension, Combined)
    assert lik.mech_names[-1] == "v_offset"
    with pytest.raises(ConfigError, match=r"\[model.extensions\]"):
        prepare_run(load_config(_config(tmp_path, '["coulomb_friction", "backlash"]')))


@pytest.mark.slow  # about 40 s: the linear fit, a start grid and the least-squares fit
def test_least_squares_fit_of_a_combination_recovers_truth_within_its_standard_error():
    """fit_extension_lsq takes a combination.  Synthetic record of offset + dead band with
    Gaussian noise; the estimate lies within 4 Gauss-Newton standard errors (from the
    finite-difference Jacobian at the estimate) of the truth, and the fit's cost is not
    above the cost at the truth (the optimum, not merely a point near it)."""
    from bayesmodal.fit import fit_extension_lsq
    from bayesmodal.fit.effects import extension_residuals

    ext = get_extension("input_offset+drive_deadband")
    N = 2400
    u = np.zeros(N)
    for k, level in zip(range(1, N, 400), (3.0, 0.6, -2.0, -0.6, 1.5, 0.8), strict=False):
        u[k : k + (10 if abs(level) > 1 else 200)] = level
    truth = np.r_[TABLE3, 0.1, 0.25]
    sigma = 2 * COUNT
    rng = np.random.default_rng(11)
    y = ext.simulate(RIG, truth, u, DT)
    rec = Experiment(np.arange(N) * DT, u, y + sigma * rng.standard_normal(y.shape))
    fit = fit_extension_lsq(rec, ext, RIG)
    r_truth = extension_residuals(ext, RIG, truth[None], [rec])[0]
    assert fit.cost <= 0.5 * np.sum(r_truth**2) * (1 + 1e-9)
    # Gauss-Newton covariance sigma^2 (J^T J)^-1 with central differences at the estimate
    steps = np.maximum(np.abs(fit.theta) * 1e-5, 1e-9)
    plus = fit.theta + np.diag(steps)
    minus = fit.theta - np.diag(steps)
    J = (extension_residuals(ext, RIG, plus, [rec])
         - extension_residuals(ext, RIG, minus, [rec])) / (2 * steps[:, None])
    cov = sigma**2 * np.linalg.inv(J @ J.T)
    se = np.sqrt(np.diag(cov))[-2:]
    assert np.all(np.abs(fit.theta[-2:] - truth[-2:]) < 4 * se), (fit.theta[-2:], se)
    assert np.all(se < 0.01)  # the record does pin both down (to 10 mV)


def test_kernel_input_stages_are_checked_before_any_code_is_generated():
    from bayesmodal.model.kernels.coulomb import coulomb_kernel
    from bayesmodal.model.kernels.lugre import lugre_kernel

    for kernel in (coulomb_kernel, lugre_kernel):
        with pytest.raises(ValueError, match="unknown input stage 'magic'"):
            kernel(3, 16, stages=("offset", "magic"))
        with pytest.raises(ValueError, match="shared input"):
            kernel(3, 16, per_lane=True, stages=("offset",))
