"""A finished run folder sized for batches: the compacted checkpoint keeps every retained
draw (float32, within its rounding of the float64 posterior) and the exact final state (an
emcee continuation from it is the longer run, bit for bit), the posterior predictive holds
the draws asked for, and the plots are palette PNGs."""

from __future__ import annotations

import json

import emcee
import h5py
import matplotlib
import numpy as np
import pytest

from bayesmodal._errors import ConfigError
from bayesmodal.inference.idata import predictive_subset
from bayesmodal.runs.checkpoint import (
    AtomicCheckpoint,
    compact_checkpoint,
    last_state,
    read_trace,
    trace_stride,
)

matplotlib.use("Agg")

EPS32 = np.finfo(np.float32).eps
NDIM, NW = 5, 12
COV = np.diag(np.linspace(0.5, 2.0, NDIM))


def _logp(x):
    return -0.5 * float(x @ np.linalg.solve(COV, x)), float(x.sum())   # (value, blob)


def _sampler(backend):
    s = emcee.EnsembleSampler(NW, NDIM, _logp, backend=backend, moves=emcee.moves.DEMove())
    s._random = np.random.mtrand.RandomState(7)
    return s


def _run(backend, n):
    s = _sampler(backend)
    s.run_mcmc(np.random.default_rng(4).normal(size=(NW, NDIM)), n)
    return s


@pytest.mark.parametrize(("n", "burn", "thin"), [(12000, 3000, 504), (500, 100, 5),
                                                  (2000, 0, 7), (10000, 1001, 5)])
