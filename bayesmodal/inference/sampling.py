"""Posterior sampling with emcee's affine-invariant ensemble, vectorised over walkers.

The target is the posterior density of the transformed coordinates ``z`` (see
``priors``): ``log p(z | y) = log L(f(z)) + log p(f(z)) + log |f'(z)| + const``.  All walkers
of a half-ensemble are evaluated in one batched simulator call (``vectorize=True``).  The
walkers start in a small ball around the least-squares optimum (noise parameters from the
moments of its residuals).

Reproducibility: the start ball is drawn from ``numpy.random.default_rng(rng)`` and
emcee's own ``RandomState`` (used by the moves) is seeded from the same generator and
handed over in the initial ``emcee.State``, so one seed gives one chain, bit for bit.
emcee's HDF backend stores the generator state after every step; a run resumed from the
backend therefore continues exactly as the uninterrupted run would have.

Model extensions (``extension="coulomb_friction"`` etc.) sample the free-damping
parameters, the extension's parameters and the noise parameters jointly; the walkers start
around ``bayesmodal.fit.fit_extension_lsq`` and every half-ensemble is one batched
``Extension.simulate`` call per experiment.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import emcee
import numpy as np

from .._errors import ConfigError
from .._progress import progress_bar
from ..data import Experiment
from ..fit.effects import ExtensionFit, fit_extension_lsq
from ..fit.linear import LSQResult, fit_lsq
from ..identified import require_identified
from ..model.effects import extension_revisions
from ..model.rigs import rig_to_dict
from ..model.system import LinearModel
from .idata import arviz
from .laplace import laplace_approximation
from .likelihood import Likelihood, as_experiments
from .mode import posterior_mode
from .moves import default_moves
from .noise_spec import NoiseSpec, parse_noise
from .priors import PriorSet, default_priors
from .records import RecordLayout, RecordsLikelihood, choose_noise, record_priors, records_start
from .stragglers import prune_stragglers
from .threads import ThreadedLogPosterior, resolve_threads

__all__ = [
    "ConvergenceWarning",
    "Diagnostics",
    "LogPosterior",
    "PosteriorRun",
    "convergence_diagnostics",
    "sample_posterior",
    "default_thin",
    "default_moves",
    "posterior_mode",
]

#: Target number of retained draws (all walkers) when ``thin`` is not given.
TARGET_DRAWS = 1000


class ConvergenceWarning(UserWarning):
    """The MCMC run does not pass the convergence checks."""


@dataclass(frozen=True, eq=False)
class LogPosterior:
    """Log posterior density of the sampling coordinates, batched.

    Calling it with ``z`` of shape (nb, P) returns an array of shape (nb, 2): the log
    posterior (up to a constant) and the log-likelihood (stored by emcee as a blob).  The
    likelihood is evaluated only where the prior is positive, so impossible parameters are
    never simulated.
    """

    likelihood: Likelihood
    priors: PriorSet
    temperature: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.temperature) and self.temperature > 0):
            raise ConfigError(f"temperature must be finite and > 0, got {self.temperature}")
        if self.priors.names != self.likelihood.names:
            raise ConfigError(
                f"prior names {self.priors.names} do not match likelihood names "
                f"{self.likelihood.names}"
            )

    def __call__(self, z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(np.asarray(z, dtype=float))
        theta = self.priors.to_physical(z)
        lp = self.priors.log_prior_z(z, theta)
        ll = np.full(z.shape[0], -np.inf)
        ok = np.isfinite(lp)
        if np.any(ok):
            th = theta[ok]
            ll[ok] = self.likelihood(th)
            population = getattr(self.likelihood, "log_population", None)
            if population is not None:  # hierarchical per-record parameters
                lp[ok] = lp[ok] + population(th)
        # a generalised (tempered) posterior weighs the likelihood by 1 / temperature
        post = np.where(np.isfinite(ll) & np.isfinite(lp), lp + ll / self.temperature, -np.inf)
        return np.column_stack([post, ll])


@dataclass(frozen=True)
class Diagnostics:
    """Convergence diagnostics of an ensemble run (post burn-in).

    Attributes
    ----------
    tau : ndarray, shape (P,)
        Integrated autocorrelation time per parameter, steps.
    n_over_tau : float
        Post-burn-in steps divided by the largest tau (want > 50).
    acceptance : float
        Mean acceptance fraction over walkers.
    rhat : ndarray, shape (P,)
        Rank-normalised split R-hat (ArviZ), walkers as chains.
    ess_bulk : ndarray, shape (P,)
        Bulk effective sample size (ArviZ) of the post-burn-in draws.
    max_rhat, min_ess : float
    converged : bool
    problems : tuple of str
        Human-readable reasons when not converged.
    """

    tau: np.ndarray
    n_over_tau: float
    acceptance: float
    rhat: np.ndarray
    ess_bulk: np.ndarray
    max_rhat: float
    min_ess: float
    converged: bool
    problems: tuple[str, ...] = ()


def convergence_diagnostics(
    chain: np.ndarray,
    acceptance: np.ndarray,
    names: Sequence[str],
    *,
    min_n_over_tau: float = 50.0,
    max_rhat: float = 1.05,
    min_ess: float = 100.0,
    acceptance_range: tuple[float, float] = (0.1, 0.8),
) -> Diagnostics:
    """Autocorrelation time, acceptance, R-hat and ESS of a post-burn-in ensemble chain.

    Parameters
    ----------
    chain : ndarray, shape (n_steps, n_walkers, P)
        Post-burn-in chain (unthinned).
    acceptance : ndarray, shape (n_walkers,)
    names : sequence of str, length P
    min_n_over_tau, max_rhat, min_ess, acceptance_range
        Thresholds.  R-hat uses walkers as chains; walkers of an ensemble are not
        independent, so the threshold is looser than the 1.01 used for independent chains.

    Returns
    -------
    Diagnostics
    """

    az = arviz()
    n_steps = chain.shape[0]
    # tol=0: always return the estimate; the length check is ours (below), not emcee's log
    # a parameter that no walker has moved yet (a very short run) has a zero
    # autocovariance: its tau is NaN, counted as not converged below, not an error
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = emcee.autocorr.integrated_time(chain, tol=0) if n_steps > 1 else np.full(
            chain.shape[-1], np.inf)
    tau = np.asarray(tau, dtype=float)
    tau = np.where(np.isnan(tau), np.inf, tau)
    tau_max = float(np.nanmax(tau)) if tau.size else np.inf
    n_over = n_steps / tau_max if tau_max > 0 else np.inf
    import xarray as xr

    # (chain, draw) as ArviZ wants; built directly, because convert_to_dataset warns for
    # short runs with more walkers than steps
    ds = xr.Dataset({nm: (("chain", "draw"), chain[:, :, i].T) for i, nm in enumerate(names)})
    rh = az.rhat(ds)
    es = az.ess(ds, method="bulk")
    rhat = np.array([float(rh[nm]) for nm in names])
    ess = np.array([float(es[nm]) for nm in names])
    acc = float(np.mean(acceptance))
    problems = []
    if not n_over > min_n_over_tau:
        problems.append(f"chain is {n_over:.1f} autocorrelation times long (want > "
                        f"{min_n_over_tau:g}; max tau {tau_max:.0f} steps)")
    # (too few kept steps leave R-hat and ESS undefined for every parameter: NaN)
    rmax = float(np.nanmax(rhat)) if np.any(~np.isnan(rhat)) else np.nan
    emin = float(np.nanmin(ess)) if np.any(~np.isnan(ess)) else np.nan
    if np.isnan(rmax) or np.isnan(emin):
        problems.append(f"R-hat and bulk ESS undefined on a chain of {n_steps} kept steps "
                        "(run more steps after the burn-in)")
    else:
        if not rmax < max_rhat:
            worst = names[int(np.nanargmax(rhat))]
            problems.append(f"max R-hat {rmax:.3f} ({worst}) >= {max_rhat}")
        if not emin > min_ess:
            worst = names[int(np.nanargmin(ess))]
            problems.append(f"min bulk ESS {emin:.0f} ({worst}) <= {min_ess:g}")
    lo, hi = acceptance_range
    if not lo < acc < hi:
        problems.append(f"mean acceptance {acc:.2f} outside ({lo}, {hi})")
    return Diagnostics(
        tau=tau,
        n_over_tau=float(n_over),
        acceptance=acc,
        rhat=rhat,
        ess_bulk=ess,
        max_rhat=rmax,
        min_ess=emin,
        converged=not problems,
        problems=tuple(problems),
    )


@dataclass(frozen=True, eq=False)
class PosteriorRun:
    """A finished ensemble run.

    Attributes
    ----------
    likelihood : Likelihood
    priors : PriorSet
    lsq : LSQResult, ExtensionFit or None
        The least-squares fit the walkers started from (an ``ExtensionFit`` for a run
        with a model extension; its ``theta`` has the extension's parameters too).
    start : ndarray, shape (P,)
        Centre of the start ball, physical units.
    chain : ndarray, shape (n_steps, n_walkers, P)
        Every step of every walker, physical units (``priors.names`` order).
    log_prob : ndarray, shape (n_steps, n_walkers)
        Log posterior of the sampling coordinates (up to a constant).
    log_likelihood : ndarray, shape (n_steps, n_walkers)
    acceptance : ndarray, shape (n_walkers,)
    burn, thin : int
        Steps discarded at the start; keep every ``thin``-th step after that.
    diagnostics : Diagnostics
    elapsed_s : float
        Wall time of the sampling in this call (excluding LSQ), s.
    n_evaluations : int
        Likelihood evaluations in this call (parameter sets).
    config : dict
        Settings that define the run (hashed into ``config_hash``).
    """

    likelihood: Likelihood
    priors: PriorSet
    lsq: object
    start: np.ndarray
    chain: np.ndarray
    log_prob: np.ndarray
    log_likelihood: np.ndarray
    acceptance: np.ndarray
    burn: int
    thin: int
    diagnostics: Diagnostics
    elapsed_s: float
    n_evaluations: int
    config: dict = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return self.priors.names

    @property
    def extension_name(self) -> str | None:
        """Name of the model extension sampled, or None for the linear model."""
        return self.likelihood.extension_name

    @property
    def draws(self) -> np.ndarray:
        """Retained draws, shape (n_walkers, n_draws, P) (chain, draw, parameter)."""
        return np.swapaxes(self.chain[self.burn :: self.thin], 0, 1)

    @property
    def flat_draws(self) -> np.ndarray:
        """Retained draws flattened over walkers, shape (n_walkers * n_draws, P)."""
        d = self.draws
        return d.reshape(-1, d.shape[-1])

    @property
    def retained_log_likelihood(self) -> np.ndarray:
        """Total log-likelihood of the retained draws, shape (n_walkers, n_draws)."""
        return self.log_likelihood[self.burn :: self.thin].T

    @property
    def retained_log_prob(self) -> np.ndarray:
        return self.log_prob[self.burn :: self.thin].T

    @property
    def evaluations_per_s(self) -> float:
        return self.n_evaluations / self.elapsed_s if self.elapsed_s > 0 else math.nan

    @property
    def ess_per_s(self) -> float:
        """Smallest bulk ESS over parameters per second of sampling."""
        return self.diagnostics.min_ess / self.elapsed_s if self.elapsed_s > 0 else math.nan

    @property
    def config_hash(self) -> str:
        return config_hash(self.config)


def _moves_key(moves) -> str:
    """A description of the moves without memory addresses (for the config hash)."""
    if moves is None:
        return "default"
    items = moves if isinstance(moves, (list, tuple)) else [moves]
    parts = []
    for it in items:
        mv, w = it if isinstance(it, tuple) else (it, 1.0)
        attrs = {k: v for k, v in vars(mv).items() if isinstance(v, (int, float, str, bool))}
        parts.append(f"{type(mv).__name__}{sorted(attrs.items())}@{w}")
    return ";".join(parts)


def config_hash(config: dict) -> str:
    """Short SHA-256 of a JSON-serialisable configuration."""
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def default_thin(n_walkers: int, n_kept_steps: int, target: int = TARGET_DRAWS) -> int:
    """Thinning that keeps about ``target`` draws over all walkers."""
    return max(1, math.ceil(n_walkers * max(n_kept_steps, 1) / target))


def _inside_priors(theta_mech: np.ndarray, priors: PriorSet) -> np.ndarray:
    """Model parameters moved into their prior support where they are outside it.

    An extension's least-squares estimate may sit outside its prior (e.g. "no saturation",
    ``v_sat = inf``); the start ball needs a point of positive prior density.  Values are
    moved to 1e-3 of the prior width inside the violated bound.
    """
    out = np.array(theta_mech, dtype=float)
    for i in range(out.size):
        lo, hi = priors.priors[i].support
        margin = 1e-3 * (hi - lo) if np.isfinite(hi - lo) else 0.0
        if out[i] > hi:
            out[i] = hi - margin
        elif out[i] < lo:
            out[i] = lo + margin
    return out


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


def sample_posterior(
    experiments: Experiment | Sequence[Experiment],
    model: LinearModel,
    *,
    noise: str = "ar1",
    priors: PriorSet | None = None,
    n_walkers: int = 32,
    n_steps: int = 5000,
    burn: int | None = None,
    thin: int | None = None,
    moves=None,
    rng=None,
    backend=None,
    progress: bool = False,
    start: LSQResult | np.ndarray | None = None,
    init_scale: float = 1e-4,
    refine: bool = True,
    warn: bool = True,
    extension=None,
    restart: int | None = None,
    prune: int | None = None,
    layout=None,
    temperature: float = 1.0,
    initial_state: str = "rest",
    init: str = "ball",
    threads: int | str = 1,
) -> PosteriorRun:
    """Sample the posterior of the mechanical and noise parameters with emcee.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    model : LinearModel
    noise : {"ar1", "white"}, "arP", "ar(p1,...,pn)", "ar:auto" or a NoiseModel
        Residual model (see ``likelihood``; AR(p) and other models of
        ``bayesmodal.inference.noise`` go through ``records.RecordsLikelihood``, with
        ``"ar:auto"`` choosing the orders by BIC on the least-squares residuals).
    priors : PriorSet, optional
        Default ``default_priors(model, noise=noise, extension=extension)``.
    n_walkers : int
        Ensemble size; at least ``2 P`` and even.
    n_steps : int
        Total steps per walker (including burn-in and steps already in ``backend``).
    burn : int, optional
        Steps discarded at the start (default ``n_steps // 5``).
    thin : int, optional
        Keep every ``thin``-th step after burn-in (default: about 1000 retained draws).
    moves : emcee move or list of (move, weight), optional
        Passed to ``emcee.EnsembleSampler``; default ``default_moves()`` (differential
        evolution 0.8, snooker 0.2), which decorrelates these strongly correlated posteriors
        two to four times faster per step than the stretch move.
    rng : numpy.random.Generator or int, optional
        Seeds the start ball and emcee's generator; same seed, same chain.
    backend : str, path or emcee backend, optional
        ``emcee.backends.HDFBackend`` file for checkpointing.  If it already holds steps of
        this configuration, sampling resumes from the last one (the generator state is
        restored from the file) and only the missing steps are run.
    progress : bool
        Show progress on stderr (a tqdm bar on a terminal, plain lines every 10 %
        otherwise; see ``bayesmodal._progress``).
    start : LSQResult, ExtensionFit or ndarray, optional
        Least-squares estimate to start from (computed with ``fit_lsq``, or with
        ``fit_extension_lsq`` for an extension, if omitted).  An array has the model
        parameters only (``Likelihood.mech_names``).  With an extension an ``LSQResult``
        is taken as the linear start of ``fit_extension_lsq``.
    refine : bool
        Move the centre of the start ball from the least-squares estimate (with noise
        parameters from its residuals) to the posterior mode first (``posterior_mode``).
        The two differ when the noise model is not white; refining shortens burn-in.
    init_scale : float
        Standard deviation of the start ball in sampling coordinates (log units for
        positive parameters; for linear-scale parameters it is scaled by
        ``max(|theta|, 1e-3 * prior width)``).
    warn : bool
        Emit a ``ConvergenceWarning`` when the checks fail.
    extension : str or Extension, optional
        Sample a model extension (a name in ``bayesmodal.model.effects.EXTENSIONS`` or an
        instance) on top of ``model``, which must have free damping.  Parameter names are
        ``extension.names(model.rig)`` followed by the noise names.
    restart : int, optional
        Re-centre the ensemble once, after ``restart`` steps of burn-in: every walker is
        placed in a new start ball around the walker with the highest log posterior at
        that step (refined to the posterior mode when ``refine``), and sampling goes on
        from there.  This is the remedy of the emcee documentation for walkers stuck in
        a separated mode of negligible mass (the static friction levels of
        ``coulomb_friction`` on the measured impulses have one about 55 nats below the
        best).  Must be smaller than ``burn``, so that the retained draws all come after
        the restart and have had ``burn - restart`` steps to spread out again.  The
        restart is deterministic for an integer ``rng`` and survives a resume from
        ``backend``.
    prune : int, optional
        After ``prune`` steps of burn-in, move only the walkers stranded far below the
        others (log posterior below the median by more than the chi-square tail
        ``(chi2_P(1 - 1e-6) - median(chi2_P)) / 2``) onto randomly chosen other walkers
        (``bayesmodal.inference.stragglers``); the rest of the ensemble goes on as it is.
        The gentler alternative to ``restart`` (which re-centres every walker) for a
        posterior with local modes far below the best, as the LuGre model on the four
        measured records.  Must be smaller than ``burn``; give ``restart`` or ``prune``,
        not both.  Deterministic for an integer ``rng`` and survives a resume from
        ``backend``.
    layout : RecordLayout, optional
        Several records, one physical system (``bayesmodal.inference.records``): the
        parameters named in ``layout.per_record`` get one value per record, independent
        or drawn from a sampled population; the others are shared.  The likelihood is a
        ``RecordsLikelihood`` and the default priors ``record_priors``.  The walkers start
        from the joint least-squares fit with per-record gains and offsets solved in
        closed form (``records_start``).  None (default): every parameter is shared.
    temperature : float
        Sample the generalised posterior ``p(theta) L(theta)^(1/T)``: ``T > 1`` widens
        the posterior of a misspecified model (calibrated by leave-one-record-out
        coverage, ``bayesmodal.inference.crossval``); 1 (default) is Bayes' rule.  The
        stored log-likelihood is the untempered one.
    initial_state : {"rest", "estimate"}
        ``"estimate"`` samples each record's initial positions and velocities too (free
        decays; see ``Likelihood``); they follow the model parameters in the chain.
    init : {"ball", "laplace"}
        How the walkers start.  ``"ball"`` (default): a small ball of width
        ``init_scale`` around the centre (the posterior mode when ``refine``).
        ``"laplace"``: draws of the Laplace approximation ``N(z*, H^-1)`` at the posterior
        mode (``bayesmodal.inference.laplace``), so that the ensemble starts with the
        posterior's width and correlations; it costs about ``2 P^2`` likelihood
        evaluations and shortens the burn-in of an extended model on several records from
        thousands of steps to hundreds (docs/discrepancy.md, "A posterior that
        converges").  The restart (``restart``) uses the same start.
    threads : int or "auto"
        Threads that evaluate each half-ensemble in blocks of walkers
        (``bayesmodal.inference.threads``; ``"auto"``: one per usable core).  The chain is
        the same bit for bit with any number; what pays is an extended model, whose
        likelihood is compiled simulation (LuGre friction on the four measured records:
        1.6-1.9 times faster with 2 threads on 2 cores, the linear model 1.1;
        ``python benchmarks/threads.py``).

    Returns
    -------
    PosteriorRun

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> from bayesmodal.model.simulate import simulate_linear
    >>> model = LinearModel(Rig(), "proportional")
    >>> t = np.arange(600) * 0.005
    >>> v = 3.0 * (t < 0.05)
    >>> y = simulate_linear(model, [6.2, 1.5, 1.4, 1.1, 1.5, 1e-4], v, 0.005)
    >>> y = y + 1e-5 * np.random.default_rng(1).standard_normal(y.shape)
    >>> run = sample_posterior(Experiment(t, v, y), model, noise="white", n_steps=60,
    ...                        rng=1, warn=False)
    >>> run.chain.shape
    (60, 32, 9)
    """
    exps = as_experiments(experiments)
    spec = parse_noise(noise) if isinstance(noise, str | NoiseSpec) else None
    if spec is None or not spec.one_record:
        # AR(p) and other noise models live in the several-record likelihood; one record
        # with every parameter shared is its simplest layout

        if layout is None:
            layout = RecordLayout({})
        if spec is not None and spec.kind == "ar:auto":
            if start is None and extension is None:
                start = fit_lsq(list(exps), model)
                require_identified(start, exps, "the posterior")
            noise = choose_noise(exps, model, start, extension=extension)
    else:
        noise = spec.name  # "AR1" or " ar1" take the path of "ar1"
    if layout is None:
        lik = Likelihood(model, exps, noise, extension, initial_state)
    else:

        if initial_state != "rest":
            raise ConfigError("estimated initial states (free decays) are built for the "
                              "single-record likelihood; drop the per-record layout")
        # (with a noise scale the records' sizes need the start: built again there)
        lik = RecordsLikelihood(model, exps, noise, extension, layout)
    ext = lik.extension
    if priors is None:
        if layout is None:
            priors = default_priors(model, noise=noise, extension=ext,
                                    initial_states=lik.initial_state_names)
        else:

            priors = record_priors(lik)
    log_post = LogPosterior(lik, priors, float(temperature))
    n_par = priors.n_params
    n_walkers = int(n_walkers)
    n_steps = int(n_steps)
    if n_walkers < 2 * n_par or n_walkers % 2:
        raise ConfigError(
            f"n_walkers must be even and at least 2 x {n_par} parameters = {2 * n_par}, "
            f"got {n_walkers}"
        )
    if n_steps < 2:
        raise ConfigError(f"n_steps must be >= 2, got {n_steps}")
    burn = n_steps // 5 if burn is None else int(burn)
    if not 0 <= burn < n_steps:
        raise ConfigError(f"burn must be in [0, n_steps) = [0, {n_steps}), got {burn}")
    thin = default_thin(n_walkers, n_steps - burn) if thin is None else int(thin)
    if thin < 1:
        raise ConfigError(f"thin must be >= 1, got {thin}")
    if init not in ("ball", "laplace"):
        raise ConfigError(f"init must be 'ball' or 'laplace', got {init!r}")
    restart, prune = burn_in_steps(restart, prune, burn)
    threads = resolve_threads(threads)
    if isinstance(backend, (str, Path)) and not Path(backend).parent.is_dir():
        # before the least-squares start and the sampling, not when the first step is saved
        raise ConfigError(f"backend {str(backend)!r}: folder {str(Path(backend).parent)!r} "
                          "does not exist; create it or give a path in an existing folder")

    # start point: LSQ mechanical estimate plus moment estimates of the noise
    if ext is None:
        if start is None:
            start = fit_lsq(list(exps), model, initial_state=initial_state)
            # no posterior around an estimate that is not an answer (a reversed drive, an
            # input that is not the motor command): one line with the cause and the fix
            require_identified(start, exps, "the posterior")
        lsq = start if isinstance(start, LSQResult) else None
        theta_mech = np.asarray(start.theta if lsq is not None else start, dtype=float)
        if lik.initial_state_names and lsq is not None:
            theta_mech = np.r_[model.check(theta_mech), lsq.x0.ravel()]
        elif lik.initial_state_names:
            theta_mech = np.r_[model.check(theta_mech[: model.n_params]),
                               theta_mech[model.n_params :]]
        else:
            theta_mech = model.check(theta_mech)
    else:

        if start is None or isinstance(start, LSQResult):
            start = fit_extension_lsq(list(exps), ext, model.rig, linear=start)
        lsq = start if isinstance(start, ExtensionFit) else None
        theta_mech = np.asarray(start.theta if lsq is not None else start, dtype=float)
        theta_mech = ext.check(model.rig, theta_mech)
        if layout is None:
            theta_mech = _inside_priors(theta_mech, priors)
    if layout is None:
        centre = np.r_[theta_mech, lik.residual_noise_start(theta_mech)]
    else:

        if layout.noise_scale != "none":
            # each record's noise level sized by its response at the start, a constant
            lik = RecordsLikelihood(model, exps, noise, ext, layout, scale_at=theta_mech)
            log_post = LogPosterior(lik, priors, float(temperature))
        centre = _inside_priors(records_start(lik, theta_mech), priors)

    gen = np.random.default_rng(rng)
    # the restart ball's seed comes from a copy of the generator, so that the stream of
    # the start ball (and the first stage) is the one of a run without restart, and a
    # resumed run, which draws no start ball, re-creates it
    split = restart if restart is not None else prune  # the one step between two stages
    restart_seed = None if split is None else np.random.SeedSequence(
        [int(np.random.Generator(copy.deepcopy(gen.bit_generator)).integers(2**63)),
         0x52455354])
    revised = {} if ext is None else extension_revisions(ext.name)
    config = {
        "damping": model.damping,
        **({} if ext is None else {"extension": ext.name}),
        **({"extension_revisions": revised} if revised else {}),
        "springs_n_m": list(model.rig.springs_n_m),
        # (absent for the chain, so that the hashes of earlier runs stay valid)
        **({} if model.rig.is_chain else {"rig": _rig_dict(model.rig)}),
        **({} if initial_state == "rest" else {"initial_state": initial_state}),
        "noise": lik.noise,
        "priors": [repr(p) for p in priors.priors],
        "transforms": list(priors.transforms),
        "n_walkers": n_walkers,
        "data": [e.sha256 or e.name for e in exps],
        "moves": _moves_key(moves),
        # an integer seed is part of the identity of a run; a Generator cannot be recorded
        "seed": int(rng) if isinstance(rng, (int, np.integer)) else None,
        "refine": bool(refine),
        **({} if restart is None else {"restart": restart}),
        **({} if prune is None else {"prune": prune}),
        **({} if layout is None else {"layout": lik.layout.to_dict()}),
        **({} if temperature == 1.0 else {"temperature": float(temperature)}),
        # (absent for the default, so that the hashes of earlier runs stay valid)
        **({} if init == "ball" else {"init": init}),
    }
    # the hash identifies the target and ensemble; a resumed run may extend n_steps
    chash = config_hash(config)
    be, done = _open_backend(backend, n_walkers, n_par, chash)

    if moves is None:
        moves = default_moves()
    # each half-ensemble in blocks of walkers on ``threads`` threads: the same numbers
    with ThreadedLogPosterior(log_post, threads) as run_post:
        sampler = emcee.EnsembleSampler(
            n_walkers, n_par, run_post, vectorize=True, moves=moves, backend=be
        )
        t0 = time.perf_counter()
        n_eval = 0
        # scale of the ball: log units for log/tanh parameters, relative for linear ones
        width = np.array([p.support[1] - p.support[0] for p in priors.priors])
        lin = np.array([t == "identity" for t in priors.transforms])

        def ball(theta, generator):
            if init == "laplace":
                return _laplace_start(run_post, posterior_mode(run_post, theta), n_walkers,
                                      generator)
            c = posterior_mode(run_post, theta) if refine else theta
            scale = np.where(lin, init_scale * np.maximum(np.abs(c), 1e-3 * width), init_scale)
            return _start_ball(priors, c, scale, n_walkers, generator, run_post)

        # the run is split at ``restart`` (if any); ``stop`` is the end of the current stage
        stop = split if split is not None and done <= split else n_steps
        if done == 0:
            z_init = ball(centre, gen)
            mt = np.random.RandomState(np.random.MT19937(np.random.SeedSequence(
                int(gen.integers(2**63)))))
            state = emcee.State(z_init, random_state=mt.get_state())
            be.reset(n_walkers, n_par)
            _set_backend_attr(be, "bayesmodal_config_hash", chash)
            _advance(sampler, state, stop, progress)
            n_eval += n_walkers * (stop + 1)
            done = stop
        elif done < stop:
            _advance(sampler, None, stop - done, progress)
            n_eval += n_walkers * (stop - done)
            done = stop
        if split is not None and done == split:  # (split < burn < n_steps)
            lp_split = be.get_log_prob()[split - 1]
            if restart is not None:
                best = be.get_chain()[split - 1, np.argmax(lp_split)]
                z_init = ball(priors.to_physical(best), np.random.default_rng(restart_seed))
            else:
                z_init = prune_stragglers(be.get_chain()[split - 1], lp_split,
                                          np.random.default_rng(restart_seed)).z
            state = emcee.State(z_init, random_state=be.random_state)
            if restart is not None:
                _advance(sampler, state, n_steps - split, progress)
            else:  # positions from the chain itself: emcee's independence check does not apply
                _advance(sampler, state, n_steps - split, progress, check=False)
            n_eval += n_walkers * (n_steps - split + 1)
        elapsed = time.perf_counter() - t0

    z_chain = be.get_chain()[:n_steps]
    blobs = be.get_blobs()[:n_steps]
    chain = priors.to_physical(z_chain)
    lp = be.get_log_prob()[:n_steps]
    acc = be.accepted / float(be.iteration)

    diag = convergence_diagnostics(z_chain[burn:], acc, priors.names)
    if warn and not diag.converged:
        warnings.warn(
            "MCMC run has not converged: " + "; ".join(diag.problems)
            + ". Run longer (more steps or burn-in) before trusting the intervals.",
            ConvergenceWarning,
            stacklevel=2,
        )
    config.update({"n_steps": n_steps, "burn": burn, "thin": thin, "config_hash": chash})
    return PosteriorRun(
        likelihood=lik,
        priors=priors,
        lsq=lsq,
        start=centre,
        chain=chain,
        log_prob=lp,
        log_likelihood=np.asarray(blobs, dtype=float),
        acceptance=np.asarray(acc, dtype=float),
        burn=burn,
        thin=thin,
        diagnostics=diag,
        elapsed_s=elapsed,
        n_evaluations=n_eval,
        config=config,
    )


def burn_in_steps(restart, prune, burn: int) -> tuple[int | None, int | None]:
    """``restart`` and ``prune`` checked as steps of a burn-in of ``burn`` steps (at most
    one of them given); one-line ``ConfigError`` otherwise."""
    if restart is not None and prune is not None:
        raise ConfigError("give restart or prune, not both: restart re-centres every "
                          "walker, prune moves only the stranded ones")
    return _burn_in_step("restart", restart, burn), _burn_in_step("prune", prune, burn)


def _burn_in_step(name: str, step, burn: int) -> int | None:
    """``step`` checked as a step of the burn-in (``restart``, ``prune``), or None."""
    if step is None:
        return None
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)):
        raise ConfigError(f"{name} must be an integer number of steps, got {step!r}")
    if not 1 <= int(step) < burn:
        raise ConfigError(f"{name} must be in [1, burn) = [1, {burn}) so that every "
                          f"retained draw comes after it, got {step}")
    return int(step)


def _rig_dict(rig) -> dict:

    return rig_to_dict(rig)
