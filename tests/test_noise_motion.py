"""AR(1) noise whose level follows each output's speed (``"ar1:motion"``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bayesmodal._errors import DataError
from bayesmodal.data import Experiment
from bayesmodal.inference.noise import AR1Noise
from bayesmodal.inference.noise.motion import MotionAR1Noise, quantum_of, speed_weight
from bayesmodal.inference.noise_spec import parse_noise

EPS = np.finfo(float).eps


def _weight(rng, n, n_out):
    return rng.uniform(size=(n, n_out))


def _params(sigma, phi, rest):
    return np.concatenate([np.atleast_2d(sigma), np.atleast_2d(phi), np.atleast_2d(rest)],
                          axis=1)


def _dense_cov(sigma, phi, rest, w, q=0.0):
    """Covariance of one output: ``r = A^-1 S e`` with ``A`` unit lower bidiagonal
    (``-phi`` below) and ``S`` the innovation levels (the first one stationary)."""
    n = w.size
    s = np.sqrt((sigma * (rest + (1 - rest) * w)) ** 2 + (1 + phi**2) * q**2 / 12)
    s[0] /= np.sqrt(1 - phi**2)
    A = np.eye(n) - phi * np.eye(n, k=-1)
    Ai = np.linalg.solve(A, np.diag(s))
    return Ai @ Ai.T


def test_the_registry_names_it():
    spec = parse_noise("AR1:Motion")
    assert spec.kind == "ar1:motion"
    assert isinstance(spec.model(2), MotionAR1Noise)
    assert spec.model(2).names(2) == ("sigma_1", "sigma_2", "phi_1", "phi_2", "rest_1",
                                      "rest_2")


@pytest.mark.parametrize("n", [7, 40])
@pytest.mark.parametrize("quantised", [False, True])
def test_loglik_equals_the_dense_gaussian(n, quantised):
    """Closed form: the density of ``r`` is N(0, A^-1 S^2 A^-T) per output."""
    rng = np.random.default_rng(n)
    n_out, nb = 2, 3
    w = _weight(rng, n, n_out)
    q = np.array([0.7, 0.0]) if quantised else np.zeros(n_out)
    model = MotionAR1Noise(weight=w, quantum_m=q if quantised else None)
    p = _params(rng.uniform(0.5, 2, (nb, n_out)), rng.uniform(-0.9, 0.95, (nb, n_out)),
                rng.uniform(0.2, 8, (nb, n_out)))
    r = rng.normal(size=(nb, n, n_out))
    got = model.loglik(np.moveaxis(r, 0, -1), p)
    for b in range(nb):
        ref, tol = 0.0, 0.0
        for j in range(n_out):
            cov = _dense_cov(p[b, j], p[b, n_out + j], p[b, 2 * n_out + j], w[:, j], q[j])
            ref += stats.multivariate_normal(np.zeros(n), cov).logpdf(r[b, :, j])
            tol += 100 * n * np.linalg.cond(cov) * EPS
        assert abs(got[b] - ref) <= tol * max(1.0, abs(ref))


def test_one_level_is_the_plain_ar1_model_and_pointwise_sums_to_loglik():
    rng = np.random.default_rng(3)
    n, n_out, nb = 300, 3, 4
    model = MotionAR1Noise(weight=_weight(rng, n, n_out))
    sp = np.c_[rng.uniform(0.5, 2, (nb, n_out)), rng.uniform(-0.9, 0.95, (nb, n_out))]
    r = AR1Noise().simulate(sp, n, rng=4)
    pw = model.pointwise(r, np.c_[sp, np.ones((nb, n_out))])
    ref = AR1Noise().pointwise(r, sp)
    assert np.all(np.abs(pw - ref) <= 8 * EPS * np.maximum(1.0, np.abs(ref)))
    total = model.loglik(np.moveaxis(r, 0, -1), np.c_[sp, np.ones((nb, n_out))])
    assert np.all(np.abs(total - pw.sum(axis=(1, 2)))
                  <= 2 * pw[0].size * EPS * np.abs(pw).sum(axis=(1, 2)))
    # negative control: a rest fraction away from 1 changes the density
    assert not np.allclose(model.loglik(np.moveaxis(r, 0, -1),
                                        np.c_[sp, np.full((nb, n_out), 0.3)]), total)


def test_simulate_has_the_model_covariance():
    """Sample covariance of 6 samples over many draws vs the dense covariance."""
    w = np.array([0.0, 0.2, 1.0, 1.0, 0.5, 0.0])[:, None]
    model = MotionAR1Noise(weight=w)
    n_draw = 20000
    p = _params(0.5, 0.7, 0.25)
    r = model.simulate(np.repeat(p, n_draw, axis=0), w.size, rng=11)[:, :, 0]
    g = _dense_cov(0.5, 0.7, 0.25, w[:, 0])
    emp = r.T @ r / n_draw
    se = np.sqrt((np.outer(np.diag(g), np.diag(g)) + g**2) / n_draw)
    # 21 distinct entries: 4.5 standard errors keeps the family-wise false alarm < 1e-3
    assert np.all(np.abs(emp - g) < 4.5 * se)


def _profile_rest(model, r, sigma, phi, grid):
    p = np.c_[np.full((grid.size, 1), sigma), np.full((grid.size, 1), phi), grid[:, None]]
    return model.loglik(np.repeat(r[:, :, None], grid.size, axis=2), p)


@pytest.mark.parametrize("rest", [1.0, 0.25])
def test_the_rest_level_is_found_and_not_found_where_there_is_none(rest):
    """The likelihood's maximum over a grid of ``rest`` (sigma and phi at the truth) lies
    within 3 standard errors of the truth (from the curvature of the log-likelihood); with
    a true rest fraction of 1/4, one level (``rest = 1``) lies far outside; with a true
    fraction of 1 it is inside (the negative control)."""
    n = 4000
    t = np.arange(n) * 0.01
    w = (np.sin(2 * np.pi * 0.3 * t) ** 2)[:, None]
    model = MotionAR1Noise(weight=w)
    r = model.simulate(_params(1e-5, 0.6, rest), n, rng=21)[0]
    grid = np.exp(np.linspace(np.log(0.05), np.log(3), 2001))
    ll = _profile_rest(model, r, 1e-5, 0.6, grid)
    k = int(np.argmax(ll))
    # curvature in log(rest) by a three-point difference around the maximum
    h = np.log(grid[1]) - np.log(grid[0])
    se = 1 / np.sqrt(-(ll[k + 1] - 2 * ll[k] + ll[k - 1]) / h**2)
    assert abs(np.log(grid[k]) - np.log(rest)) < 3 * se
    if rest != 1.0:
        assert abs(np.log(grid[k])) > 10 * se


@pytest.mark.parametrize("rest", [1.0, 0.25])
def test_the_start_is_unbiased_over_replicates(rest):
    """``start`` (a straight line through the innovations' sizes) over 40 replicate
    records: the mean of ``log rest`` lies within 4 standard errors of the truth."""
    n, reps = 4000, 40
    t = np.arange(n) * 0.01
    model = MotionAR1Noise(weight=(np.sin(2 * np.pi * 0.3 * t) ** 2)[:, None])
    r = model.simulate(np.repeat(_params(1e-5, 0.6, rest), reps, axis=0), n, rng=22)
    est = np.log([model.start(x)[2] for x in r])
    assert abs(est.mean() - np.log(rest)) < 4 * est.std(ddof=1) / np.sqrt(reps)


def test_quantum_of_reads_the_encoder_step():
    rng = np.random.default_rng(5)
    q = 0.0706 / 16000                                    # one ECP 210 encoder count, m
    counts = np.cumsum(rng.integers(-3, 4, size=500), axis=0)
    y = np.c_[counts * q, rng.normal(size=500)]           # an encoder, an analogue sensor
    got = quantum_of(y)
    assert abs(got[0] - q) <= 8 * np.finfo(float).eps * np.abs(y[:, 0]).max()
    assert got[1] == 0.0


def test_the_floor_keeps_a_resting_record_finite():
    """A cart at rest reads one count throughout, so its residual is constant and its
    innovations ``r_k - phi r_{k-1}`` vanish as phi -> 1.  Without the floor the log
    density grows without bound as the rest level shrinks; with the quantisation floor it
    levels off (the bound: every term at most ``-log(f) - log(2 pi)/2``)."""
    n = 400
    r = np.full((1, n, 1), 3e-6)
    w = np.zeros((n, 1))
    q = np.array([0.0706 / 16000])
    levels = np.array([1e-6, 1e-7, 1e-8])   # all above the innovations (3e-10 m after
    # the first; the first, stationary one is 4e-8 m)
    p = np.c_[levels, np.full(3, 0.9999), np.ones(3)]
    bare = MotionAR1Noise(weight=w).loglik(np.repeat(r, 3, 0).transpose(1, 2, 0), p)
    floor = MotionAR1Noise(weight=w, quantum_m=q).loglik(
        np.repeat(r, 3, 0).transpose(1, 2, 0), p)
    assert np.all(np.diff(bare) > n)                      # unbounded without the floor
    f = np.sqrt((1 + 0.9999**2) * q[0] ** 2 / 12)
    bound = n * (-np.log(f) - 0.5 * np.log(2 * np.pi))
    assert np.all(floor <= bound + n * EPS * abs(bound))


def test_speed_weight_is_zero_at_rest_and_one_at_the_fastest_motion():
    dt = 0.01
    t = np.arange(0, 4, dt)
    y = np.c_[np.where(t < 1, 0.0, np.sin(2 * np.pi * (t - 1))) * (t < 2), np.zeros_like(t)]
    w = speed_weight(y, dt, 0.1)
    assert w.shape == y.shape and w.max() == 1.0 and np.all(w >= 0)
    assert np.all(w[t < 0.9, 0] == 0) and np.all(w[t > 2.1, 0] == 0)
    assert np.all(w[:, 1] == 0)          # a cart that never moves


def test_a_record_gives_the_model_its_own_speed_and_a_model_without_one_refuses():
    dt = 0.01
    t = np.arange(200) * dt
    y = np.c_[np.sin(t), np.cos(t)]
    e = Experiment(t, np.zeros_like(t), y, name="r")
    m = MotionAR1Noise().for_record(e)
    assert m.weight.shape == y.shape
    assert MotionAR1Noise().for_record(e) == m  # the covariate is not part of equality
    with pytest.raises(DataError, match="for_record"):
        MotionAR1Noise().loglik(np.zeros((200, 2, 1)), np.ones((1, 6)))
    with pytest.raises(DataError, match="shape"):
        m.loglik(np.zeros((100, 2, 1)), np.ones((1, 6)))


def test_invalid_parameters_give_minus_infinity():
    m = MotionAR1Noise(weight=np.zeros((10, 1)))
    p = np.array([[1.0, 0.5, -1.0], [1.0, 1.0, 2.0], [-1.0, 0.0, 2.0], [1.0, 0.0, 2.0]])
    ll = m.loglik(np.zeros((10, 1, 4)), p)
    assert np.all(np.isneginf(ll[:3])) and np.isfinite(ll[3])


# ---------------------------------------------------------------- through the likelihood
def _records_with_motion_noise(rest, n=1200, seed=0):
    """Two records of the three-cart rig (a pulse, a slow sine) whose residuals are
    ``ar1:motion`` noise built on each record's own noise-free speed."""
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig

    model = LinearModel(Rig(), "free")
    theta = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
    dt = 0.005
    t = np.arange(n) * dt
    noise = _params(np.full((1, 3), 4e-6), np.full((1, 3), 0.5), np.full((1, 3), rest))
    out = []
    for k, v in enumerate((3.0 * ((t > 0.5) & (t < 0.55)), 0.5 * np.sin(2 * t))):
        y = simulate_linear(model, theta, v, dt)
        clean = Experiment(t, v, y, name=f"r{k}")
        r = MotionAR1Noise().for_record(clean).simulate(noise, n, rng=seed + k)[0]
        out.append(Experiment(t, v, y + r, name=f"r{k}"))
    return model, theta, noise, out


def test_each_record_is_evaluated_with_its_own_speed():
    from bayesmodal.inference.record_layout import RecordLayout
    from bayesmodal.inference.records import RecordsLikelihood
    from bayesmodal.model.simulate import simulate_linear

    model, theta, noise, recs = _records_with_motion_noise(0.25)
    lik = RecordsLikelihood(model, recs, "ar1:motion", layout=RecordLayout({}))
    assert lik.names[-9:] == MotionAR1Noise().names(3)
    x = np.r_[theta, noise[0]][None]
    got = lik.record_loglik(x)[0]
    for k, e in enumerate(recs):
        R = (e.y_m - simulate_linear(model, theta, e.v_volt, e.dt))[:, :, None]
        own = MotionAR1Noise().for_record(e).loglik(R, noise)[0]
        other = MotionAR1Noise().for_record(recs[1 - k]).loglik(R, noise)[0]
        assert abs(got[k] - own) <= 1e3 * EPS * R.size * abs(own)
        assert abs(got[k] - other) > 1.0          # negative control: the other record's speed


def test_a_held_out_record_is_predicted_with_its_own_speed():
    from bayesmodal.inference.predictive import predict_new_record
    from bayesmodal.inference.record_layout import RecordLayout
    from bayesmodal.inference.records import RecordsLikelihood

    model, theta, noise, recs = _records_with_motion_noise(0.25)
    lik = RecordsLikelihood(model, recs[:1], "ar1:motion", layout=RecordLayout({}))
    draws = np.repeat(np.r_[theta, noise[0]][None], 400, axis=0)
    y_hat, y_pred, ll = predict_new_record(lik, draws, recs[1], rng=5)
    assert y_pred.shape == (400, *recs[1].y_m.shape) and np.all(np.isfinite(ll))
    # the predictive spread follows the held-out record's own speed: the ratio of its
    # residual sd where cart 1 moves fastest to its sd at rest is the ratio of the RMS
    # levels rest + (1 - rest) w there (they change slowly against phi = 0.5's memory),
    # within Monte Carlo error (effective draws of an AR(1) with phi = 0.5: a third)
    w = MotionAR1Noise().for_record(recs[1]).weight[:, 0]
    fast, rest = w > 0.95, w < 0.05
    level = 0.25 + 0.75 * w
    expected = np.sqrt(np.mean(level[fast] ** 2) / np.mean(level[rest] ** 2))
    e = (y_pred - y_hat)[:, :, 0]
    ratio = e[:, fast].std() / e[:, rest].std()
    n_eff = 400 * min(fast.sum(), rest.sum()) * (1 - 0.5) / (1 + 0.5)
    assert abs(np.log(ratio) - np.log(expected)) < 4 * np.sqrt(2 / n_eff)
    assert abs(np.log(ratio)) > 20 * np.sqrt(2 / n_eff)   # not the plain AR(1) spread


def test_the_posterior_finds_the_rest_level_on_simulated_records():
    """``sample_posterior(..., noise="ar1:motion")`` on the two records above (true rest
    fraction 1/4 on every output): each 99 % interval of ``rest_j`` holds 1/4 and lies
    further from 1 than its own width."""
    from bayesmodal.inference import sample_posterior

    model, _, _, recs = _records_with_motion_noise(0.25)
    run = sample_posterior(recs, model, noise="ar1:motion", n_walkers=40, n_steps=2000,
                           rng=1, warn=False)
    for j in range(3):
        d = run.flat_draws[:, list(run.names).index(f"rest_{j + 1}")]
        lo, hi = np.percentile(d, [0.5, 99.5])
        assert lo < 0.25 < hi and 1.0 - hi > hi - lo


def test_a_run_configuration_names_it(tmp_path):
    from bayesmodal.runs.config import load_config

    (tmp_path / "exp.csv").write_text("t,v,x1,x2,x3\n0,0,0,0,0\n", encoding="utf-8")
    p = tmp_path / "run.toml"
    p.write_text('[data]\nfiles=["exp.csv"]\n[likelihood]\nnoise="ar1:motion"\n',
                 encoding="utf-8")
    cfg = load_config(p)
    assert cfg.likelihood.noise == "ar1:motion" and cfg.layout is not None  # several-record path
