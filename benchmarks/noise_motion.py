"""Does a noise level that follows the carts' speed fit the measured records better?

Samples the four measured ECP 210 records (the layout of ``runs/records_free.toml``: free
damping, g_v per record from a population, one shared input offset, each record's noise
level sized by its response) twice, with ``noise = "ar1"`` and ``noise = "ar1:motion"``,
and prints for each:

- the 90 % posterior-predictive band's coverage of the measured samples, split into the
  samples where the measuring cart moves (speed weight w > 0.1, ``speed_weight`` of
  ``inference/noise/motion.py``) and where it rests, per record and overall;
- the posterior of every rest fraction ``rest_j`` (ar1:motion: the level at rest over the
  level in motion);
- the in-sample PSIS-LOO ELPD difference (``elpd_change``) between the two.

    python benchmarks/noise_motion.py [--steps 4000] [--walkers 48] [--draws 200]

About 10 minutes on one core of a 2-core machine at the defaults.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bayesmodal.data import find_data, load_experiment
from bayesmodal.inference import elpd_change, sample_posterior
from bayesmodal.inference.noise.motion import speed_weight
from bayesmodal.inference.predictive import predict_new_record
from bayesmodal.inference.record_layout import RecordLayout
from bayesmodal.model.system import LinearModel, Rig

FILES = ("data_impulses.mat", "data_steps.mat", "data_sine_sweep_fast.mat",
         "data_sine_sweep_slow.mat")
LAYOUT = RecordLayout({"g_v": "hierarchical", "v0": "shared"}, noise_scale="response")
MOVING = 0.1   # speed weight above which a cart counts as moving


def band_coverage(run, draws: int, rng) -> list[tuple[str, float, float, int, int]]:
    """Per record: (name, coverage moving, coverage resting, n moving, n resting)."""
    lik = run.likelihood
    theta = run.flat_draws[rng.choice(len(run.flat_draws), draws, replace=False)]
    noise = lik.noise_draws(theta, rng)
    rows = []
    for r, e in enumerate(lik.experiments):
        y = lik.predict_record(theta, r) + noise[r]            # (draws, N, n_out)
        lo, hi = np.percentile(y, [5, 95], axis=0)
        moving = speed_weight(e.y_m, e.dt, 0.1) > MOVING
        rows.append((e.name, *split_coverage(e, lo, hi), int(moving.sum()),
                     int((~moving).sum())))
    return rows


def split_coverage(e, lo, hi) -> tuple[float, float]:
    """Coverage of ``e``'s samples by the band [lo, hi], carts moving and resting."""
    inside = (e.y_m >= lo) & (e.y_m <= hi)
    moving = speed_weight(e.y_m, e.dt, 0.1) > MOVING
    return float(inside[moving].mean()), float(inside[~moving].mean())


def heldout(exps, model, name: str, args) -> None:
    """Fit both noise models on the other records, predict ``name`` (never fitted): its
    90 % predictive band's coverage, moving and resting, and its mean log density."""
    test = next(e for e in exps if e.name == name)
    train = [e for e in exps if e.name != name]
    print(f"held out: {name}; trained on {', '.join(e.name for e in train)}")
    for noise in ("ar1", "ar1:motion"):
        run = sample_posterior(train, model, noise=noise, layout=LAYOUT,
                               n_walkers=args.walkers, n_steps=args.steps,
                               thin=max(1, args.steps * args.walkers // (2 * args.draws)),
                               rng=1, warn=False)
        rng = np.random.default_rng(2)
        theta = run.flat_draws[rng.choice(len(run.flat_draws), args.draws, replace=False)]
        _, y_pred, ll = predict_new_record(run.likelihood, theta, test, rng=rng)
        lo, hi = np.percentile(y_pred, [5, 95], axis=0)
        cm, cr = split_coverage(test, lo, hi)
        lpd = float(np.log(np.mean(np.exp(ll - ll.max()))) + ll.max())
        print(f"  {noise:11s} max R-hat {run.diagnostics.max_rhat:.3f}; 90 % band holds "
              f"{cm:6.1%} moving, {cr:6.1%} resting; log predictive density "
              f"{lpd:.0f} nats")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--walkers", type=int, default=48)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--heldout", metavar="RECORD",
                    help="fit on the other records and predict this one (e.g. "
                         "data_sine_sweep_fast) instead of the in-sample comparison")
    args = ap.parse_args(argv)
    exps = [load_experiment(find_data(f"ecp210-3dof/{f}")) for f in FILES]
    model = LinearModel(Rig(), "free")
    if args.heldout:
        heldout(exps, model, args.heldout, args)
        return
    runs = {}
    for noise in ("ar1", "ar1:motion"):
        t0 = time.perf_counter()
        run = sample_posterior(exps, model, noise=noise, layout=LAYOUT,
                               n_walkers=args.walkers, n_steps=args.steps,
                               thin=max(1, args.steps * args.walkers // (2 * args.draws)),
                               rng=1, warn=False)
        runs[noise] = run
        d = run.diagnostics
        print(f"\n{noise}: {time.perf_counter() - t0:.0f} s, max R-hat {d.max_rhat:.3f}, "
              f"min bulk ESS {d.min_ess:.0f}")
        rows = band_coverage(run, args.draws, np.random.default_rng(2))
        mv = sum(c * n for _, c, _, n, _ in rows) / sum(n for *_, n, _ in rows)
        rs = sum(c * n for _, _, c, _, n in rows) / sum(n for *_, n in rows)
        for name, cm, cr, nm, nr in rows:
            print(f"  {name:28s} 90 % band holds {cm:6.1%} moving ({nm} samples), "
                  f"{cr:6.1%} resting ({nr})")
        print(f"  {'all records':28s} 90 % band holds {mv:6.1%} moving, {rs:6.1%} resting")
        for j, nm in enumerate(run.names):
            if nm.startswith("rest"):
                q = np.percentile(run.flat_draws[:, j], [5, 50, 95])
                print(f"  {nm}: {q[1]:.3g} [{q[0]:.3g}, {q[2]:.3g}] (90 % interval)")
    print("\n" + elpd_change(runs["ar1"], runs["ar1:motion"],
                             labels=("ar1", "ar1:motion")).reading)


if __name__ == "__main__":
    main()
