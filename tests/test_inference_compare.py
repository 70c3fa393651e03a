"""Model choice: evidence against closed forms, Bayes-factor reading, LOO/WAIC, prediction."""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal.data import Experiment
from bayesmodal.inference import (
    PriorSet,
    Uniform,
    bayes_factor,
    choose_model,
    information_criteria,
    kass_raftery,
    nested_evidence,
    sample_posterior,
    simulate_noise,
    to_inference_data,
)
from bayesmodal.inference.evidence import Evidence
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig


def _gauss(mu, sd):
    mu, sd = np.asarray(mu), np.asarray(sd)

    def f(theta):
        z = (theta - mu) / sd
        return np.sum(-0.5 * z**2 - np.log(sd) - 0.5 * np.log(2 * np.pi), axis=-1)

    return f


def test_nested_evidence_matches_closed_form_and_prior_width():
    """Normalised Gaussian likelihood well inside a box prior: Z = 1 / box volume.

    Doubling the width of one prior halves Z (negative control: ln Z drops by ln 2)."""
    pytest.importorskip("dynesty", reason="dynesty (the 'evidence' extra) not installed")
    mu, sd = [0.3, -1.0], [0.2, 0.5]
    narrow = PriorSet(("a", "b"), (Uniform(-3, 3), Uniform(-5, 5)), ("identity",) * 2)
    wide = PriorSet(("a", "b"), (Uniform(-6, 6), Uniform(-5, 5)), ("identity",) * 2)
    ev1 = nested_evidence(_gauss(mu, sd), narrow, nlive=200, rng=1)
    ev2 = nested_evidence(_gauss(mu, sd), wide, nlive=200, rng=2)
    for ev, vol in ((ev1, 60.0), (ev2, 120.0)):
        assert abs(ev.log_z - np.log(1 / vol)) < 4 * ev.log_z_err, (ev.log_z, ev.log_z_err)
        assert ev.n_calls > 0 and ev.information_nats > 0
    bf = bayes_factor({"narrow": ev1, "wide": ev2}, "narrow", "wide")
    assert abs(bf.log_bf - np.log(2)) < 4 * bf.log_bf_err
    assert bf.favoured == "narrow"


def test_kass_raftery_reading():
    assert kass_raftery(1.0) == "not worth more than a bare mention"
    assert kass_raftery(-3.0) == "positive"
    assert kass_raftery(7.0) == "strong"
    assert kass_raftery(25.0) == "very strong"
    e = {"a": Evidence(10.0, 0.3, 1, 1, 1, 0.0), "b": Evidence(6.0, 0.4, 1, 1, 1, 0.0)}
    bf = bayes_factor(e, "a", "b")
    assert bf.log_bf == pytest.approx(4.0) and bf.log_bf_err == pytest.approx(0.5)
    assert bf.two_ln_b == pytest.approx(8.0) and bf.reading == "strong"


def _free_data(v_amp, seed, n=1000):
    """Free damping with strong relative dampers, which proportional damping cannot mimic."""
    model = LinearModel(Rig(), "free")
    truth = np.array([6.2, 1.57, 1.46, 1.14, 0.5, 0.3, 2.5, 1.5, 0.1])
    t = np.arange(n) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), v_amp, 0.0) + np.where(t >= 2.5, 0.5, 0.0)
    e = simulate_noise(np.full((1, 3), 3e-5), None, n, rng=seed)[0]
    return Experiment(t, v, simulate_linear(model, truth, v, 0.005) + e, name=f"free{seed}")


@pytest.fixture(scope="module")
def two_runs():
    train = _free_data(3.0, seed=1)
    out = {}
    for damping in ("free", "proportional"):
        run = sample_posterior(train, LinearModel(Rig(), damping), noise="white",
                               n_walkers=24, n_steps=800, burn=300, rng=3, warn=False)
        out[damping] = to_inference_data(run, n_predictive=0, rng=0)
    return out


def test_information_criteria_effective_parameters(two_runs):
    ic = information_criteria(two_runs["free"])
    assert ic.n_obs == 3000
    # regular, well-specified model: p_loo and p_waic approach the number of parameters
    # (9 mechanical + 3 sigma = 12); the Monte Carlo error with ~1000 draws is a few units
    assert 6 < ic.p_loo < 20 and 6 < ic.p_waic < 20
    assert abs(ic.elpd_loo - ic.elpd_waic) < 2
    assert ic.n_bad_k == 0


def test_model_choice_prefers_the_true_damping_model(two_runs):
    test = _free_data(-2.0, seed=2)
    choice = choose_model(two_runs, test=test, evidence=False)
    assert choice.preferred["loo"] == "free"
    assert choice.preferred["waic"] == "free"
    assert choice.preferred["predictive"] == "free"
    pf, pp = choice.predictive["free"], choice.predictive["proportional"]
    assert pf.lpd > pp.lpd and pf.mean_log_lik <= pf.lpd
    assert np.all(pf.fit_percent_median > pp.fit_percent_median)
    md = choice.to_markdown()
    assert "PSIS-LOO" in md and "lpd on free2" in md
    assert "free" in choice.verdict
    d = choice.as_dict()
    assert d["preferred"]["loo"] == "free" and "loo_compare" in d
