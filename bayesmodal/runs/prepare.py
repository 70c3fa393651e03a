"""Check a run configuration against its data before any sampling.

:func:`prepare_run` loads the records (each from rest, its offset removed where asked),
builds the model of the configuration's rig, its priors with the configuration's
overrides and the moves, and checks the ensemble size; every problem is a
``ConfigError`` naming the configuration key.  :func:`default_out_dir` is the run's
folder under an output root.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from .._errors import ConfigError, DataError
from .._window import motion_at_start, offset_at_rest
from ..data import Experiment, check_identifiable, load_experiment, options_for_rig
from ..fit.lsq import fit_lsq
from ..inference import default_priors
from ..inference.likelihood import Likelihood
from ..inference.noise_choice import choose_noise
from ..inference.noise_spec import parse_noise
from ..inference.record_priors import record_priors
from ..model.effects import get_extension
from ..model.system import LinearModel
from .config import RunConfig

__all__ = ["PreparedRun", "prepare_run", "default_out_dir"]


@dataclass(frozen=True, eq=False)
class PreparedRun:
    """A configuration checked against its data, ready to sample.

    Attributes
    ----------
    config : RunConfig
    experiments : tuple of Experiment
        The fitted records.
    heldout : tuple of Experiment
        Records scored, not fitted.
    model : LinearModel
    priors : bayesmodal.inference.PriorSet
    moves : list of (emcee move, weight)
    extension : str or None
        The model extension sampled with the linear model (``[model] extensions``).
    """

    config: RunConfig
    experiments: tuple[Experiment, ...]
    heldout: tuple[Experiment, ...]
    model: LinearModel
    priors: object
    moves: list
    extension: str | None = None
    noise: str | None = None  # the resolved noise model (``ar:auto`` -> its orders)



def _check_window_rest(e: Experiment) -> None:
    why = motion_at_start(e.y_m, e.v_volt, e.dt)
    if why:
        raise DataError(f"{e.source or e.name}: the window starts at t = {e.t_s[0]:g} s with "
                        f"{why}, not at rest; a run starts every record from rest: set "
                        "t_start where the carts rest at 0 with no input")



def _check_offset(e: Experiment) -> None:
    why = offset_at_rest(e.y_m, e.v_volt)
    if why:
        raise DataError(f"{e.source or e.name}: before the first input the carts rest with "
                        f"{why}, not at 0 where a run starts every record; an encoder not "
                        "zeroed at rest: set rest_offset = \"initial\" in [data]")



def _load(files, cfg: RunConfig, key: str, *, fitted: bool = True) -> tuple[Experiment, ...]:
    out = []
    for f in files:
        try:
            opts = cfg.data.read_options()
            if cfg.model.rig is not None:  # the rig's sensors say what each column holds
                opts = options_for_rig(opts, cfg.make_rig(), f)
            out.append(load_experiment(Path(f), m_per_count=cfg.data.m_per_count, options=opts))
            at_rest = cfg.likelihood.initial_state == "rest"   # else the start is sampled
            if fitted:
                if cfg.data.t_start is not None and at_rest:  # every record from rest
                    _check_window_rest(out[-1])
                if cfg.data.rest_offset == "none" and at_rest:
                    _check_offset(out[-1])
                check_identifiable(out[-1])
        except (DataError, OSError, ValueError) as exc:
            raise ConfigError(f"{cfg.source}: [{key}] {exc}") from exc
    return tuple(out)



def prepare_run(config: RunConfig) -> PreparedRun:
    """Check a configuration against its data before any sampling.

    Raises
    ------
    ConfigError
        Naming the file and the key: unreadable data (``[data.files]``), outputs that do
        not match the rig (``[rig.springs_n_m]``), priors the sampler cannot use
        (``[priors.NAME]``), too few or an odd number of walkers (``[sampler.walkers]``),
        model extensions that cannot be combined (``[model.extensions]``) or an extension
        without free damping (``[model.damping]``).
    """

    cfg = config
    src = cfg.source
    exps = _load(cfg.data.files, cfg, "data.files")
    held = _load(cfg.data.heldout, cfg, "data.heldout", fitted=False)
    try:
        model = LinearModel(cfg.make_rig(), cfg.model.damping)
    except ValueError as exc:
        raise ConfigError(f"{src}: [rig{'' if cfg.model.rig else '.springs_n_m'}] {exc}") from exc
    for e in exps + held:
        if cfg.model.rig is not None and e.n_outputs != model.n_outputs:
            raise ConfigError(
                f"{src}: [rig] the rig has {model.n_outputs} sensors, but "
                f"{e.source or e.name} has {e.n_outputs} measured outputs")
        if cfg.model.rig is None and e.n_outputs != model.n_carts:
            raise ConfigError(
                f"{src}: [rig.springs_n_m] {len(cfg.model.springs_n_m)} springs make "
                f"{model.n_carts} carts, but {e.source or e.name} has {e.n_outputs} measured "
                "outputs")
    extension = None
    if cfg.model.extensions:
        # several effects make one combined model, named "a+b" (extensions.Combined)
        extension = "+".join(cfg.model.extensions)
        try:
            get_extension(extension)
        except ValueError as exc:
            raise ConfigError(f"{src}: [model.extensions] {exc}") from exc
        if cfg.model.damping != "free":
            raise ConfigError(
                f"{src}: [model.damping] the {extension} extension is built on free "
                f"damping, got {cfg.model.damping!r}")
    layout = cfg.layout
    spec = parse_noise(cfg.likelihood.noise)
    noise = spec.name
    if spec.kind == "ar:auto":
        if extension is not None:
            raise ConfigError(f"{src}: [likelihood.noise] 'ar:auto' is built for the linear "
                              "model; give the orders, e.g. 'ar4'")
        noise = choose_noise(exps, model, fit_lsq(list(exps), model)).name
    estimate = cfg.likelihood.initial_state == "estimate"
    if estimate and layout is not None:
        raise ConfigError(f"{src}: [likelihood.initial_state] estimated initial states are "
                          "built for white or AR(1) noise with every parameter shared; drop "
                          "[records] or use noise \"white\" or \"ar1\"")
    if layout is None:
        names = (Likelihood(model, exps, noise, extension, initial_state="estimate")
                 .initial_state_names if estimate else ())
        base = default_priors(model, noise=noise, n_outputs=model.n_carts,
                              extension=extension, initial_states=names)
    else:
        try:
            base = record_priors(Likelihood(model, exps, noise, extension, layout))
        except ValueError as exc:
            raise ConfigError(f"{src}: [records] {exc}") from exc
    for name in cfg.model.priors:
        if name not in base.names:
            raise ConfigError(
                f"{src}: [priors.{name}] the sampler samples {list(base.names)}; "
                "remove this entry")
    try:
        priors = base.replace(cfg.prior_overrides())
    except ConfigError as exc:
        raise ConfigError(f"{src}: [priors] {exc}") from exc
    n_par = priors.n_params
    if cfg.sampler.walkers < 2 * n_par or cfg.sampler.walkers % 2:
        raise ConfigError(
            f"{src}: [sampler.walkers] must be even and at least 2 x {n_par} parameters = "
            f"{2 * n_par} for {cfg.model.damping} damping with {cfg.likelihood.noise} noise, "
            f"got {cfg.sampler.walkers}")
    moves = cfg.sampler_spec().moves
    return PreparedRun(cfg, exps, held, model, priors, moves, extension, noise)



def default_out_dir(config: RunConfig, out_root: str | os.PathLike = "runs") -> Path:
    """``out_root / (outputs.dir or the config name)``, a folder strictly inside the root.

    Raises
    ------
    ConfigError
        When it would not be: ``..``, an absolute path, a configuration named ``...toml``
        (stem ``..``), or a symbolic link inside the root that points out of it.
    """
    from pathlib import PurePosixPath

    root = Path(out_root)
    rel = config.outputs.dir or config.name
    key = "[outputs.dir]" if config.outputs.dir else "(the configuration's name)"
    parts = PurePosixPath(rel.replace("\\", "/"))
    if Path(rel).is_absolute() or parts.is_absolute() or ".." in parts.parts or \
            not rel.strip():
        raise ConfigError(f"{config.source}: {key} {rel!r} must be a relative folder inside "
                          f"the output root {root}")
    out = root / rel
    real_root, real_out = root.resolve(), out.resolve()
    if real_out == real_root or real_root not in real_out.parents:
        raise ConfigError(f"{config.source}: {key} {rel!r} leads to {real_out}, not into "
                          f"the output root {real_root} (a symbolic link?)")
    return out
