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
around the least-squares fit of the extended model (``bayesmodal.fit.fit_lsq`` with
``extension=``) and every half-ensemble is one batched
``Extension.simulate`` call per experiment.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._errors import ConfigError
from ..data import Experiment
from ..fit.lsq import fit_lsq
from ..fit.result import LSQResult
from ..identified import require_identified
from ..model.effects import extension_revisions
from ..model.rigs import rig_to_dict
from ..model.system import LinearModel
from .convergence import ConvergenceWarning, Diagnostics, convergence_diagnostics
from .ensemble import check_backend_folder, run_ensemble
from .likelihood import Likelihood, as_experiments
from .mode import posterior_mode
from .moves import default_moves
from .noise_choice import choose_noise
from .noise_spec import NoiseSpec, parse_noise
from .priors import PriorSet, default_priors
from .record_layout import RecordLayout
from .record_priors import record_priors, records_start
from .spec import LikelihoodSpec, RunDescription, SamplerSpec, with_settings
from .threads import resolve_threads

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


@dataclass(frozen=True, eq=False)
class PosteriorRun:
    """A finished ensemble run.

    Attributes
    ----------
    likelihood : Likelihood
    priors : PriorSet
    lsq : LSQResult or None
        The least-squares fit the walkers started from (of the extended model for a run
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


def sample_posterior(
    experiments: Experiment | Sequence[Experiment],
    model: LinearModel | RunDescription,
    likelihood: LikelihoodSpec | None = None,
    sampler: SamplerSpec | None = None,
    *,
    priors: PriorSet | None = None,
    start: LSQResult | np.ndarray | None = None,
    rng=None,
    backend=None,
    **settings,
) -> PosteriorRun:
    """Sample the posterior of the mechanical and noise parameters with emcee.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    model : LinearModel or RunDescription
        The model sampled, or a whole run description (``bayesmodal.runs.RunConfig``,
        from a run's TOML file, ``load_config``): its rig and damping, its
        ``[likelihood]``, ``[records]``, effects and ``[sampler]`` sections (where
        ``likelihood`` and ``sampler`` are not given), its ``[priors]`` (where
        ``priors`` is not given) and its seed (where ``rng`` is not given).
    likelihood : LikelihoodSpec, optional
        What is modelled: the noise model, an extension, the records' layout, a
        temperature, the initial states (``bayesmodal.inference.spec``; default
        ``LikelihoodSpec()``: AR(1) noise, the linear model, every parameter shared).
    sampler : SamplerSpec, optional
        How it is sampled: walkers, steps, burn-in, thinning, moves, the start method,
        a restart or pruning of stranded walkers, threads, progress, warnings (default
        ``SamplerSpec()``: 32 walkers, 5000 steps).
    priors : PriorSet, optional
        Default ``default_priors(model, noise=..., extension=...)`` (``record_priors``
        with a records layout).
    start : LSQResult or ndarray, optional
        Least-squares estimate to start from (computed with ``fit_lsq``, with
        ``extension=`` for an extension, if omitted).  An array has the model
        parameters only (``Likelihood.mech_names``).  With an extension a fit of the
        linear model (``extension`` None) is taken as the linear start of the extended
        fit.
    rng : numpy.random.Generator or int, optional
        Seeds the start and emcee's generator; same seed, same chain.
    backend : str, path or emcee backend, optional
        ``emcee.backends.HDFBackend`` file for checkpointing.  If it already holds steps of
        this configuration, sampling resumes from the last one (the generator state is
        restored from the file) and only the missing steps are run.
    **settings
        Any field of ``LikelihoodSpec`` or ``SamplerSpec`` by name (``noise="white"``,
        ``n_steps=8000``), replacing the one of ``likelihood`` or ``sampler``; an unknown
        name is a ``TypeError`` listing the names.

    Returns
    -------
    PosteriorRun

    Notes
    -----
    The walkers start around the least-squares estimate with noise parameters from the
    moments of its residuals, refined to the posterior mode (``SamplerSpec.refine``).
    AR(p) and the other noise models of ``bayesmodal.inference.noise`` need a record
    layout of the ``Likelihood`` (one record with every parameter shared is its simplest
    one); ``"ar:auto"`` chooses the orders by BIC on the least-squares residuals.
    ``restart`` re-centres every walker after that many burn-in steps around the best
    one, ``prune`` moves only the walkers stranded far below the others (the chi-square
    tail ``(chi2_P(1 - 1e-6) - median(chi2_P)) / 2``); both are deterministic for an
    integer ``rng`` and survive a resume.  ``init="laplace"`` starts from draws of the
    Laplace approximation at the mode (``bayesmodal.inference.laplace``): about ``2 P^2``
    evaluations, and burn-in of an extended model on several records falls from
    thousands of steps to hundreds.  Threads give the same chain bit for bit.

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
    overrides = {}
    if not isinstance(model, LinearModel):
        model, likelihood, sampler, rng, overrides = _from_description(
            model, likelihood, sampler, rng)
    lik_spec, smp = with_settings(likelihood, sampler, settings)
    exps = as_experiments(experiments)
    lik, noise, layout, start = _likelihood(exps, model, lik_spec, start)
    ext = lik.extension
    if priors is None:
        priors = (record_priors(lik) if layout is not None else default_priors(
            model, noise=noise, extension=ext, initial_states=lik.initial_state_names))
        priors = priors.replace(overrides)
    n_par = priors.n_params
    n_walkers, n_steps = int(smp.n_walkers), int(smp.n_steps)
    if n_walkers < 2 * n_par or n_walkers % 2:
        raise ConfigError(
            f"n_walkers must be even and at least 2 x {n_par} parameters = {2 * n_par}, "
            f"got {n_walkers}"
        )
    burn = smp.burn_steps
    thin = default_thin(n_walkers, n_steps - burn) if smp.thin is None else int(smp.thin)
    threads = resolve_threads(smp.threads)
    check_backend_folder(backend)   # before the least-squares start, not at the first save
    lik, lsq, centre = _start_point(exps, model, lik, priors, lik_spec, start, noise,
                                    layout)
    log_post = LogPosterior(lik, priors, float(lik_spec.temperature))

    gen = np.random.default_rng(rng)
    config = _run_config(model, lik, priors, exps, lik_spec, smp, rng)
    # the hash identifies the target and ensemble; a resumed run may extend n_steps
    chash = config_hash(config)
    ens = run_ensemble(log_post, priors, centre, smp, gen=gen, backend=backend, chash=chash,
                       threads=threads)
    be = ens.backend
    z_chain = be.get_chain()[:n_steps]
    blobs = be.get_blobs()[:n_steps]
    acc = be.accepted / float(be.iteration)
    diag = convergence_diagnostics(z_chain[burn:], acc, priors.names)
    if smp.warn and not diag.converged:
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
        chain=priors.to_physical(z_chain),
        log_prob=be.get_log_prob()[:n_steps],
        log_likelihood=np.asarray(blobs, dtype=float),
        acceptance=np.asarray(acc, dtype=float),
        burn=burn,
        thin=thin,
        diagnostics=diag,
        elapsed_s=ens.elapsed_s,
        n_evaluations=ens.n_evaluations,
        config=config,
    )


