"""A noise level per record size (``RecordLayout(noise_scale="response")``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.data import Experiment
from bayesmodal.inference.idata import likelihood_from_idata, to_inference_data
from bayesmodal.inference.predictive import predict_new_record
from bayesmodal.inference.record_layout import RecordLayout
from bayesmodal.inference.records import RecordsLikelihood
from bayesmodal.inference.sampling import sample_posterior
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.config import load_config

EPS = np.finfo(float).eps
MODEL = LinearModel(Rig(), "free")
THETA = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])
DT = 0.005
#: Input amplitudes of the records (V): small, middle, big, as impulses against sweeps.
AMPS = (0.3, 1.0, 3.0)
SCALED = RecordLayout({}, noise_scale="response")


def _inputs(n=800):
    t = np.arange(n) * DT
    return t, [a * np.sin(2 * np.pi * (0.5 + k) * t) * (t < 3.0)
               for k, a in enumerate(AMPS)]


def _rms(inputs):
    """RMS of the true model's response to each input (direct simulation), m."""
    return np.array([np.sqrt(np.mean(simulate_linear(MODEL, THETA, v, DT) ** 2))
                     for v in inputs])


def _records(sigma_rel, seed, n=800, noise_sd=None):
    """Records whose noise sd is ``sigma_rel`` times the response's RMS (or
    ``noise_sd(rms)``, one sd per record from the records' RMS)."""
    rng = np.random.default_rng(seed)
    t, vs = _inputs(n)
    sd = sigma_rel * _rms(vs) if noise_sd is None else noise_sd(_rms(vs))
    out = []
    for k, v in enumerate(vs):
        y = simulate_linear(MODEL, THETA, v, DT)
        out.append(Experiment(t, v, y + sd[k] * rng.standard_normal(y.shape), name=f"r{k}"))
    return out


def _scale_truth(exps):
    """rms of each record's simulated response over their geometric mean (direct)."""
    rms = _rms([e.v_volt for e in exps])
    return rms / np.exp(np.mean(np.log(rms)))


@pytest.mark.parametrize("noise", ["white", "ar1", "ar2"])
def test_a_scaled_level_is_the_plain_likelihood_of_records_divided_by_their_scale(noise):
    """Change of variables: ``y_r / s_r`` under the plain likelihood, plus ``-N n log s_r``.

    The other route divides the input and the positions by ``s_r`` (the linear model is
    linear in its input) and uses the unscaled likelihood: different code, same density.
    """
    exps = _records(0.05, seed=1)
    lik = RecordsLikelihood(MODEL, exps, noise, layout=SCALED, scale_at=THETA)
    s = _scale_truth(exps)
    assert np.allclose(lik.record_scales.scales, s, rtol=0, atol=800 * EPS * s.max())
    divided = [Experiment(e.t_s, e.v_volt / s[r], e.y_m / s[r], name=e.name)
               for r, e in enumerate(exps)]
    plain = RecordsLikelihood(MODEL, divided, noise, layout=RecordLayout({}))
    rng = np.random.default_rng(2)
    n_noise = lik.n_params - THETA.size
    noise_par = {"white": [2e-5] * 3, "ar1": [2e-5] * 3 + [0.5, 0.6, 0.7],
                 "ar2": [2e-5] * 3 + [0.5, -0.1, 0.4, 0.1, 0.2, 0.0]}[noise]
    assert len(noise_par) == n_noise
    theta = np.r_[THETA, noise_par] * (1 + 0.01 * rng.standard_normal((4, lik.n_params)))
    jac = sum(e.n_samples * e.n_outputs * np.log(s[r]) for r, e in enumerate(exps))
    got, want = lik(theta), plain(theta) - jac
    # roundoff of sums of N n terms of size |ll| / (N n)
    tol = lik.n_data * EPS * np.max(np.abs(want))
    assert np.max(np.abs(got - want)) <= tol, (got - want, tol)
    # the pointwise terms sum to the same totals (the other evaluation path)
    pw = sum(np.sum(p, axis=(1, 2)) for p in lik.pointwise(theta))
    assert np.max(np.abs(pw - got)) <= tol


