"""Posterior of extended models: likelihood, priors, sampling, InferenceData, ELPD change.

Data with a hidden effect come from the independent reference simulators in
``tests/reference_sim.py`` (via ``hidden_effects.make``), with sensor noise and encoder
quantisation, so the package's kernels never generate the data they are tested on.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, zoh_rtol
from hidden_effects import make

from bayesmodal._errors import ConfigError, ModelError
from bayesmodal.inference import (
    Likelihood,
    default_priors,
    elpd_change,
    likelihood_from_idata,
    predictive_check,
    propagate_modes,
    sample_posterior,
    summary_dict,
    to_inference_data,
)
from bayesmodal.model.effects import EXTENSIONS
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

N_SAMPLES = 2000  # four pulses and a 0.5 V step


@pytest.fixture(scope="module")
def friction_data():
    return make("coulomb_friction", seed=8, n_samples=N_SAMPLES)


@pytest.fixture(scope="module")
def linear_data():
    return make(None, seed=5, n_samples=N_SAMPLES)


def _free():
    return LinearModel(Rig(), "free")


# ------------------------------------------------------------------------- likelihood
@pytest.mark.parametrize("name", sorted(EXTENSIONS))
def test_names_priors_and_null_equivalence(name, linear_data):
    """At the null values every extension's likelihood equals the linear likelihood."""
    model = _free()
    e = linear_data.experiment
    lik = Likelihood(model, [e], "ar1", extension=name)
    ext = EXTENSIONS[name]
    assert lik.names[: lik.n_mech] == ext.names(model.rig)
    assert lik.names[lik.n_mech :] == Likelihood(model, [e], "ar1").names[model.n_params :]
    priors = default_priors(model, noise="ar1", extension=name)
    assert priors.names == lik.names
    for spec, prior in zip(ext.specs(model.rig), priors.priors[model.n_params : lik.n_mech],
                           strict=True):
        assert prior.support == spec.bounds
    lin = Likelihood(model, [e], "ar1")
    theta_lin = np.r_[linear_data.theta_linear, np.full(3, 1e-5), np.full(3, 0.5)]
    null = ext.null_values(model.rig)
    if not np.all(np.isfinite(null)):  # saturation: a level far above the input
        null = np.where(np.isfinite(null), null, 1e3)
    full = np.r_[linear_data.theta_linear, null, theta_lin[model.n_params :]]
    a, b = lik(full[None])[0], lin(theta_lin[None])[0]
    # two simulators of one linear system, each within the ZOH bound (the extension's at
    # its sub-step, if it has one), carried through the AR(1) terms: the innovations
    # e_t = r_t - phi r_t-1 move by (1 + |phi|) dr, the log-density by sum |e| de / s^2
    # (a worst case, every error aligned); plus n eps of the summed terms
    theta_m = linear_data.theta_linear
    A, _ = model.state_space(theta_m)
    n_sub = int(getattr(ext, "n_sub", 1))
    y = simulate_linear(model, theta_m, e.v_volt, e.dt)
    dr = (zoh_rtol(A, e.dt, n_steps=e.n_samples)
          + zoh_rtol(A, e.dt / n_sub, n_steps=e.n_samples * n_sub)) * np.abs(y).max()
    s, phi = theta_lin[model.n_params : model.n_params + 3], theta_lin[-3:]
    r = e.y_m - y
    innov = r[1:] - phi * r[:-1]
    terms = lin.pointwise(theta_lin[None])[0][0]
    tol = (np.sum(np.abs(innov) * (1 + np.abs(phi)) / s**2) * dr
           + terms.size * EPS * np.abs(terms).sum())
    assert np.isfinite(a) and a == pytest.approx(b, rel=0, abs=tol)


