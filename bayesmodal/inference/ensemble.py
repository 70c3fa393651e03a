"""The emcee ensemble of a posterior run: the walkers' start, the checkpoint, the steps.

:func:`run_ensemble` places the walkers (a ball around the start, or draws of the Laplace
approximation at the posterior mode), opens or resumes the checkpoint (an emcee HDF
backend tagged with the run's configuration hash), and advances the ensemble, in two
stages when the burn-in re-centres (``restart``) or prunes stranded walkers (``prune``).

Reproducibility: the start is drawn from the run's generator and emcee's own
``RandomState`` (used by the moves) is seeded from the same generator and handed over in
the initial ``emcee.State``, so one seed gives one chain, bit for bit.  The HDF backend
stores the generator state after every step; a resumed run continues exactly as the
uninterrupted run would have.
"""

from __future__ import annotations

import copy
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import emcee
import numpy as np

from .._errors import ConfigError
from .._progress import progress_bar
from .convergence import ConvergenceWarning
from .laplace import laplace_approximation
from .mode import posterior_mode
from .moves import default_moves
from .priors import PriorSet
from .spec import SamplerSpec
from .stragglers import prune_stragglers
from .threads import ThreadedLogPosterior

if TYPE_CHECKING:  # the target's type only: sampling builds it and calls this module
    from .sampling import LogPosterior

__all__ = ["EnsembleRun", "run_ensemble", "LAPLACE_SHRINK"]


@dataclass(frozen=True, eq=False)
class EnsembleRun:
    """What the ensemble left: the backend holding the chain, wall time, evaluations."""

    backend: object
    elapsed_s: float
    n_evaluations: int


def restart_seed(gen: np.random.Generator, split: int | None):
    """The seed of the second stage's start, from a copy of the run's generator.

    The stream of the start ball (and the first stage) is then the one of a run without
    a second stage, and a resumed run, which draws no start ball, re-creates it.
    """
    if split is None:
        return None
    return np.random.SeedSequence(
        [int(np.random.Generator(copy.deepcopy(gen.bit_generator)).integers(2**63)),
         0x52455354])