def _from_description(run, likelihood, sampler, rng):
    """The model, sections, seed and prior overrides of a run description (the
    sections and seed given to ``sample_posterior`` win)."""
    if not isinstance(run, RunDescription):
        raise TypeError(f"model must be a LinearModel or a run description (RunConfig, "
                        f"bayesmodal.runs.load_config), got {type(run).__name__}")
    return (run.make_model(),
            run.likelihood_spec() if likelihood is None else likelihood,
            run.sampler_spec() if sampler is None else sampler,
            run.seed if rng is None else rng,
            run.prior_overrides())


def _likelihood(exps, model: LinearModel, spec: LikelihoodSpec, start):
    """The likelihood of a run, its noise name and layout, and the start (an ``"ar:auto"``
    noise needs the least-squares fit, which becomes the start)."""
    noise, layout = spec.noise, spec.layout
    nspec = parse_noise(noise) if isinstance(noise, str | NoiseSpec) else None
    if nspec is None or not nspec.one_record:
        # AR(p) and other noise models live in the several-record likelihood; one record
        # with every parameter shared is its simplest layout
        if layout is None:
            layout = RecordLayout({})
        if nspec is not None and nspec.kind == "ar:auto":
            if start is None and spec.extension is None:
                start = fit_lsq(list(exps), model)
                require_identified(start, exps, "the posterior")
            noise = choose_noise(exps, model, start, extension=spec.extension)
    else:
        noise = nspec.name  # "AR1" or " ar1" take the path of "ar1"
    if layout is None:
        return Likelihood(model, exps, noise, spec.extension,
                          initial_state=spec.initial_state), noise, None, start
    if spec.initial_state != "rest":
        raise ConfigError("estimated initial states (free decays) are built for the "
                          "single-record likelihood; drop the per-record layout")
    # (with a noise scale the records' sizes need the start: built again there)
    return Likelihood(model, exps, noise, spec.extension, layout), noise, layout, start


