"""Several records of one rig: shared, per-record and hierarchical parameters."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesmodal._errors import ConfigError, DataError
from bayesmodal.data import Experiment
from bayesmodal.inference.likelihood import Likelihood
from bayesmodal.inference.record_layout import DEFAULT_LAYOUT, RecordLayout
from bayesmodal.inference.record_priors import record_priors, records_start
from bayesmodal.inference.records import RecordsLikelihood
from bayesmodal.inference.sampling import LogPosterior
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig

EPS = np.finfo(float).eps
MODEL = LinearModel(Rig(), "free")
THETA = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
TRUTH = [(5.5, 0.01), (6.0, -0.02), (5.0, 0.0)]  # (g_v, v0) per record
DT = 0.005
#: Gain and offset per record from populations (the truth above has both).
HIER = RecordLayout({"g_v": "hierarchical", "v0": "hierarchical"})


def _records(noise_m=1e-5, n=1500, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    out = []
    for k, (g, v0) in enumerate(TRUTH):
        v = 3.0 * ((t % 2) < 0.05) if k == 0 else 0.5 * np.sin(t * (1 + k))
        th = THETA.copy()
        th[0] = g
        y = simulate_linear(MODEL, th, v + v0, DT)
        out.append(Experiment(t, v, y + noise_m * rng.standard_normal(y.shape), name=f"r{k}"))
    return out


@pytest.fixture(scope="module")
def records():
    return _records()


def test_no_per_record_parameter_is_the_single_record_likelihood(records):
    lik = RecordsLikelihood(MODEL, records, "ar1", layout=RecordLayout({}))
    single = Likelihood(MODEL, records, "ar1")
    assert lik.names == single.names
    x = np.r_[THETA, 1e-5, 2e-5, 3e-5, 0.5, 0.6, 0.7][None]
    assert lik(x)[0] == single(x)[0]


def test_records_sharing_every_parameter_add_up_to_the_one_record_likelihoods(records):
    """One class for one record or several: with nothing per record (no layout, or the
    all-shared one) the likelihood of three records is the sum of the one-record
    likelihoods, record by record, and the white-noise closed form of the known
    residuals; a gain per record (the negative control) changes it."""
    sigma = np.array([1e-5, 2e-5, 3e-5])
    x = np.r_[THETA, sigma][None]
    ones = np.array([Likelihood(MODEL, [e], "white")(x)[0] for e in records])
    closed = [np.sum(stats.norm.logpdf(e.y_m - simulate_linear(MODEL, THETA, e.v_volt, DT),
                                       scale=sigma)) for e in records]
    for lik in (Likelihood(MODEL, records, "white"),
                Likelihood(MODEL, records, "white", layout=RecordLayout({}))):
        assert lik.names == MODEL.names + ("sigma_1", "sigma_2", "sigma_3")
        np.testing.assert_array_equal(lik.record_loglik(x)[0], ones)
        assert lik(x)[0] == ones[0] + ones[1] + ones[2]
        np.testing.assert_allclose(lik.record_loglik(x)[0], closed, rtol=1e-10)
    per = Likelihood(MODEL, records, "white", layout=RecordLayout({"g_v": "independent"}))
    at = dict(zip(MODEL.names + ("sigma_1", "sigma_2", "sigma_3"), x[0], strict=True))
    gains = {f"g_v[r{k}]": THETA[0] for k in range(3)}
    same = np.array([[{**at, **gains}[nm] for nm in per.names]])
    assert per(same)[0] == ones[0] + ones[1] + ones[2]
    other = np.array([[{**at, **gains, "g_v[r1]": 1.1 * THETA[0]}[nm] for nm in per.names]])
    ll = per.record_loglik(other)[0]
    assert ll[0] == ones[0] and ll[2] == ones[2]
    assert abs(ll[1] - ones[1]) > 10.0  # (record 1 was recorded with a gain of 6.0)


def test_names_follow_the_layout(records):
    lik = RecordsLikelihood(MODEL, records, "white",
                            layout=RecordLayout({"g_v": "independent", "m1": "hierarchical"},
                                                noise_per_record=True))
    assert lik.names[:7] == ("m2", "m3", "c1", "c2", "c3", "c12", "c23")
    assert lik.names[7:10] == ("g_v[r0]", "g_v[r1]", "g_v[r2]")
    assert lik.names[10:12] == ("mu_m1", "tau_m1")
    assert lik.names[-3:] == ("sigma_1[r2]", "sigma_2[r2]", "sigma_3[r2]")


def test_input_offset_by_superposition_equals_simulating_the_offset_input(records):
    lik = RecordsLikelihood(MODEL, records, "ar1", layout=HIER)
    centre = records_start(lik, THETA)
    for r, e in enumerate(records):
        full, v0 = lik.record_theta(centre[None], r)
        direct = simulate_linear(MODEL, full[0, :9], e.v_volt + v0[0], DT)
        # the same exact recursions, regrouped: rounding grows at most with the length
        tol = e.n_samples * EPS * np.max(np.abs(direct))
        assert np.max(np.abs(lik.predict_record(centre[None], r)[0] - direct)) <= tol
        assert v0[0] != 0.0 or TRUTH[r][1] == 0.0


def test_start_solves_gains_and_offsets_in_closed_form():
    exact = _records(noise_m=0.0)
    lik = RecordsLikelihood(MODEL, exact, "white", layout=HIER)
    c = dict(zip(lik.names, records_start(lik, THETA), strict=True))
    for k, (g, v0) in enumerate(TRUTH):
        # a least-squares solve of an exactly consistent system: error ~ cond * eps
        A = np.column_stack([simulate_linear(MODEL, np.r_[1.0, THETA[1:]], exact[k].v_volt,
                                             DT).ravel(),
                             simulate_linear(MODEL, np.r_[1.0, THETA[1:]],
                                             np.ones(exact[k].n_samples), DT).ravel()])
        tol = np.linalg.cond(A) * exact[k].n_samples * EPS
        assert c[f"g_v[r{k}]"] == pytest.approx(g, rel=tol)
        assert c[f"v0[r{k}]"] == pytest.approx(v0, abs=tol)
    assert c["mu_g_v"] == pytest.approx(np.exp(np.mean(np.log([g for g, _ in TRUTH]))))


def test_pointwise_terms_sum_to_the_total(records):
    lik = RecordsLikelihood(MODEL, records, "ar1", layout=HIER)
    c = records_start(lik, THETA)
    x = np.stack([c, c * np.r_[np.full(lik.n_params - 6, 1.001), np.ones(6)]])
    total = lik(x)
    parts = sum(p.sum(axis=(1, 2)) for p in lik.pointwise(x))
    n = lik.n_data
    np.testing.assert_allclose(parts, total, rtol=n * 1e3 * EPS)  # 3 digits lost: see ar1
    assert lik.record_loglik(x).shape == (2, 3)


def test_population_density_matches_scipy(records):
    lik = RecordsLikelihood(MODEL, records, "white", layout=HIER)
    c = records_start(lik, THETA)
    d = dict(zip(lik.names, c, strict=True))
    gs = [d[f"g_v[r{k}]"] for k in range(3)]
    v0s = [d[f"v0[r{k}]"] for k in range(3)]
    ref = np.sum(stats.lognorm.logpdf(gs, s=d["tau_g_v"], scale=d["mu_g_v"]))
    ref += np.sum(stats.norm.logpdf(v0s, d["mu_v0"], d["tau_v0"]))
    assert lik.log_population(c[None])[0] == pytest.approx(ref, rel=1e3 * EPS)
    # the posterior adds it to the independent priors
    priors = record_priors(lik)
    lp = LogPosterior(lik, priors)(priors.to_sampling(c)[None])
    expect = (priors.log_prior_z(priors.to_sampling(c)) + ref + lik(c[None])[0])
    assert lp[0, 0] == pytest.approx(expect, rel=1e3 * EPS)
    # negative control: a spread that excludes the records lowers the density
    bad = c.copy()
    bad[lik.names.index("tau_g_v")] = 1e-3
    assert lik.log_population(bad[None])[0] < ref


def test_bad_layouts_name_the_fix(records):
    with pytest.raises(ConfigError, match="not a model parameter"):
        RecordsLikelihood(MODEL, records, "white", layout=RecordLayout({"k9": "independent"}))
    with pytest.raises(ConfigError, match="kind must be one of"):
        RecordLayout({"g_v": "pooled"})
    same = [records[0], records[0]]
    with pytest.raises(DataError, match="distinct"):
        RecordsLikelihood(MODEL, same, "white")
    lik = RecordsLikelihood(MODEL, records, "white", layout=RecordLayout({"c12": "hierarchical"}))
    with pytest.raises(ConfigError, match="declare c12 independent"):
        record_priors(lik)
    with pytest.raises(ConfigError, match="input_offset"):
        RecordsLikelihood(MODEL, records, "white", extension="motor_lag", layout=DEFAULT_LAYOUT)


def test_layout_round_trips_through_a_dict():
    lay = RecordLayout({"g_v": "hierarchical", "v0": "independent"}, noise_per_record=True)
    assert RecordLayout.from_dict(lay.to_dict()) == lay


def test_ar_p_noise_with_order_one_is_the_ar1_likelihood(records):
    from bayesmodal.inference.noise import ARpNoise

    ar1 = RecordsLikelihood(MODEL, records, "ar1", layout=HIER)
    arp = RecordsLikelihood(MODEL, records, ARpNoise((1, 1, 1)), layout=HIER)
    assert arp.names[-3:] == ("pacf1_1", "pacf1_2", "pacf1_3")
    c = records_start(ar1, THETA)
    # two implementations of the exact AR(1) density: sufficient statistics lose ~3
    # digits (see residual_loglik), so agree to n_data * 1e3 eps
    np.testing.assert_allclose(arp(c[None]), ar1(c[None]), rtol=ar1.n_data * 1e3 * EPS)
    ar3 = RecordsLikelihood(MODEL, records, "ar3", layout=HIER)
    c3 = records_start(ar3, THETA)
    parts = sum(p.sum(axis=(1, 2)) for p in ar3.pointwise(c3[None]))
    np.testing.assert_allclose(parts, ar3(c3[None]), rtol=ar3.n_data * 1e3 * EPS)
    assert np.isfinite(record_priors(ar3).log_prior(c3))


def test_noise_model_names_are_checked():
    from bayesmodal.inference.noise_choice import resolve_noise

    assert resolve_noise("ar(2,3,1)", 3).orders == (2, 3, 1)
    with pytest.raises(ConfigError, match="ar:auto"):
        resolve_noise("arma", 3)
    with pytest.raises(DataError, match="one order per output"):
        resolve_noise("ar(2,3)", 3)


def test_predicting_a_record_with_its_own_population_covers_it():
    """Known truth: records whose gains come from the population the posterior describes
    are covered; the control with the population spread forced to ~0 and a gain far off
    covers much less."""
    from bayesmodal.inference.predictive import predict_new_record, score_samples

    recs = _records(noise_m=2e-5, n=1200, seed=3)
    lik = RecordsLikelihood(MODEL, recs[:2], "white", layout=HIER)
    c = records_start(lik, THETA)
    d = dict(zip(lik.names, c, strict=True))
    rng = np.random.default_rng(11)
    draws = np.repeat(c[None], 400, axis=0)
    # a population wide enough to hold the third record's gain (5.0) and offset (0)
    draws[:, lik.names.index("mu_g_v")] = 5.5
    draws[:, lik.names.index("tau_g_v")] = 0.1
    draws[:, lik.names.index("mu_v0")] = 0.0
    draws[:, lik.names.index("tau_v0")] = 0.02
    draws[:, lik.names.index("sigma_1"):] = 2e-5
    _, y_pred, ll = predict_new_record(lik, draws, recs[2], rng=rng)
    good = score_samples("r2", recs[2].y_m, y_pred, ll)
    bad_draws = draws.copy()
    bad_draws[:, lik.names.index("mu_g_v")] = 6.5
    bad_draws[:, lik.names.index("tau_g_v")] = 1e-4
    _, y_bad, ll_bad = predict_new_record(lik, bad_draws, recs[2], rng=rng)
    bad = score_samples("r2", recs[2].y_m, y_bad, ll_bad)
    assert np.all(good.coverage_90 > bad.coverage_90)
    assert good.lpd > bad.lpd
    assert d["g_v[r0]"] > 0


def test_offset_per_record_through_the_input_offset_effect(records):
    """With a model extension the record's v0 is the input_offset effect's v_offset; on the
    linear plant it predicts what the linear model predicts for v + v0."""
    lik = RecordsLikelihood(MODEL, records, "white", extension="input_offset", layout=HIER)
    assert "v_offset[r1]" in lik.names and "mu_v_offset" in lik.names
    c = records_start(lik, np.r_[THETA, 0.0])
    c[lik.names.index("v_offset[r1]")] = -0.02
    full, _ = lik.record_theta(c[None], 1)
    th = full[0, :9]
    direct = simulate_linear(MODEL, th, records[1].v_volt - 0.02, DT)
    got = lik.predict_record(c[None], 1)[0]
    tol = records[1].n_samples * EPS * np.max(np.abs(direct))
    assert np.max(np.abs(got - direct)) <= tol
    assert np.isfinite(record_priors(lik).log_prior(c))


def test_process_noise_through_the_records_likelihood(records):
    """Process noise: the record likelihood is the Kalman filter's (checked against a dense
    reference in test_noise_kalman.py), per record with its own gain; the refusals name
    the fix."""
    from bayesmodal.inference.noise import kalman_loglik

    lik = RecordsLikelihood(MODEL, records, "process", layout=RecordLayout({"g_v": "independent"}))
    assert lik.names[-6:] == ("q_1", "q_2", "q_3", "sigma_1", "sigma_2", "sigma_3")
    c = records_start(lik, THETA)
    per = lik.record_loglik(c[None])[0]
    for r, e in enumerate(records):
        full, _ = lik.record_theta(c[None], r)
        ref = kalman_loglik(MODEL, full[:, :9], full[:, 9:12], full[:, 12:], e.v_volt, e.y_m,
                            e.dt, initial="rest")[0]
        assert per[r] == ref
    parts = lik.pointwise(c[None])
    assert all(np.all(np.isfinite(p)) for p in parts)
    with pytest.raises(ConfigError, match="linear model"):
        RecordsLikelihood(MODEL, records, "process", extension="motor_lag",
                          layout=RecordLayout({}))


@pytest.mark.parametrize("layout", [DEFAULT_LAYOUT, HIER], ids=["v0 shared", "v0 per record"])
def test_process_noise_takes_the_input_offset(records, layout):
    """With an input offset (shared or per record) each record's process-noise likelihood
    is the filter of the shifted input ``v + v0`` (brute force, one row at a time), its
    pointwise terms sum to it, and the predictive noise draws are centred on the offset
    model's prediction (Monte Carlo tolerance).  Negative control: the offset matters."""
    from bayesmodal.inference.noise import kalman_loglik

    lik = RecordsLikelihood(MODEL, records, "process", layout=layout)
    c = records_start(lik, THETA)
    assert "v0" in lik.names or "v0[r1]" in lik.names
    per = lik.record_loglik(c[None])[0]
    parts = lik.pointwise(c[None])
    for r, e in enumerate(records):
        full, v0 = lik.record_theta(c[None], r)
        assert v0[0] != 0.0
        ref = kalman_loglik(MODEL, full[:, :9], full[:, 9:12], full[:, 12:], e.v_volt + v0[0],
                            e.y_m, e.dt, initial="rest")[0]
        kalman_pointwise_sum = parts[r][0].sum()
        tol = 8 * e.n_samples * EPS * np.abs(parts[r][0]).sum()
        assert abs(per[r] - ref) <= tol
        # pointwise terms are the steady-start filter's: they differ from the exact start
        # from rest by its correction only (a transient), not by the offset's response
        steady = kalman_loglik(MODEL, full[:, :9], full[:, 9:12], full[:, 12:],
                               e.v_volt + v0[0], e.y_m, e.dt)[0]
        assert abs(kalman_pointwise_sum - steady) <= tol
        without = kalman_loglik(MODEL, full[:, :9], full[:, 9:12], full[:, 12:], e.v_volt,
                                e.y_m, e.dt, initial="rest")[0]
        assert abs(without - ref) > 100 * tol
    # predictive noise draws: the random force's response, from the same generator stream
    # as a simulation of the shifted input minus the offset model's prediction
    from bayesmodal.inference.noise import simulate_process_noise

    th = np.repeat(c[None], 3, axis=0)
    draws = lik.noise_draws(th, rng=np.random.default_rng(3))
    rng = np.random.default_rng(3)
    for r, e in enumerate(records):
        full, v0 = lik.record_theta(th, r)
        y = simulate_process_noise(MODEL, full[:, :9], full[:, 9:12], full[:, 12:],
                                   e.v_volt + v0[0], e.dt, rng)
        ref = y - simulate_linear(MODEL, full[:, :9], e.v_volt + v0[0], e.dt)
        scale = np.abs(y).max()
        assert np.allclose(draws[r], ref, rtol=0, atol=1e4 * EPS * scale)
        shift = simulate_linear(MODEL, full[:, :9], e.v_volt + v0[0], e.dt) - \
            simulate_linear(MODEL, full[:, :9], e.v_volt, e.dt)
        assert np.abs(shift).max() > 1e8 * EPS * scale  # the offset moves the prediction
    if layout is DEFAULT_LAYOUT:
        # a held-out record: the shared offset enters its prediction and its log density
        from bayesmodal.inference.predictive import predict_new_record

        th = c[None].copy()
        th[0, lik.names.index("tau_g_v")] = 0.0  # the new record's gain is mu_g_v
        y_hat, _, ll = predict_new_record(lik, th, records[1], rng=0)
        full, v0 = lik.record_theta(th, 1)
        mech = full[:, :9].copy()
        mech[0, 0] = th[0, lik.names.index("mu_g_v")]
        e = records[1]
        ref = simulate_linear(MODEL, mech, e.v_volt + v0[0], e.dt)
        assert np.allclose(y_hat, ref, rtol=0, atol=1e3 * EPS * np.abs(ref).max())
        ref_ll = kalman_loglik(MODEL, mech, full[:, 9:12], full[:, 12:], e.v_volt + v0[0],
                               e.y_m, e.dt, initial="rest")
        assert abs(ll[0] - ref_ll[0]) <= 8 * e.n_samples * EPS * abs(ref_ll[0])


def test_a_shared_offset_is_one_parameter_for_every_record(records):
    lik = RecordsLikelihood(MODEL, records, "white",
                            layout=RecordLayout({"g_v": "hierarchical", "v0": "shared"}))
    assert lik.names.count("v0") == 1 and not any(n.startswith("v0[") for n in lik.names)
    c = records_start(lik, THETA)
    v0 = c[lik.names.index("v0")]
    assert v0 == pytest.approx(np.mean([o for _, o in TRUTH]), abs=1e-3)
    for r, e in enumerate(records):
        full, off = lik.record_theta(c[None], r)
        assert off[0] == v0
        direct = simulate_linear(MODEL, full[0, :9], e.v_volt + v0, DT)
        tol = e.n_samples * EPS * np.max(np.abs(direct))
        assert np.max(np.abs(lik.predict_record(c[None], r)[0] - direct)) <= tol
    assert np.isfinite(record_priors(lik).log_prior(c))
    assert lik.log_population(c[None])[0] == pytest.approx(
        RecordsLikelihood(MODEL, records, "white",
                          layout=RecordLayout({"g_v": "hierarchical"})).log_population(
            np.delete(c, lik.names.index("v0"))[None])[0])