def run_ensemble(log_post, priors: PriorSet, centre: np.ndarray, sampler: SamplerSpec, *,
                 gen: np.random.Generator, backend, chash: str, threads: int
                 ) -> EnsembleRun:
    """Advance emcee's ensemble on ``log_post`` from ``centre`` to ``sampler.n_steps``.

    Parameters
    ----------
    log_post : LogPosterior
        The target, in the sampling coordinates of ``priors``.
    priors : PriorSet
    centre : ndarray, shape (P,)
        The start point, physical units.
    sampler : SamplerSpec
        Walkers, steps, moves, start method and width, refinement, the step between the
        two stages (``restart`` or ``prune``), progress.
    gen : numpy.random.Generator
        The run's generator (the start ball, emcee's moves, the second stage's seed).
    backend : str, path, emcee backend or None
        Checkpoint; resumed when it holds steps of this configuration.
    chash : str
        The run's configuration hash, stored in and checked against the checkpoint.
    threads : int
        Threads evaluating each half-ensemble.

    Returns
    -------
    EnsembleRun
    """
    n_par, n_steps = priors.n_params, int(sampler.n_steps)
    n_walkers, restart, prune = int(sampler.n_walkers), sampler.restart, sampler.prune
    split = restart if restart is not None else prune  # the one step between two stages
    seed2 = restart_seed(gen, split)
    be, done = _open_backend(backend, n_walkers, n_par, chash)
    resumed = done > 0
    moves = default_moves() if sampler.moves is None else sampler.moves
    progress = sampler.progress
    # each half-ensemble in blocks of walkers on ``threads`` threads: the same numbers
    with ThreadedLogPosterior(log_post, threads) as run_post:
        emc = emcee.EnsembleSampler(n_walkers, n_par, run_post, vectorize=True, moves=moves,
                                    backend=be)
        t0 = time.perf_counter()
        n_eval = 0
        # scale of the ball: log units for log/tanh parameters, relative for linear ones
        width = np.array([p.support[1] - p.support[0] for p in priors.priors])
        lin = np.array([t == "identity" for t in priors.transforms])

        def ball(theta, generator):
            if sampler.init == "laplace":
                return _laplace_start(run_post, posterior_mode(run_post, theta), n_walkers,
                                      generator)
            c = posterior_mode(run_post, theta) if sampler.refine else theta
            scale = np.where(lin, sampler.init_scale * np.maximum(np.abs(c), 1e-3 * width),
                             sampler.init_scale)
            return _start_ball(priors, c, scale, n_walkers, generator, run_post)

        # the run is split at ``split`` (if any); ``stop`` is the end of the current stage
        stop = split if split is not None and done <= split else n_steps
        if done == 0:
            z_init = ball(centre, gen)
            mt = np.random.RandomState(np.random.MT19937(np.random.SeedSequence(
                int(gen.integers(2**63)))))
            state = emcee.State(z_init, random_state=mt.get_state())
            be.reset(n_walkers, n_par)
            _set_backend_attr(be, "bayesmodal_config_hash", chash)
            _advance(emc, state, stop, progress)
            n_eval += n_walkers * (stop + 1)
            done = stop
        elif done < stop:
            _advance(emc, None, stop - done, progress)
            n_eval += n_walkers * (stop - done)
            done = stop
        if split is not None and done == split:  # (split < burn < n_steps)
            lp_split = be.get_log_prob()[split - 1]
            if restart is not None:
                best = be.get_chain()[split - 1, np.argmax(lp_split)]
                z_init = ball(priors.to_physical(best), np.random.default_rng(seed2))
            else:
                z_init = prune_stragglers(be.get_chain()[split - 1], lp_split,
                                          np.random.default_rng(seed2)).z
            state = emcee.State(z_init, random_state=be.random_state)
            if restart is not None:
                _advance(emc, state, n_steps - split, progress)
            else:  # positions from the chain itself: emcee's independence check does not apply
                _advance(emc, state, n_steps - split, progress, check=False)
            n_eval += n_walkers * (n_steps - split + 1)
        elapsed = time.perf_counter() - t0
    # a resumed run reports the whole chain's sampling: the earlier parts' time and
    # evaluations are kept in the checkpoint (a finished chain resumed adds nothing)
    if resumed:
        elapsed = (elapsed if n_eval else 0.0) + float(
            _backend_attr(be, "bayesmodal_elapsed_s") or 0.0)
        n_eval += int(_backend_attr(be, "bayesmodal_n_evaluations") or 0)
    _set_backend_attr(be, "bayesmodal_elapsed_s", elapsed)
    _set_backend_attr(be, "bayesmodal_n_evaluations", n_eval)
    return EnsembleRun(be, elapsed, n_eval)


def check_backend_folder(backend) -> None:
    """A checkpoint path's folder exists (checked before the start's least squares)."""
    if isinstance(backend, (str, Path)) and not Path(backend).parent.is_dir():
        raise ConfigError(f"backend {str(backend)!r}: folder {str(Path(backend).parent)!r} "
                          "does not exist; create it or give a path in an existing folder")


def _start_ball(priors: PriorSet, centre: np.ndarray, scale: np.ndarray, n_walkers: int,
                rng: np.random.Generator, log_post: LogPosterior) -> np.ndarray:
    """Walkers around ``centre`` (physical) with finite posterior, in z coordinates.

    Identity-transformed parameters at a zero lower bound are pushed inside by taking the
    absolute value of the perturbation.
    """
    z0 = priors.to_sampling(centre)

    def draw():
        z = z0 + scale * rng.standard_normal((n_walkers, priors.n_params))
        for i, tr in enumerate(priors.transforms):
            lo = priors.priors[i].support[0]
            if tr == "identity" and centre[i] - lo < 3 * scale[i]:
                z[:, i] = lo + np.abs(z[:, i] - lo)
        return z

    return _fill_walkers(
        draw, log_post, n_walkers,
        "could not place the walkers: the start point has zero posterior density "
        f"({dict(zip(priors.names, np.round(centre, 6).tolist(), strict=True))}); "
        "check the priors against the least-squares estimate")