def test_a_new_record_is_sized_from_its_input_and_its_noise_draws_follow():
    exps = _records(0.05, seed=3)
    lik = RecordsLikelihood(MODEL, exps, "ar1", layout=SCALED, scale_at=THETA)
    base = exps[1]
    tripled = Experiment(base.t_s, 3.0 * base.v_volt, 3.0 * base.y_m, name="x3")
    # the model is linear in its input: three times the input, three times the scale
    s1, s3 = lik.scale_of(base), lik.scale_of(tripled)
    assert abs(s1 - lik.scale(1)) <= 800 * EPS * s1
    assert abs(s3 - 3 * s1) <= 800 * EPS * s3
    # predictive draws of the new record: residual sd three times the record's own
    theta = np.tile(np.r_[THETA, [2e-5] * 3, [0.0] * 3], (400, 1))
    rng = np.random.default_rng(4)
    _, yp1, _ = predict_new_record(lik, theta, base, rng=rng)
    _, yp3, _ = predict_new_record(lik, theta, tripled, rng=rng)
    # (sample 0 is the record's known start, no draw: left out)
    sd1 = np.std(yp1[:, 1:] - np.median(yp1[:, 1:], axis=0), axis=0).mean()
    sd3 = np.std(yp3[:, 1:] - np.median(yp3[:, 1:], axis=0), axis=0).mean()
    # Monte Carlo error of an sd from 400 x N x 3 white draws, relative, with margin 5
    se = 5 / np.sqrt(2 * yp1.size)
    assert abs(sd3 / sd1 / 3 - 1) < se, (sd3 / sd1, se)
    assert abs(sd1 / (2e-5 * s1) - 1) < se


def _sigma_sampled(layout, exps, seed):
    run = sample_posterior(exps, MODEL, noise="white", layout=layout, n_walkers=32,
                           n_steps=600, burn=300, rng=seed, warn=False)
    flat = run.flat_draws
    j = [run.names.index(f"sigma_{i}") for i in (1, 2, 3)]
    return run, flat[:, j]


def test_the_scaled_posterior_recovers_a_relative_noise_level_and_a_shared_one_does_not():
    """Known truth: noise sd 2 % of each record's response RMS, record sizes 9 times apart.

    With the scale, ``sigma_j * s_r`` is each record's noise sd: ``sigma_j`` is the level
    of a record of the reference size, 2 % of the geometric-mean RMS, and the posterior
    must cover it.  Negative control: one level in metres for all records settles between
    the smallest and the biggest record's sd and covers neither.
    """
    rel = 0.02
    exps = _records(rel, seed=5)
    rms = _rms([e.v_volt for e in exps])
    ref = np.exp(np.mean(np.log(rms)))
    run, sig = _sigma_sampled(SCALED, exps, seed=6)
    mean, sd = sig.mean(axis=0), sig.std(axis=0)
    # posterior sd of sigma ~ sigma / sqrt(2 N n): 4 posterior sd plus the start's offset
    assert np.all(np.abs(mean - rel * ref) < 4 * sd + 0.01 * rel * ref), (mean, rel * ref, sd)
    _, plain = _sigma_sampled(RecordLayout({}), exps, seed=6)
    pm, psd = plain.mean(axis=0), plain.std(axis=0)
    assert np.all(pm - rel * rms.min() > 4 * psd) and np.all(rel * rms.max() - pm > 4 * psd)
    # the stored run rebuilds the same likelihood (reference size kept), here and on
    # other records
    idata = to_inference_data(run)
    again = likelihood_from_idata(idata)
    th = run.flat_draws[:3]
    assert np.array_equal(again(th), run.likelihood(th))
    other = likelihood_from_idata(idata, exps[:2])
    assert np.allclose(other.record_scales.scales, run.likelihood.record_scales.scales[:2],
                       rtol=1e-12)