def _start_point(exps, model: LinearModel, lik, priors: PriorSet, spec: LikelihoodSpec,
                 start, noise, layout):
    """The start: the likelihood (rebuilt when each record's noise level is sized at the
    start), the least-squares result (or None for a given vector) and the centre of the
    walkers, model parameters then noise moments, physical units."""
    ext = lik.extension
    if ext is None:
        if start is None:
            start = fit_lsq(list(exps), model, initial_state=spec.initial_state)
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
        if start is None or (isinstance(start, LSQResult) and start.extension is None):
            start = fit_lsq(list(exps), model.rig, extension=ext, linear=start)
        lsq = start if isinstance(start, LSQResult) else None
        theta_mech = ext.check(model.rig, np.asarray(
            start.theta if lsq is not None else start, dtype=float))
        if lik.layout is None:
            theta_mech = _inside_priors(theta_mech, priors)
    if lik.layout is None:
        return lik, lsq, np.r_[theta_mech, lik.residual_noise_start(theta_mech)]
    if lik.layout.noise_scale != "none":
        # each record's noise level sized by its response at the start, a constant
        lik = Likelihood(model, exps, noise, ext, layout, scale_at=theta_mech)
    return lik, lsq, _inside_priors(records_start(lik, theta_mech), priors)


def _run_config(model, lik, priors, exps, spec: LikelihoodSpec, smp: SamplerSpec,
                rng) -> dict:
    """What identifies a run (its hash names the checkpoint and the run folder).

    Keys at their default are left out where earlier runs did not have them, so that
    the hashes of earlier runs stay valid.
    """
    ext = lik.extension
    revised = {} if ext is None else extension_revisions(ext.name)
    temperature = float(spec.temperature)
    return {
        "damping": model.damping,
        **({} if ext is None else {"extension": ext.name}),
        **({"extension_revisions": revised} if revised else {}),
        "springs_n_m": list(model.rig.springs_n_m),
        **({} if model.rig.is_chain else {"rig": rig_to_dict(model.rig)}),
        **({} if spec.initial_state == "rest" else {"initial_state": spec.initial_state}),
        "noise": lik.noise,
        "priors": [repr(p) for p in priors.priors],
        "transforms": list(priors.transforms),
        "n_walkers": int(smp.n_walkers),
        "data": [e.sha256 or e.name for e in exps],
        "moves": _moves_key(smp.moves),
        # an integer seed is part of the identity of a run; a Generator cannot be recorded
        "seed": int(rng) if isinstance(rng, (int, np.integer)) else None,
        "refine": bool(smp.refine),
        **({} if smp.restart is None else {"restart": smp.restart}),
        **({} if smp.prune is None else {"prune": smp.prune}),
        **({} if lik.layout is None else {"layout": lik.layout.to_dict()}),
        **({} if temperature == 1.0 else {"temperature": temperature}),
        **({} if smp.init == "ball" else {"init": smp.init}),
    }
