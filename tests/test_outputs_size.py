"""Run outputs sized for batches: compressed NetCDF and checkpoint, float32 terms that lose
nothing that matters, and the pointwise log-likelihood left out and rebuilt exactly."""

from __future__ import annotations

import emcee
import h5py
import numpy as np
import pytest

from bayesmodal.data import Experiment
from bayesmodal.inference import (
    information_criteria,
    load_idata,
    sample_posterior,
    save_idata,
    simulate_noise,
    to_inference_data,
)
from bayesmodal.inference.idata import predictive_quantum, with_pointwise_loglik
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.runs.checkpoint import AtomicCheckpoint

TRUTH = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])
EPS32 = np.finfo(np.float32).eps


@pytest.fixture(scope="module")
def run():
    model = LinearModel(Rig(), "proportional")
    n = 600
    t = np.arange(n) * 0.005
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    e = simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=3)[0]
    y = simulate_linear(model, TRUTH, v, 0.005) + e
    exp = Experiment(t, v, y, name="syn", sha256="0" * 64)
    return sample_posterior(exp, model, noise="ar1", n_walkers=24, n_steps=200, burn=100,
                            rng=5, warn=False)


def test_float32_pointwise_terms_lose_nothing_that_matters(run):
    """The stored float32 terms against the float64 ones: each term within float32
    rounding, and PSIS-LOO ELPD and the per-draw sums within the bound that rounding
    allows (sum over terms of |term| x eps32), far below the ELPD's standard error."""
    idata = to_inference_data(run, n_predictive=0)
    ll32 = idata.log_likelihood["y"].values
    assert ll32.dtype == np.float32
    flat = run.draws.reshape(-1, run.draws.shape[-1])
    ll64 = np.concatenate(run.likelihood.pointwise(flat), axis=1).reshape(ll32.shape)
    assert np.all(np.abs(ll32 - ll64) <= np.abs(ll64) * EPS32)
    # per-draw sums: the rounding bound, and the sampler's own float64 totals
    bound = np.abs(ll64).sum(axis=(2, 3)) * EPS32
    assert np.all(np.abs(ll32.sum(axis=(2, 3), dtype=np.float64)
                         - ll64.sum(axis=(2, 3))) <= bound)
    # PSIS-LOO: each observation's elpd moves by at most its largest term error
    ic32 = information_criteria(idata)
    idata64 = idata.copy()
    idata64.log_likelihood["y"] = (idata.log_likelihood["y"].dims, ll64)
    ic64 = information_criteria(idata64)
    elpd_bound = float((np.abs(ll64).max(axis=(0, 1)) * EPS32).sum())
    assert abs(ic32.elpd_loo - ic64.elpd_loo) <= 2 * elpd_bound
    assert 2 * elpd_bound < 0.01 * ic64.se_loo   # invisible next to its standard error
    assert ic32.n_bad_k == ic64.n_bad_k
    # the posterior itself is not rounded
    assert idata.posterior["m1"].dtype == np.float64
    assert np.array_equal(idata.posterior["m1"].values, run.draws[:, :, 1])


def test_netcdf_is_compressed_losslessly(run, tmp_path):
    idata = to_inference_data(run, n_predictive=16, rng=1)
    p = save_idata(idata, tmp_path / "posterior.nc")
    back = load_idata(p)
    step = predictive_quantum(idata.observed_data["y"].values)
    for g in idata.groups():
        for name, var in idata[g].data_vars.items():
            if g == "posterior_predictive":
                # packed in integer steps: at most half a step (plus the float32 rounding
                # of the value held in memory) from it, and not exactly equal
                x = var.values.astype(float)
                err = np.abs(back[g][name].values - x)
                assert np.all(err <= step / 2 + np.abs(x) * EPS32), (g, name)
                assert np.any(err > 0)
                continue
            assert np.array_equal(back[g][name].values, var.values), (g, name)
    assert np.array_equal(back.observed_data["experiment"].values.astype(str),
                          idata.observed_data["experiment"].values)
    with h5py.File(p, "r") as f:
        d = f["log_likelihood/y"]
        assert d.compression == "gzip" and d.shuffle
        stored, raw = d.id.get_storage_size(), d.size * d.dtype.itemsize
    assert stored < raw
    # the caller's object is not changed by the encoding set for the write
    assert "zlib" not in idata.log_likelihood["y"].encoding


def test_pointwise_left_out_is_rebuilt_bit_for_bit_and_the_file_shrinks(run, tmp_path):
    full = to_inference_data(run, n_predictive=16, rng=1)
    lean = to_inference_data(run, n_predictive=16, rng=1, pointwise=False)
    assert "log_likelihood" not in lean.groups()
    p_full = save_idata(full, tmp_path / "full.nc")
    p_lean = save_idata(lean, tmp_path / "lean.nc")
    with h5py.File(p_full, "r") as f:
        ll_stored = f["log_likelihood/y"].id.get_storage_size()
    # the file shrinks by the compressed group and its coordinates, not more
    saved = p_full.stat().st_size - p_lean.stat().st_size
    assert ll_stored <= saved <= ll_stored + 256 * 1024
    rebuilt = with_pointwise_loglik(load_idata(p_lean))
    assert np.array_equal(rebuilt.log_likelihood["y"].values, full.log_likelihood["y"].values)
    assert with_pointwise_loglik(full) is full
    # negative control: a changed draw changes the rebuilt terms
    other = load_idata(p_lean)
    other.posterior["m1"].values[0, 0] *= 1.01
    changed = with_pointwise_loglik(other).log_likelihood["y"].values
    assert not np.array_equal(changed[0, 0], full.log_likelihood["y"].values[0, 0])