def test_bad_uses_name_the_fix(tmp_path):
    exps = _records(0.05, seed=7)
    # names and priors need no reference; evaluating the likelihood does
    named = RecordsLikelihood(MODEL, exps, "ar1", layout=SCALED)
    assert named.names == RecordsLikelihood(MODEL, exps, "ar1", layout=RecordLayout({})).names
    with pytest.raises(ConfigError, match="'response' needs scale_at"):
        named(np.r_[THETA, [2e-5] * 3, [0.5] * 3][None])
    with pytest.raises(ConfigError, match="scale_at must be 9"):
        RecordsLikelihood(MODEL, exps, "ar1", layout=SCALED, scale_at=THETA[:3])
    with pytest.raises(ConfigError, match="process noise has no noise level"):
        RecordsLikelihood(MODEL, exps, "process", layout=RecordLayout(
            {"g_v": "hierarchical"}, noise_scale="response"), scale_at=THETA)
    with pytest.raises(ConfigError, match="noise_scale must be one of"):
        RecordLayout({}, noise_scale="record")
    silent = [Experiment(e.t_s, 0 * e.v_volt, e.y_m, name=e.name) for e in exps]
    with pytest.raises(Exception, match="response to this record's input is zero"):
        RecordsLikelihood(MODEL, silent, "ar1", layout=SCALED, scale_at=THETA)
    # the run configuration: the key, its check, and the layout it gives
    cfg = tmp_path / "r.toml"
    text = '[data]\nfiles = ["a.mat"]\n[records]\nnoise_scale = "{}"\n'
    cfg.write_text(text.format("response"))
    c = load_config(cfg, check_files=False)
    assert c.layout.noise_scale == "response"
    assert c.hash() != replace(c, records=replace(c.records, noise_scale="none")).hash()
    cfg.write_text(text.format("size"))
    with pytest.raises(ConfigError, match="records.noise_scale.*'none', 'response' or 'power'"):
        load_config(cfg, check_files=False)
    assert RecordLayout.from_dict(SCALED.to_dict()) == SCALED
    assert "noise_scale" not in RecordLayout({}).to_dict()  # earlier hashes unchanged


def test_a_run_with_a_scaled_noise_level_goes_end_to_end(tmp_path):
    """``bayesmodal run`` with ``[records] noise_scale = "response"``: sampling, the
    stored run (its scale reference), the report, and the leave-one-record-out check."""
    import json

    from bayesmodal.cli import main
    from bayesmodal.data import save_csv
    from bayesmodal.inference import load_idata

    for e in _records(0.05, seed=8, n=600)[:2]:
        save_csv(e, tmp_path / f"{e.name}.csv")
    cfg = tmp_path / "scaled.toml"
    cfg.write_text('[data]\nfiles = ["r0.csv", "r1.csv"]\n'
                   '[records]\nper_record = { g_v = "hierarchical" }\n'
                   'noise_scale = "response"\n'
                   '[likelihood]\nnoise = "ar1"\n'
                   "[sampler]\nwalkers = 36\nsteps = 40\nburn = 10\nthin = 2\nseed = 3\n"
                   "[crossval]\nenabled = true\ndraws = 10\nsteps = 20\n")
    assert main(["run", str(cfg), "--out-root", str(tmp_path / "out"), "--quiet"]) == 0
    out = tmp_path / "out" / "scaled"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["crossval"]["spec"]["layout"]["noise_scale"] == "response"
    idata = load_idata(out / "posterior.nc")
    stored = json.loads(idata.posterior.attrs["record_scale_at_json"])
    assert len(stored["at"]) == THETA.size and stored["reference_m"] > 0
    # the report's first line names the scaled level (and a plain run's does not)
    from bayesmodal.runs.report import _noise_scale_note

    assert "ar1 noise (level per record size)" in (out / "report.html").read_text()
    assert _noise_scale_note({"run": {"config": {"noise_scale": "none"}}}) == ""
    assert "sampled power" in _noise_scale_note({"run": {"config": {"noise_scale": "power"}}})