def test_impossible_parameters_give_minus_inf(friction_data):
    model = _free()
    lik = Likelihood(model, [friction_data.experiment], "ar1", extension="coulomb_friction")
    good = np.r_[friction_data.theta_linear, friction_data.theta_extension,
                 np.full(3, 1e-5), np.full(3, 0.5)]
    bad_fs = good.copy()
    bad_fs[9 + 1], bad_fs[12 + 1] = 0.5, 0.2  # Fs2 < Fc2
    neg = good.copy()
    neg[9] = -0.1
    nan = good.copy()
    nan[11] = np.nan
    mass = good.copy()
    mass[1] = -1.0
    out = lik(np.array([good, bad_fs, neg, nan, mass]))
    assert np.isfinite(out[0])
    assert np.all(out[1:] == -np.inf)
    pw = lik.pointwise(np.array([good, bad_fs]))
    assert np.isfinite(pw[0][0]).all() and np.all(pw[0][1] == -np.inf)
    # the same terms summed in another order: n eps of the sum of their magnitudes
    assert np.sum(pw[0][0]) == pytest.approx(out[0], rel=0,
                                             abs=pw[0][0].size * EPS * np.abs(pw[0][0]).sum())


def test_bad_extension_arguments(linear_data):
    e = linear_data.experiment
    with pytest.raises(ModelError, match="unknown model extension"):
        Likelihood(_free(), [e], extension="friction")
    with pytest.raises(ModelError, match="free-damping"):
        Likelihood(LinearModel(Rig(), "proportional"), [e], extension="coulomb_friction")
    with pytest.raises(ModelError, match="Extension"):
        Likelihood(_free(), [e], extension=3.0)


# ------------------------------------------------------------------------- a short run
@pytest.fixture(scope="module")
def short_run(friction_data):
    run = sample_posterior(friction_data.experiment, _free(), extension="coulomb_friction",
                           noise="ar1", n_walkers=42, n_steps=40, rng=2, warn=False)
    return run


def test_short_run_layout_idata_summary_modes(short_run, friction_data, linear_data):
    """Shapes, names, InferenceData round trip, summaries and modes from the linear part."""
    run = short_run
    ext = EXTENSIONS["coulomb_friction"]
    assert run.names[:15] == ext.names(Rig())
    assert run.chain.shape == (40, 42, 21)
    assert run.extension_name == "coulomb_friction"
    assert run.config["extension"] == "coulomb_friction"
    assert np.all(ext.valid(Rig(), run.chain.reshape(-1, 21)[:, :15]))
    idata = to_inference_data(run, n_predictive=20, rng=1)
    assert idata.posterior.attrs["extension"] == "coulomb_friction"
    assert "Fs3" in idata.posterior
    # the rebuilt likelihood reproduces the stored total log-likelihood
    lik = likelihood_from_idata(idata)
    assert lik.extension_name == "coulomb_friction"
    d = run.flat_draws[:5]
    ll = lik(d)
    parts = lik.pointwise(d)
    pw = sum(p.sum(axis=(1, 2)) for p in parts)
    # the same terms summed in another order: n eps of the sum of their magnitudes
    tol = sum(p[0].size for p in parts) * EPS * sum(np.abs(p).sum(axis=(1, 2)) for p in parts)
    assert np.all(np.abs(ll - pw) <= tol)
    s = summary_dict(idata)
    assert s["extension"] == "coulomb_friction"
    assert set(s["parameters"]) == set(run.names)
    assert {r["quantity"] for r in s["lsq_comparison"]} >= {"Fc1", "Fs3", "omega_1"}
    ms = propagate_modes(_free(), run.flat_draws)
    assert ms.omega_rad_s.shape == (run.flat_draws.shape[0], 3)
    # predictive check of another record with the extended model
    test = likelihood_from_idata(idata, [linear_data.experiment])
    ps = predictive_check(test, run.flat_draws, max_draws=10)
    assert ps.fit_percent_median.shape == (1, 3) and np.isfinite(ps.lpd)


