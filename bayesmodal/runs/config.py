"""Run configurations: TOML files parsed into a frozen, fully validated dataclass.

A configuration is data only (``tomllib``; nothing is executed or unpickled).  Every
problem in a file is collected and reported at once, each naming the file and the key::

    [data]
    files = ["ecp210-3dof/data_impulses.mat"]   # relative to the config, or to a data root
    m_per_count = 0.0000044125                   # optional, m per encoder count
    heldout = ["ecp210-3dof/data_steps.mat"]     # optional: records scored, not fitted
    columns = { t = "time", v = "target_v", x1 = "enc1", x2 = "enc2" }   # optional: a
                                                 # lab file's own names (CLI --columns)
    input_scale = "5/4096"                       # optional: V per unit of the input
    time_scale = "1/1000"                        # optional: s per unit of the time
    time_base = "grid"                           # optional: auto, stamps or grid (a
                                                 # logger's stamps; CLI --time-base)
    t_start = 2.0                                # optional: a time window, s of the
    t_end = 12.0                                 # record's clock (starting at rest)
    rest_offset = "initial"                      # optional: none, initial or final (CLI
                                                 # --rest-offset); release: only "none"

    [rig]
    springs_n_m = [774.0, 770.0, 396.0]   # a chain; or file = "my_rig.toml" (or a preset
                                          # name), or the tables of a rig description
                                          # inline ([[rig.carts]], [[rig.springs]], ...)

    [model]
    damping = "free"            # or "proportional"
    extensions = []             # names from bayesmodal.model.effects

    [priors]                    # per-parameter overrides: [lo, hi] bounds of a uniform prior
    m1 = [0.5, 3.0]             # or { lo = 0.5, hi = 3.0, scale = "log" }
    sigma_1 = { lo = 1e-7, hi = 1e-3, scale = "log" }   # noise: sigma_i (m), phi_i

    [likelihood]
    noise = "ar1"               # residual model: white, ar1, iar1, arP, ar(p1,...,pn),
                                # ar:auto or process (docs/reference/noise.md)
    temperature = 1.0           # optional: generalised posterior L^(1/T), or "loro":
                                # calibrated by leave-one-record-out coverage
    initial_state = "rest"      # optional: "estimate" samples each record's initial
                                # positions and velocities (decays released by hand)

    [records]                   # optional: several records, one physical system
    per_record = { g_v = "hierarchical", v0 = "hierarchical" }   # or "independent"
    noise_per_record = false    # true: each record its own noise parameters
    noise_scale = "none"        # or "response": each record's noise level sized by the
                                # model's response to its input, or "power": by that
                                # size to a sampled power in [0, 1] (docs/uncertainty.md)

    [crossval]                  # optional: leave-one-record-out check of the run
    enabled = true              # run the check after the posterior run
    draws = 200                 # posterior draws per held-out prediction
    walkers = 32                # walkers per fold (default [sampler] walkers)
    steps = 4000                # sampler steps per fold (default [sampler] steps)

    [sampler]
    walkers = 32                # emcee ensemble size
    steps = 5000                # steps per walker
    burn = 1000                 # steps discarded as burn-in (< steps)
    thin = 5                    # keep every thin-th step after the burn-in
    seed = 1                    # random seed: the same seed gives the same chain
    moves = "de"                # de, stretch, de-snooker, de-jump, walk, kde, "de:0.8,de-jump:0.2"
    restart = 500               # optional: re-centre the walkers on the best one at this
                                # step (< burn), for walkers stuck in a negligible mode
    # prune = 3000              # or: move only the walkers stranded far below the others
    init = "ball"               # or "laplace": walkers drawn from the Gaussian at the
                                # posterior mode (an extended model on several records)
    threads = 1                 # or "auto", or N: each half-ensemble evaluated in blocks
                                # of walkers on N threads; the same chain, faster for an
                                # extended model (not part of the run's identity)

    [outputs]
    dir = "impulses-free"       # relative to the output root; no "..", not absolute
    plots = true                # the run's figures
    report = true               # report.html
    predictive_draws = 200      # posterior draws of the posterior predictive
    ema = true                  # LSCE cross-check (bayesmodal.ema) in the report
    checkpoint_every_s = 5.0    # seconds between atomic checkpoint writes
    pointwise_loglik = true     # false leaves the pointwise log-likelihood out of
                                # posterior.nc (most of its size); LOO rebuilds it
    chain = "compact"           # chain.h5 of a finished run: every k-th step in float32
                                # and the final state in float64; "full" keeps the
                                # float64 checkpoint

    [identify]                  # optional: the whole workflow (bayesmodal identify):
    enabled = true              # this configuration is the linear model's; after its run,
                                # diagnose, then sample the model with the causes found
    null = 19                   # null data sets of the diagnosis' calibration
    max_effects = 4             # most effects the diagnosis puts in the model
    split = "auto"              # or "none": cut the record that moves furthest at rest
    weights = "auto"            # or "none", "spread": weighing of the records' fits
    candidates = ["coulomb_friction", "input_offset"]   # the effects tried (default:
                                # the catalogue's defaults and the driven cart's end stop)
    seed = 0                    # seed of the diagnosis' null simulations
    starts = 3                  # local fits per candidate from its best grid points
    global_search = true        # also differential evolution for stick-slip models
    walkers = 56                # walkers of the found model's posterior
    steps = 12000               # its steps per walker
    burn = 1000                 # its burn-in
    thin = 616                  # its thinning
    prune = 500                 # step at which its stranded walkers are pruned (< burn)
    crossval_steps = 3000       # steps per fold of its leave-one-record-out check
    population = false          # true: every mass per record, drawn from a population
                                # (intervals for the next experiment)

    [evidence]                  # optional nested-sampling evidence (dynesty), slow
    enabled = false             # compute the Bayesian evidence of the model
    nlive = 250                 # live points
    dlogz = 0.5                 # stop when the remaining evidence is below this, in log

Data paths are looked up relative to the config file, then ``$BAYESMODAL_DATA``, then
``../shared/data`` beside the repository.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

from .._errors import ConfigError
from ..inference.moves import MOVE_REVISIONS, move_spec
from ..inference.moves import MOVES as _MOVE_CLASSES
from ..inference.record_scale import NOISE_SCALES
from ..model.effects import EXTENSION_REVISIONS, extension_revisions
from .config_sections import (
    PriorOverride,
    _parse_data,
    _parse_likelihood,
    _parse_model,
    _parse_outputs,
    _parse_priors,
    _parse_sampler,
)
from .description import (
    CrossvalSection,
    DataSection,
    EvidenceSection,
    LikelihoodSection,
    ModelSection,
    OutputsSection,
    RecordsSection,
    RunConfig,
    SamplerSection,
)

__all__ = ["RunConfig", "DataSection", "ModelSection", "RecordsSection",
           "LikelihoodSection", "SamplerSection", "CrossvalSection", "OutputsSection",
           "EvidenceSection", "PriorOverride", "load_config", "parse_config", "MOVES",
           "NOISE_SCALES", "EXTENSION_REVISIONS", "MOVE_REVISIONS", "extension_revisions",
           "move_spec"]

#: Move names of ``[sampler] moves`` (``bayesmodal.inference.moves.MOVES``).
MOVES = tuple(_MOVE_CLASSES)

_SCHEMA: dict[str, dict[str, type | tuple]] = {
    "data": {"files": list, "m_per_count": (int, float), "heldout": list, "columns": dict,
             "input_scale": (int, float, str), "time_scale": (int, float, str),
             "time_base": str, "t_start": (int, float), "t_end": (int, float),
             "rest_offset": str, "release": str},
    "rig": {"springs_n_m": list, "file": str, "name": str, "clamped": list, "carts": list,
            "springs": list, "dampers": dict, "drive": dict, "sensors": list},
    "model": {"damping": str, "extensions": list},
    "priors": {},  # free keys, checked against parameter names later
    "likelihood": {"noise": str, "temperature": (int, float, str), "initial_state": str},
    "records": {"per_record": dict, "noise_per_record": bool, "noise_scale": str},
    "crossval": {"enabled": bool, "draws": int, "walkers": int, "steps": int},
    "sampler": {"walkers": int, "steps": int, "burn": int, "thin": int, "seed": int,
                "moves": str, "restart": int, "prune": int, "init": str,
                "threads": (int, str)},
    "outputs": {"dir": str, "plots": bool, "report": bool, "predictive_draws": int,
                "ema": bool, "checkpoint_every_s": (int, float), "pointwise_loglik": bool,
                "chain": str},
    "evidence": {"enabled": bool, "nlive": int, "dlogz": (int, float)},
    "identify": {"enabled": bool, "null": int, "max_effects": int, "split": str,
                 "weights": str, "seed": int, "candidates": list, "starts": int,
                 "global_search": bool, "walkers": int, "steps": int, "burn": int,
                 "thin": int, "prune": int, "crossval_steps": int, "population": bool},
}



def _type_name(t) -> str:
    if isinstance(t, tuple):
        return " or ".join(x.__name__ for x in t)
    return t.__name__


def parse_config(raw: dict, *, source: str = "<config>", base: Path | None = None,
                 name: str = "run", check_files: bool = True) -> RunConfig:
    """Validate a parsed TOML mapping; raise one ConfigError listing every problem.

    Parameters
    ----------
    raw : dict
        The parsed TOML document.
    source : str
        File name used in messages.
    base : Path, optional
        Folder that relative data paths start from (the config's folder).
    name : str
        Run name (the config file stem).
    check_files : bool
        Check that every data file exists.
    """
    errors: list[str] = []
    base = base or Path.cwd()

    def err(key: str, msg: str) -> None:
        errors.append(f"{source}: [{key}] {msg}")

    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: not a TOML table")
    for section in raw:
        if section not in _SCHEMA:
            err(section, f"unknown section; expected one of {sorted(_SCHEMA)}")
    values: dict = {}
    for section, keys in _SCHEMA.items():
        table = raw.get(section, {})
        if not isinstance(table, dict):
            err(section, "must be a table")
            continue
        if section == "priors":
            continue
        for key, val in table.items():
            if key not in keys:
                err(f"{section}.{key}", f"unknown key; expected one of {sorted(keys)}")
                continue
            want = keys[key]
            ok = isinstance(val, want) and not (want is int and isinstance(val, bool))
            if want == (int, float) and isinstance(val, bool):
                ok = False
            if not ok:
                err(f"{section}.{key}", f"must be {_type_name(want)}, got {val!r}")
                continue
            values[(section, key)] = val

    kw: dict = {"name": name, "source": source}
    files, mpc = _parse_data(values, kw, err, base, check_files)
    _parse_model(raw, values, kw, err, base, mpc)
    _parse_likelihood(raw, values, kw, err, files)
    _parse_sampler(values, kw, err)
    _parse_outputs(values, kw, err)
    _parse_priors(raw, kw, err)

    if errors:
        raise ConfigError(f"{len(errors)} problem(s) in the configuration:\n" + "\n".join(errors))
    return RunConfig.from_flat(kw)


def load_config(path: str | os.PathLike, *, check_files: bool = True) -> RunConfig:
    """Read and validate a TOML run configuration.

    Parameters
    ----------
    path : str or path
        The TOML file; data paths in it are relative to its folder.
    check_files : bool
        Check that every data file exists.

    Returns
    -------
    RunConfig
        Named after the file's stem.

    Raises
    ------
    ConfigError
        Listing every problem found, each with the file and the key.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such configuration file")
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from exc
    return parse_config(raw, source=str(path), base=path.parent, name=path.stem,
                        check_files=check_files)