POWER = RecordLayout({}, noise_scale="power")


@pytest.mark.parametrize("noise", ["ar1", "ar2"])
def test_a_sampled_power_interpolates_between_one_level_and_the_response_scale(noise):
    """``noise_scale = "power"``: row by row, the level's factor is ``s_r ** a``.  At
    ``a = 0`` the likelihood is the one-level one, at ``a = 1`` the ``"response"`` one, and
    in between the plain likelihood of records divided by ``s_r ** a`` plus
    ``-N n a log s_r`` (rows with different ``a`` in one batch)."""
    exps = _records(0.05, seed=11)
    lik = RecordsLikelihood(MODEL, exps, noise, layout=POWER, scale_at=THETA)
    assert lik.names[-1] == "scale_power"
    from bayesmodal.inference.record_priors import record_priors

    pri = record_priors(lik)
    assert pri.priors[-1].support == (0.0, 1.0)
    one = RecordsLikelihood(MODEL, exps, noise, layout=RecordLayout({}))
    resp = RecordsLikelihood(MODEL, exps, noise, layout=SCALED, scale_at=THETA)
    s = _scale_truth(exps)
    noise_par = {"ar1": [2e-5] * 3 + [0.5, 0.6, 0.7],
                 "ar2": [2e-5] * 3 + [0.5, -0.1, 0.4, 0.1, 0.2, 0.0]}[noise]
    a = np.array([0.0, 0.37, 1.0])
    theta = np.c_[np.tile(np.r_[THETA, noise_par], (3, 1)), a]
    got = lik(theta)
    tol = lik.n_data * EPS * np.max(np.abs(got))
    assert abs(got[0] - one(theta[:1, :-1])[0]) <= tol
    assert abs(got[2] - resp(theta[2:, :-1])[0]) <= tol
    divided = [Experiment(e.t_s, e.v_volt / s[r] ** a[1], e.y_m / s[r] ** a[1], name=e.name)
               for r, e in enumerate(exps)]
    plain = RecordsLikelihood(MODEL, divided, noise, layout=RecordLayout({}))
    jac = sum(e.n_samples * e.n_outputs * a[1] * np.log(s[r]) for r, e in enumerate(exps))
    assert abs(got[1] - (plain(theta[1:2, :-1])[0] - jac)) <= tol
    pw = sum(np.sum(p, axis=(1, 2)) for p in lik.pointwise(theta))
    assert np.max(np.abs(pw - got)) <= tol
    # a new record's factor is its size to each row's power
    new = exps[2]
    assert np.allclose(lik.scale_of(new, theta), lik.scale(2) ** a, rtol=1e-12)


def test_the_power_is_recovered_and_its_ends_are_excluded():
    """Known truth: noise sd proportional to the square root of each record's size
    (``a = 0.5``).  The posterior of ``scale_power`` covers 0.5 within 4 posterior sd and
    excludes both ends, one level (0) and a level proportional to the size (1)."""
    recs = _records(None, seed=12, noise_sd=lambda rms: 1e-4 * np.sqrt(
        rms / np.exp(np.mean(np.log(rms)))))
    run = sample_posterior(recs, MODEL, noise="white", layout=POWER, n_walkers=32,
                           n_steps=600, burn=300, rng=13, warn=False)
    a = run.flat_draws[:, run.names.index("scale_power")]
    m, sd = a.mean(), a.std()
    assert abs(m - 0.5) < 4 * sd, (m, sd)
    assert m - 4 * sd > 0.0 and m + 4 * sd < 1.0
