"""What a posterior run models and how it samples: two frozen sections with their defaults.

:func:`~bayesmodal.inference.sampling.sample_posterior` takes the records, the model and
these two objects::

    from bayesmodal.inference import LikelihoodSpec, SamplerSpec, sample_posterior

    run = sample_posterior(records, model, LikelihoodSpec(noise="ar4"),
                           SamplerSpec(n_walkers=48, n_steps=8000), rng=1)

A setting may also be given by its name (``sample_posterior(records, model, noise="ar4",
n_steps=8000)``): :func:`with_settings` puts each name into the section that owns it,
so the defaults live here only and an unknown name is a one-line error.  The run
configuration (``[likelihood]``, ``[sampler]`` of a run's TOML) builds the same objects.

Each section checks what it can check alone when it is built (a burn-in inside the
chain, a known start method); the checks that need the model (walkers against the
number of parameters) happen in ``sample_posterior``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Protocol, runtime_checkable

import numpy as np

from .._errors import ConfigError

__all__ = ["LikelihoodSpec", "SamplerSpec", "RunDescription", "with_settings",
           "put_settings", "burn_in_steps", "INIT_METHODS", "INITIAL_STATES"]

#: How the walkers start (``SamplerSpec.init``).
INIT_METHODS = ("ball", "laplace")
#: What the records' initial states are (``LikelihoodSpec.initial_state``).
INITIAL_STATES = ("rest", "estimate")


@dataclass(frozen=True)
class LikelihoodSpec:
    """What is modelled: the noise, the model's extension, the records' layout.

    Attributes
    ----------
    noise : str, NoiseSpec or NoiseModel
        Residual model: ``"ar1"``, ``"white"``, ``"arP"``, ``"ar(p1,...,pn)"``,
        ``"ar:auto"``, ``"iar1"``, ``"ar1:motion"``, ``"process"``
        (``bayesmodal.inference.noise_spec.parse_noise``) or a built model.
    extension : str, Extension or None
        A model extension on top of the linear model (a name of
        ``bayesmodal.model.effects.EXTENSIONS`` or an instance); None is the linear model.
    layout : RecordLayout or None
        Several records, one system: which parameters are per record
        (``bayesmodal.inference.records``); None shares every parameter.
    temperature : float
        Sample ``p(theta) L(theta)^(1/T)``; 1 is Bayes' rule, ``T > 1`` widens the
        posterior of a misspecified model.
    initial_state : {"rest", "estimate"}
        ``"estimate"`` samples each record's initial positions and velocities (free
        decays).
    """

    noise: object = "ar1"
    extension: object = None
    layout: object = None
    temperature: float = 1.0
    initial_state: str = "rest"

    def __post_init__(self) -> None:
        if not float(self.temperature) > 0:
            raise ConfigError(f"temperature must be > 0, got {self.temperature}")
        if self.initial_state not in INITIAL_STATES:
            raise ConfigError(f"initial_state must be one of {INITIAL_STATES}, "
                              f"got {self.initial_state!r}")


@dataclass(frozen=True)
class SamplerSpec:
    """How the posterior is sampled (emcee's ensemble and the start).

    Attributes
    ----------
    n_walkers : int
        Ensemble size; at least twice the number of parameters, and even.
    n_steps : int
        Steps per walker, burn-in included.
    burn : int or None
        Steps discarded at the start (None: ``n_steps // 5``).
    thin : int or None
        Keep every ``thin``-th step after burn-in (None: about 1000 retained draws).
    moves : emcee move, list of (move, weight), or None
        None: differential evolution alone (``inference.moves.default_moves``).
    init : {"ball", "laplace"}
        A small ball around the start, or draws of the Laplace approximation there.
    init_scale : float
        Width of the ball in sampling coordinates.
    refine : bool
        Move the start to the posterior mode first.
    restart, prune : int or None
        Re-centre every walker, or move only the stranded ones, after that many steps of
        burn-in (at most one of the two; smaller than ``burn``).
    threads : int or "auto"
        Threads that evaluate each half-ensemble (the chain is the same with any number).
    progress : bool
        Show progress on stderr.
    warn : bool
        Warn (``ConvergenceWarning``) when the convergence checks fail.
    """

    n_walkers: int = 32
    n_steps: int = 5000
    burn: int | None = None
    thin: int | None = None
    moves: object = None
    init: str = "ball"
    init_scale: float = 1e-4
    refine: bool = True
    restart: int | None = None
    prune: int | None = None
    threads: int | str = 1
    progress: bool = False
    warn: bool = True

    def __post_init__(self) -> None:
        n_steps = int(self.n_steps)
        if n_steps < 2:
            raise ConfigError(f"n_steps must be >= 2, got {self.n_steps}")
        if self.burn is not None and not 0 <= int(self.burn) < n_steps:
            raise ConfigError(f"burn must be in [0, n_steps) = [0, {n_steps}), "
                              f"got {self.burn}")
        if self.thin is not None and int(self.thin) < 1:
            raise ConfigError(f"thin must be >= 1, got {self.thin}")
        if self.init not in INIT_METHODS:
            raise ConfigError(f"init must be 'ball' or 'laplace', got {self.init!r}")
        restart, prune = burn_in_steps(self.restart, self.prune, self.burn_steps)
        object.__setattr__(self, "restart", restart)   # as integers, checked once
        object.__setattr__(self, "prune", prune)

    @property
    def burn_steps(self) -> int:
        """The burn-in in steps, the default resolved."""
        return int(self.n_steps) // 5 if self.burn is None else int(self.burn)


@runtime_checkable
class RunDescription(Protocol):
    """What a run description gives the functions that run it (``sample_posterior``,
    ``crossval``, ``diagnose``).

    ``bayesmodal.runs.RunConfig`` (built from a run's TOML file or from a command's flags)
    is the one implementation; the functions read it through these methods, so the layers
    below the runs do not import the TOML layer.
    """

    def make_model(self):
        """The ``LinearModel`` of the rig and damping."""

    def likelihood_spec(self) -> LikelihoodSpec:
        """The ``[likelihood]``, ``[records]`` and effects as a ``LikelihoodSpec``."""

    def sampler_spec(self) -> SamplerSpec:
        """The ``[sampler]`` section as a ``SamplerSpec``."""

    def prior_overrides(self) -> dict:
        """Per-parameter priors replacing the defaults, name -> ``Prior``."""

    def crossval_spec(self):
        """The leave-one-record-out study (``bayesmodal.inference.crossval.CrossvalSpec``)."""

    def diagnose_spec(self, n_train: int = 1):
        """What ``diagnose`` reads (``bayesmodal.discrepancy.diagnosis.DiagnoseSpec``)."""

    def make_rig(self):
        """The ``Rig``."""

    @property
    def seed(self) -> int:
        """The sampler's seed."""

    @property
    def diagnosis_seed(self) -> int:
        """The diagnosis' seed (null data sets)."""


def burn_in_steps(restart, prune, burn: int) -> tuple[int | None, int | None]:
    """``restart`` and ``prune`` checked as steps of a burn-in of ``burn`` steps.

    Parameters
    ----------
    restart, prune : int or None
        Burn-in step of a restart of every walker, or of the pruning of stranded ones; at
        most one of them given.
    burn : int
        Burn-in steps.

    Returns
    -------
    tuple of (int or None, int or None)
        The two, as integers.

    Raises
    ------
    ConfigError
        Both given, or a step outside ``[1, burn)``.
    """
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



def put_settings(sections: tuple, settings: dict, who: str) -> tuple:
    """Each frozen section with the ``settings`` that name one of its fields.

    Parameters
    ----------
    sections : tuple of dataclass instances
        Sections whose field names do not overlap.
    settings : dict
        Setting name -> value; each name a field of one section.
    who : str
        The entry point, for the message.

    Returns
    -------
    tuple
        The sections, in order, each rebuilt (and so checked again) where a setting
        replaced one of its fields.

    Raises
    ------
    TypeError
        For a name no section has, listing the names.
    """
    names = [{f.name for f in fields(s)} for s in sections]
    known = set().union(*names)
    unknown = sorted(set(settings) - known)
    if unknown:
        raise TypeError(f"{who} got unknown setting(s) {unknown}; the settings are "
                        f"{sorted(known)}")
    out = []
    for section, own in zip(sections, names, strict=True):
        mine = {k: v for k, v in settings.items() if k in own}
        out.append(replace(section, **mine) if mine else section)
    return tuple(out)


def with_settings(likelihood: LikelihoodSpec | None, sampler: SamplerSpec | None,
                  settings: dict) -> tuple[LikelihoodSpec, SamplerSpec]:
    """The two sections with ``settings`` (setting name -> value) put into their owners.

    Parameters
    ----------
    likelihood, sampler : LikelihoodSpec, SamplerSpec or None
        None: the defaults.
    settings : dict
        Names of fields of either section.

    Returns
    -------
    tuple of (LikelihoodSpec, SamplerSpec)

    Raises
    ------
    TypeError
        For a name neither section has, listing the names.

    Examples
    --------
    >>> lik, smp = with_settings(None, None, {"noise": "white", "n_steps": 60})
    >>> lik.noise, smp.n_steps, smp.n_walkers
    ('white', 60, 32)
    """
    return put_settings((LikelihoodSpec() if likelihood is None else likelihood,
                         SamplerSpec() if sampler is None else sampler),
                        settings, "sample_posterior")