def test_elpd_change_refuses_other_data(short_run, linear_data):
    other = sample_posterior(linear_data.experiment, _free(), noise="ar1", n_walkers=30,
                             n_steps=20, rng=1, warn=False, refine=False)
    with pytest.raises(ConfigError, match="same observations"):
        elpd_change(other, short_run)


def test_same_seed_same_chain(friction_data):
    kw = dict(extension="coulomb_friction", noise="white", n_walkers=36, n_steps=30,
              warn=False, refine=False)
    e = friction_data.experiment
    a = sample_posterior(e, _free(), rng=7, **kw)
    b = sample_posterior(e, _free(), rng=7, start=a.lsq, **kw)
    np.testing.assert_array_equal(a.chain, b.chain)


# ------------------------------------------------------------------------- known truth
def _run(exp, extension, seed, start=None):
    return sample_posterior(exp, _free(), extension=extension, noise="ar1", n_walkers=42,
                            n_steps=1500, burn=700, rng=seed, warn=False, start=start)


@pytest.fixture(scope="module")
def truth_runs(friction_data):
    """With one encoder count of noise the posterior of the friction level is some 1e-4 N
    wide, narrower than the bias one sub-step per sample leaves against the reference
    simulator (a fraction of a count, see test_extensions); the run uses the default four
    sub-steps.  It starts from the single-start least-squares fit of the one-sub-step
    model, which reaches the truth's basin on this record (cost 1.6e-8 m^2); the
    four-sub-step fit from the linear fit, or from diagnose's grid start, stops in a local
    optimum 25000 times costlier that a 1500-step chain does not leave."""
    from bayesmodal.fit import fit_extension_lsq
    from bayesmodal.model.effects import CoulombFriction

    e = friction_data.experiment
    ext = EXTENSIONS["coulomb_friction"]
    start = fit_extension_lsq(e, CoulombFriction(n_sub=1), Rig()).theta
    return _run(e, ext, 11, start), _run(e, None, 12)


@pytest.mark.slow
def test_known_truth_friction_level(truth_runs, friction_data):
    """The 99 % interval of the kinetic level of the rubbing cart contains the truth and
    the other carts' levels are small; ELPD prefers friction decisively."""
    fr, lin = truth_runs
    i = friction_data.location[0] - 1
    d = fr.flat_draws
    fc_true = friction_data.theta_extension[i]
    lo, hi = np.quantile(d[:, 9 + i], [0.005, 0.995])
    assert lo <= fc_true <= hi, (lo, fc_true, hi)
    fs_true = friction_data.theta_extension[3 + i]
    lo, hi = np.quantile(d[:, 12 + i], [0.005, 0.995])
    assert lo <= fs_true <= hi, (lo, fs_true, hi)
    others = [j for j in range(3) if j != i]
    assert np.all(np.quantile(d[:, [9 + j for j in others]], 0.95, axis=0) < 0.1 * fc_true)
    ch = elpd_change(lin, fr)
    assert ch.decisive and ch.preferred == "coulomb_friction", ch.reading
    assert ch.delta > 0


@pytest.fixture(scope="module")
def null_runs(linear_data):
    e = linear_data.experiment
    return _run(e, "coulomb_friction", 21), _run(e, None, 22)


@pytest.mark.slow
def test_negative_control_linear_data(null_runs):
    """On data without friction the friction levels are consistent with zero and the ELPD
    change is not decisive."""
    fr, lin = null_runs
    d = fr.flat_draws
    # every kinetic level's lower 1 % quantile touches zero and the 95 % bound is small
    # against the smallest effect the catalogue's tests hide (0.3 N)
    assert np.all(np.quantile(d[:, 9:12], 0.01, axis=0) < 0.01)
    assert np.all(np.quantile(d[:, 9:12], 0.95, axis=0) < 0.05)
    ch = elpd_change(lin, fr)
    assert not ch.decisive, ch.reading
    assert ch.preferred == "neither"