def _unique_rows(chain: np.ndarray) -> int:
    """Walker rows that differ from the same walker's previous step (plus the first)."""
    moved = np.any(chain[1:] != chain[:-1], axis=2)
    return chain.shape[1] + int(moved.sum())


@pytest.mark.parametrize("n_steps", [400, 1600])
def test_checkpoint_size_follows_the_accepted_steps_and_resume_is_exact(n_steps, tmp_path):
    """The final checkpoint is compressed losslessly: its size lies between the bytes of
    the distinct rows (repeated rows of rejected proposals compress away; random
    mantissas do not) and the raw float64 bytes, and it reloads bit for bit."""
    ndim, nw = 6, 16
    p = tmp_path / "chain.h5"
    rng = np.random.default_rng(4)
    cov = np.diag(np.linspace(0.5, 2.0, ndim))

    def logp(x):
        return -0.5 * float(x @ np.linalg.solve(cov, x))

    be = AtomicCheckpoint(p, every_s=1e9)
    s = emcee.EnsembleSampler(nw, ndim, logp, backend=be, moves=emcee.moves.DEMove())
    s._random = np.random.mtrand.RandomState(7)
    s.run_mcmc(rng.normal(size=(nw, ndim)), n_steps)
    chain = be.get_chain()
    raw = chain.nbytes + be.get_log_prob().nbytes
    floor = _unique_rows(chain) * ndim * chain.itemsize
    size = p.stat().st_size
    assert floor < size < raw
    with h5py.File(p, "r") as f:
        assert f["mcmc/chain"].compression == "gzip"
    back = AtomicCheckpoint(p)
    assert np.array_equal(back.get_chain(), chain)
    assert np.array_equal(back.get_log_prob(), be.get_log_prob())
    assert back.random_state[1].tolist() == be.random_state[1].tolist()


def test_outputs_pointwise_loglik_key():
    from bayesmodal._errors import ConfigError
    from bayesmodal.runs.config import parse_config

    base = {"data": {"files": ["a.csv"]}}
    on = parse_config(base, check_files=False)
    off = parse_config({**base, "outputs": {"pointwise_loglik": False}}, check_files=False)
    assert on.outputs.pointwise_loglik is True and off.outputs.pointwise_loglik is False
    assert on.hash() == off.hash()   # storage only: the posterior is the same
    with pytest.raises(ConfigError, match="outputs.pointwise_loglik"):
        parse_config({**base, "outputs": {"pointwise_loglik": "no"}}, check_files=False)


RUN_CONFIG = """\
[data]
files = ["fit.csv"]

[sampler]
walkers = 30
steps = 200
burn = 100
thin = 5
seed = 3

[outputs]
plots = false
report = false
ema = false
predictive_draws = 20
pointwise_loglik = {pointwise}
"""


@pytest.mark.slow
def test_run_without_pointwise_loglik_compares_like_the_full_run(tmp_path):
    """Two runs of one configuration, with and without the stored pointwise terms: the
    same chain (storage is not in the hash), a smaller posterior.nc, and the same PSIS-LOO
    when ``compare_runs`` rebuilds the terms."""
    from bayesmodal.data import save_csv
    from bayesmodal.inference import information_criteria
    from bayesmodal.runs import run_config

    model = LinearModel(Rig(), "free")
    dt, n = 0.005, 600
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])
    y = simulate_linear(model, theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=1)[0]
    save_csv(Experiment(t, v, y, name="fit"), tmp_path / "fit.csv")
    dirs = {}
    for flag in ("true", "false"):
        cfg = tmp_path / f"pw_{flag}.toml"
        cfg.write_text(RUN_CONFIG.format(pointwise=flag))
        dirs[flag] = run_config(cfg, out_root=tmp_path / "out").out_dir
    full, lean = (load_idata(dirs[f] / "posterior.nc") for f in ("true", "false"))
    assert "log_likelihood" in full.groups() and "log_likelihood" not in lean.groups()
    assert np.array_equal(full.posterior["m1"].values, lean.posterior["m1"].values)
    assert (dirs["false"] / "posterior.nc").stat().st_size < \
        (dirs["true"] / "posterior.nc").stat().st_size
    # (compare_runs refuses the same run twice: the criteria are compared directly)
    a, b = information_criteria(full), information_criteria(lean)
    assert a.elpd_loo == b.elpd_loo and a.n_bad_k == b.n_bad_k
    with h5py.File(dirs["false"] / "chain.h5", "r") as f:   # compacted at the end
        assert f["mcmc"].attrs["compact"] and f["mcmc/trace"].compression == "gzip"
