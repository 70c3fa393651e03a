"""Is the posterior as wide as the likelihood says?  Three checks on known truth.

1. ``information``: the likelihood against its generator.  Known-truth records
   (``tests/records_truth.py``, four records, gains and offsets per record, AR(1) noise,
   encoder quantisation); at the truth, the score's covariance over ``--draws`` noise
   draws against the negative Hessian (information-matrix equality).  Printed per
   parameter: the inverse-Hessian standard deviation and the ratio of the sandwich
   variance ``H^-1 J H^-1`` to ``H^-1``, which is 1 for a likelihood that matches how the
   data were made.
2. ``gaussian``: the emcee moves on a correlated 22-dimensional Gaussian, walkers started
   at stationarity: the chain's standard deviations over the target's, per move set
   (differential evolution, stretch, emcee 3.1.6's snooker mixed in, the corrected
   ``SnookerMove`` mixed in), and the autocorrelation times.
3. ``chain``: one known-truth replicate sampled with the package's defaults: chain
   standard deviation over the Laplace (inverse-Hessian) standard deviation at the
   posterior median, per likelihood parameter.

Usage::

    python benchmarks/posterior_width.py            # all three, about 2 min on 2 cores
    python benchmarks/posterior_width.py --only gaussian
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import emcee
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import records_truth as rt  # noqa: E402

from bayesmodal.data import Experiment  # noqa: E402
from bayesmodal.inference import sample_posterior  # noqa: E402
from bayesmodal.inference.laplace import hessian_fd  # noqa: E402
from bayesmodal.inference.moves import SnookerMove  # noqa: E402
from bayesmodal.inference.record_layout import RecordLayout  # noqa: E402
from bayesmodal.inference.records import RecordsLikelihood  # noqa: E402
from bayesmodal.model.system import LinearModel, Rig  # noqa: E402

MODEL = LinearModel(Rig(rt.SPRINGS), "free")
LAYOUT = RecordLayout({"g_v": "hierarchical", "v0": "hierarchical"})


def _steps(theta, idx):
    return np.array([max(abs(theta[i]), 1e-3) * 1e-5 for i in idx])


def _score(lik, theta, idx, h):
    pts = np.repeat(theta[None], 2 * len(idx), axis=0)
    for j, i in enumerate(idx):
        pts[2 * j, i] += h[j]
        pts[2 * j + 1, i] -= h[j]
    ll = lik(pts)
    return (ll[0::2] - ll[1::2]) / (2 * h)


def _curvature(lik, theta, idx, h):
    """Inverse of the negative Hessian of the log-likelihood over ``idx`` at ``theta``."""

    def f(x):
        pts = np.repeat(theta[None], len(x), axis=0)
        pts[:, idx] = x
        return lik(pts)

    H, _ = hessian_fd(f, theta[idx], h)
    return np.linalg.inv(H)


def information(draws: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    n = 2000
    gains = rt.MU_GV * np.exp(rt.TAU_GV * rng.standard_normal(4))
    offsets = rt.V0_SD * rng.standard_normal(4)
    ins = rt.inputs(n)
    clean = [rt.simulate(np.r_[g, rt.PHYSICS], v + o)
             for v, g, o in zip(ins.values(), gains, offsets, strict=True)]

    def records():
        out = []
        for (name, v), y in zip(ins.items(), clean, strict=True):
            out.append(Experiment(np.arange(n) * rt.DT, v, rt.measure(y, rng), name=name))
        return out

    lik = RecordsLikelihood(MODEL, records(), "ar1", layout=LAYOUT)
    names = lik.names
    theta = np.zeros(len(names))
    for nm, val in zip(lik.mech_names[1:], rt.PHYSICS, strict=True):
        theta[names.index(nm)] = val
    for r, key in enumerate(lik.record_keys):
        theta[names.index(f"g_v[{key}]")] = gains[r]
        theta[names.index(f"v0[{key}]")] = offsets[r]
    theta[names.index("mu_g_v")], theta[names.index("tau_g_v")] = rt.MU_GV, rt.TAU_GV
    theta[names.index("tau_v0")] = rt.V0_SD
    for i, nm in enumerate(names):
        theta[i] = {"sigma": rt.SIGMA, "phi": rt.PHI}.get(nm.split("_")[0], theta[i])
    idx = [i for i, nm in enumerate(names) if not nm.startswith(("mu_", "tau_"))]
    h = _steps(theta, idx)
    S = np.array([_score(RecordsLikelihood(MODEL, records(), "ar1", layout=LAYOUT), theta,
                         idx, h) for _ in range(draws)])
    J = S.T @ S / draws
    Hi = _curvature(lik, theta, idx, h)
    sandwich = Hi @ J @ Hi
    print(f"information-matrix equality at the truth, {draws} noise draws")
    print(f"{'parameter':16s} {'sd (curvature)':>15s} {'sandwich / curvature':>21s} "
          f"{'mean score / se':>16s}")
    zmean = S.mean(axis=0) / (S.std(axis=0) / np.sqrt(draws))
    for j, i in enumerate(idx):
        print(f"{names[i]:16s} {np.sqrt(Hi[j, j]):15.3g} {sandwich[j, j] / Hi[j, j]:21.2f} "
              f"{zmean[j]:16.1f}")


def gaussian(steps: int = 5000, ndim: int = 22, walkers: int = 56) -> None:
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.standard_normal((ndim, ndim)))
    cov = q @ np.diag(np.logspace(0, -6, ndim)) @ q.T
    prec = np.linalg.inv(cov)

    def logp(x):
        return -0.5 * np.einsum("ij,jk,ik->i", x, prec, x)

    sets = {"differential evolution": emcee.moves.DEMove(),
            "stretch": emcee.moves.StretchMove(),
            "DE 0.8 + emcee 3.1.6 snooker 0.2": [(emcee.moves.DEMove(), 0.8),
                                                 (emcee.moves.DESnookerMove(), 0.2)],
            "DE 0.8 + SnookerMove 0.2": [(emcee.moves.DEMove(), 0.8), (SnookerMove(), 0.2)]}
    print(f"\nGaussian, {ndim} dimensions, {walkers} walkers x {steps} steps, started at "
          "stationarity: chain sd / target sd")
    for label, moves in sets.items():
        p0 = (np.linalg.cholesky(cov) @ rng.standard_normal((ndim, walkers))).T
        s = emcee.EnsembleSampler(walkers, ndim, logp, moves=moves, vectorize=True)
        s.run_mcmc(emcee.State(p0, random_state=np.random.RandomState(1).get_state()), steps)
        chain = s.get_chain(discard=steps // 5)
        r = chain.reshape(-1, ndim).std(axis=0) / np.sqrt(np.diag(cov))
        tau = emcee.autocorr.integrated_time(chain, quiet=True)
        print(f"{label:34s} median {np.median(r):.3f} [{r.min():.3f}, {r.max():.3f}]  "
              f"tau median {np.median(tau):.0f} steps")


def chain(seed: int = 1, steps: int = 3000, walkers: int = 56) -> None:
    recs, _ = rt.make_replicate(np.random.default_rng(seed), 2000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = sample_posterior(recs, MODEL, noise="ar1", layout=LAYOUT, n_walkers=walkers,
                               n_steps=steps, burn=steps // 2, rng=seed, warn=False)
    d, names = run.flat_draws, run.names
    theta = np.median(d, axis=0)
    idx = [i for i, nm in enumerate(names) if not nm.startswith(("mu_", "tau_"))]
    Hi = _curvature(run.likelihood, theta, idx, _steps(theta, idx))
    sd = d[:, idx].std(axis=0)
    print(f"\nknown-truth replicate {seed}, default moves, {walkers} walkers x {steps} steps "
          f"(R-hat {run.diagnostics.max_rhat:.3f}): chain sd / curvature sd")
    for j, i in enumerate(idx):
        print(f"{names[i]:16s} {sd[j] / np.sqrt(Hi[j, j]):.2f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("information", "gaussian", "chain"))
    ap.add_argument("--draws", type=int, default=1000)
    args = ap.parse_args(argv)
    if args.only in (None, "information"):
        information(args.draws)
    if args.only in (None, "gaussian"):
        gaussian()
    if args.only in (None, "chain"):
        chain()


if __name__ == "__main__":
    main()