def _fill_walkers(draw, log_post: LogPosterior, n_walkers: int, failure: str | None,
                  rounds: int = 100) -> np.ndarray | None:
    """``n_walkers`` start points of finite posterior density, z coordinates.

    ``draw()`` gives ``(n_walkers, n_params)`` candidates; those with zero density are
    dropped and drawn again, up to ``rounds`` rounds, then ``ConfigError(failure)`` (or
    None when ``failure`` is None).
    """
    out = np.empty((n_walkers, log_post.priors.n_params))
    filled = 0
    for _ in range(rounds):
        z = draw()
        good = z[np.isfinite(log_post(z)[:, 0])]
        take = min(len(good), n_walkers - filled)
        out[filled : filled + take] = good[:take]
        filled += take
        if filled == n_walkers:
            return out
    if failure is None:
        return None
    raise ConfigError(failure)


#: Shrink factors of the Laplace start's covariance tried in turn (standard deviations):
#: at a point that is not a mode (a restart mid-burn-in) the measured Hessian can be far
#: too flat in some direction, and every draw at full width lands beyond a prior bound.
LAPLACE_SHRINK = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01)


def _laplace_start(log_post: LogPosterior, mode: np.ndarray, n_walkers: int,
                   rng: np.random.Generator) -> np.ndarray:
    """Walkers drawn from the Laplace approximation at ``mode`` (physical), z coordinates.

    Draws with zero posterior density (beyond a prior bound) are redrawn.
    """

    priors = log_post.priors
    la = laplace_approximation(lambda z: log_post(z)[:, 0], priors.to_sampling(mode))
    for k in LAPLACE_SHRINK:
        z = _fill_walkers(lambda k=k: la.sample(n_walkers, rng, scale=k), log_post,
                          n_walkers, None, rounds=20)
        if z is not None:
            if k < 1.0:
                warnings.warn(
                    f"Laplace start: draws at full width fell outside the priors; the "
                    f"walkers start at {k} times its standard deviations (burn-in spreads "
                    "them out)", ConvergenceWarning, stacklevel=3)
            return z
    raise ConfigError(
        "could not place the walkers: draws of the Laplace approximation at the posterior "
        f"mode fall outside the priors even at {LAPLACE_SHRINK[-1]} times its width; use "
        "init='ball'")


def _open_backend(backend, n_walkers: int, n_params: int, chash: str):
    """An emcee backend and the number of steps it already holds."""
    if backend is None:
        return emcee.backends.Backend(), 0
    if isinstance(backend, (str, Path)):
        backend = emcee.backends.HDFBackend(str(backend), name="mcmc")
    done = 0
    if backend.initialized and backend.iteration > 0:
        if backend.shape != (n_walkers, n_params):
            raise ConfigError(
                f"checkpoint holds {backend.shape[0]} walkers x {backend.shape[1]} parameters, "
                f"this run has {n_walkers} x {n_params}; use a new checkpoint file"
            )
        stored = _backend_attr(backend, "bayesmodal_config_hash")
        if stored is not None and stored != chash:
            raise ConfigError(
                f"checkpoint was written by a different configuration (hash {stored}, "
                f"now {chash}); use a new checkpoint file"
            )
        done = int(backend.iteration)
    return backend, done


def _advance(sampler, state, n_steps: int, progress: bool, check: bool = True) -> None:
    """``sampler.run_mcmc(state, n_steps)`` with the package's progress display.

    The same ``sampler.sample`` iterations as ``run_mcmc`` (identical draws); ``state``
    None continues from the backend's last sample, as ``run_mcmc(None, ...)`` does for a
    sampler opened on a filled backend.  ``check=False`` skips emcee's test that the
    walkers are linearly independent (for positions taken from the chain itself, whose
    strongly correlated posterior can fail emcee's condition-number heuristic).
    """
    if state is None:  # a continuation: the walkers are the chain's own
        state, check = sampler.get_last_sample(), False
    with progress_bar(n_steps, desc="sampling", unit="step", enabled=bool(progress)) as bar:
        for _ in sampler.sample(state, iterations=n_steps,
                                skip_initial_state_check=not check):
            bar.update(1)


def _backend_attr(backend, key):
    if not isinstance(backend, emcee.backends.HDFBackend):
        return getattr(backend, "_bayesmodal_" + key, None)
    with backend.open() as f:
        val = f[backend.name].attrs.get(key)
    return val.decode() if isinstance(val, bytes) else val


def _set_backend_attr(backend, key, value) -> None:
    if not isinstance(backend, emcee.backends.HDFBackend):
        setattr(backend, "_bayesmodal_" + key, value)
        return
    with backend.open("a") as f:
        f[backend.name].attrs[key] = value