def test_trace_stride_divides_burn_and_thin_and_caps_the_trace(n, burn, thin):
    k = trace_stride(n, burn, thin, max_steps=1000)
    g = np.gcd(burn, thin)
    assert g % k == 0
    steps = np.arange(0, n, k)
    assert set(range(burn, n, thin)) <= set(steps.tolist())   # every retained draw kept
    smaller = [d for d in range(1, k) if g % d == 0]
    if steps.size > 1000:   # only when no divisor of the gcd meets the cap
        assert k == g
    else:   # and it is the finest stride that does
        assert all(-(-n // d) > 1000 for d in smaller)


def test_compacted_checkpoint_keeps_the_draws_and_continues_exactly(tmp_path):
    n, m, burn, thin = 600, 50, 100, 20
    path = tmp_path / "chain.h5"
    be = AtomicCheckpoint(path, every_s=1e9)
    _run(be, n)
    z64 = be.get_chain()
    full_size = path.stat().st_size
    compact_checkpoint(path, burn=burn, thin=thin, max_steps=100)
    tr = read_trace(path)
    assert tr.stride == trace_stride(n, burn, thin, 100) and tr.chain.dtype == np.float32
    # the retained draws are exactly the float32 rounding of the float64 ones
    assert np.array_equal(tr.retained, z64[burn::thin].astype(np.float32))
    assert np.array_equal(tr.chain, z64[:: tr.stride].astype(np.float32))
    # a summary from them moves by at most the largest rounding error (quantiles are
    # monotone in the values); the same summary from a float64 copy does not move at all
    q = [0.05, 0.5, 0.95]
    flat32 = tr.retained.reshape(-1, NDIM).astype(float)
    flat64 = z64[burn::thin].reshape(-1, NDIM)
    bound = np.abs(flat64).max(axis=0) * EPS32 / 2
    change = np.abs(np.quantile(flat32, q, axis=0) - np.quantile(flat64, q, axis=0))
    assert np.all(change <= bound) and np.any(change > 0)
    # continuation: emcee from the stored final state gives the steps of one longer run
    longer = AtomicCheckpoint(tmp_path / "longer.h5", every_s=1e9)
    _run(longer, n + m)
    st = last_state(path)
    cont = emcee.backends.Backend()
    _sampler(cont).run_mcmc(st, m)
    assert np.array_equal(cont.get_chain(), longer.get_chain()[n:])
    assert np.array_equal(cont.get_blobs(), longer.get_blobs()[n:])
    # negative control: another generator state gives another continuation
    other = emcee.State(st.coords, log_prob=st.log_prob, blobs=st.blobs,
                        random_state=np.random.RandomState(8).get_state())
    cont2 = emcee.backends.Backend()
    _sampler(cont2).run_mcmc(other, m)
    assert not np.array_equal(cont2.get_chain(), cont.get_chain())
    # the file shrinks to its float32 trace and final state, plus the HDF5 overhead of
    # the layout (measured on a compacted one-step chain)
    tiny = tmp_path / "tiny.h5"
    _run(AtomicCheckpoint(tiny, every_s=1e9), 1)
    compact_checkpoint(tiny, burn=0, thin=1)
    overhead = tiny.stat().st_size
    payload = tr.chain.nbytes + tr.log_prob.nbytes + 3 * z64[-1].nbytes
    assert path.stat().st_size <= payload + overhead
    assert path.stat().st_size < full_size
    # a compacted file is not a checkpoint to resume; compacting it again is a no-op
    with pytest.raises(ConfigError, match="cannot be resumed"):
        AtomicCheckpoint(path)
    before = path.read_bytes()
    compact_checkpoint(path, burn=burn, thin=thin)
    assert path.read_bytes() == before
    with pytest.raises(ConfigError, match="not a compacted"):
        read_trace(tmp_path / "longer.h5")


@pytest.mark.parametrize("n_chain", [1, 7, 24, 56])
@pytest.mark.parametrize("n_draw", [1, 5, 18])
@pytest.mark.parametrize("n_pred", [1, 20, 48, 200, 10_000])
def test_predictive_subset_never_exceeds_the_draws_asked_for(n_chain, n_draw, n_pred):
    ch, dr = predictive_subset(n_chain, n_draw, n_pred)
    total = ch.size * dr.size
    assert total <= max(n_pred, 1) and total <= n_chain * n_draw
    assert np.all(np.diff(ch) > 0) and np.all(np.diff(dr) > 0)
    assert ch.max() < n_chain and dr.max() < n_draw
    # and not far fewer: below n_chain draws exactly; above, whole draws per chain
    if n_pred <= n_chain:
        assert total == n_pred
    else:
        assert total > min(n_pred, n_chain * n_draw) - n_chain


def test_palette_png_is_exact_for_few_colours_and_smaller_for_many(tmp_path):
    import io

    import matplotlib.pyplot as plt
    from PIL import Image

    from bayesmodal.plots._png import save_png

    # few colours (no anti-aliasing): the palette PNG has the very pixels of matplotlib's
    fig, ax = plt.subplots(figsize=(3, 2))
    for j in range(5):
        ax.plot(np.arange(10), np.arange(10) * j, color=f"C{j}", antialiased=False)
    ax.axis("off")
    ref = io.BytesIO()
    fig.savefig(ref, format="png", dpi=80, bbox_inches="tight")
    save_png(fig, tmp_path / "few.png", dpi=80)
    plt.close(fig)
    with Image.open(tmp_path / "few.png") as a, Image.open(ref) as b:
        assert a.mode == "P"
        assert np.array_equal(np.asarray(a.convert("RGB")), np.asarray(b.convert("RGB")))
    # many colours (translucent anti-aliased walkers, as the trace plot): smaller file
    rng = np.random.default_rng(1)
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.plot(rng.normal(size=(200, 40)).cumsum(axis=0), lw=0.4, alpha=0.5)
    ref = io.BytesIO()
    fig.savefig(ref, format="png", dpi=100, bbox_inches="tight")
    save_png(fig, tmp_path / "many.png", dpi=100)
    plt.close(fig)
    with Image.open(ref) as b:
        assert b.convert("RGB").getcolors(256) is None   # really more than 256 colours
    assert (tmp_path / "many.png").stat().st_size < len(ref.getvalue())


RUN_CONFIG = """\
[data]
files = ["fit.csv"]

[sampler]
walkers = 30
steps = 240
burn = 120
thin = 6
seed = 3

[outputs]
report = true
ema = false
predictive_draws = 16
pointwise_loglik = false
"""


@pytest.mark.slow
def test_small_run_folder_is_compacted_and_reproduces_its_summary(tmp_path):
    """A finished run: chain.h5 compacted (its retained rows are the posterior draws
    within float32 rounding, mapped through the monotone prior transforms), the predictive
    group as large as asked, palette PNGs; and a rerun from the recorded configuration
    reproduces summary.json (the compacted chain is not needed for it)."""
    from PIL import Image

    from bayesmodal.data import Experiment, save_csv
    from bayesmodal.inference import load_idata, posterior_matrix, priors_from_idata
    from bayesmodal.inference.likelihood import simulate_noise
    from bayesmodal.model.simulate import simulate_linear
    from bayesmodal.model.system import LinearModel, Rig
    from bayesmodal.runs import rerun_run, run_config

    model = LinearModel(Rig(), "free")
    dt, n = 0.005, 500
    t = np.arange(n) * dt
    v = np.where((t >= 0.1) & (t < 0.15), 3.0, 0.0)
    theta = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.0, 0.0])
    y = simulate_linear(model, theta, v, dt)
    y = y + simulate_noise(np.full((1, 3), 2e-5), np.full((1, 3), 0.8), n, rng=1)[0]
    save_csv(Experiment(t, v, y, name="fit"), tmp_path / "fit.csv")
    cfg = tmp_path / "small.toml"
    cfg.write_text(RUN_CONFIG)
    out = run_config(cfg, out_root=tmp_path / "out").out_dir
    idata = load_idata(out / "posterior.nc")
    a = idata.posterior.attrs
    names = json.loads(a["parameter_names"])
    post = posterior_matrix(idata, names)                      # (chain, draw, P) float64
    with h5py.File(out / "chain.h5", "r") as f:
        assert f["mcmc"].attrs["compact"] and f["mcmc"].attrs["iteration"] == 240
    tr = read_trace(out / "chain.h5")
    z32 = np.swapaxes(tr.retained, 0, 1).astype(float)         # (chain, draw, P)
    pri = priors_from_idata(idata)
    # z64 lies within half a float32 spacing of z32; the transforms are increasing
    half = np.abs(np.spacing(tr.retained)).astype(float).swapaxes(0, 1) / 2
    lo, hi = pri.to_physical(z32 - half), pri.to_physical(z32 + half)
    slack = 4 * np.finfo(float).eps * np.abs(post)
    assert np.all((lo - slack <= post) & (post <= hi + slack))
    s = json.loads((out / "summary.json").read_text())
    x32 = pri.to_physical(z32).reshape(-1, len(names))
    width = (hi - lo).reshape(-1, len(names)).max(axis=0) + slack.max(axis=(0, 1))
    for j, nm in enumerate(names):
        assert abs(np.median(x32[:, j]) - s["parameters"][nm]["median"]) <= width[j], nm
    st = last_state(out / "chain.h5")
    assert st.coords.dtype == np.float64 and st.coords.shape == (30, len(names))
    pp = idata.posterior_predictive
    assert pp.sizes["chain"] * pp.sizes["draw"] == 16
    # stored as packed 32-bit integers, compressed below their raw size
    with h5py.File(out / "posterior.nc", "r") as f:
        for v in ("y", "y_hat"):
            d = f[f"posterior_predictive/{v}"]
            assert d.dtype == np.int32 and d.id.get_storage_size() < d.size * d.dtype.itemsize
    for p in out.glob("*.png"):
        with Image.open(p) as im:
            assert im.mode == "P", p.name
    # --resume leaves the finished (compacted) run as it is
    assert run_config(cfg, out, resume=True).action == "none"
    res = rerun_run(out, tmp_path / "again")
    assert res.identical, res.differences
