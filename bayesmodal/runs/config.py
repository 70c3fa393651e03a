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

import hashlib
import json
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath

from .._errors import ConfigError, ModelError
from ..data import ECP_M_PER_COUNT, in_data_root
from ..inference.crossval import CrossvalSpec
from ..inference.moves import MOVE_REVISIONS, move_spec
from ..inference.moves import MOVES as _MOVE_CLASSES
from ..inference.noise_spec import NOISE_MODELS, parse_noise
from ..inference.record_scale import NOISE_SCALES
from ..inference.records import RecordLayout
from ..inference.threads import resolve_threads
from ..model.effects import EXTENSION_REVISIONS, EXTENSIONS, extension_revisions
from ..model.rigs import PRESETS, load_rig, rig_from_dict, rig_to_dict
from ..model.system import DAMPING_MODELS, ECP210_SPRINGS_N_M, LinearModel, Rig
from ..reading import REST_OFFSETS, TIME_BASES, ReadOptions, parse_scale

__all__ = ["RunConfig", "load_config", "parse_config", "MOVES", "NOISE_SCALES",
           "EXTENSION_REVISIONS", "MOVE_REVISIONS", "extension_revisions", "move_spec"]

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
    "likelihood": {"noise": str, "temperature": (int, float, str)},
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

#: ``[identify]`` keys of the diagnosis stage (``runs.identify.DiagnosisSpec`` fields).
IDENTIFY_DIAGNOSIS_KEYS = {"null": "n_null", "max_effects": "max_effects", "split": "split",
                           "weights": "weights", "seed": "seed", "candidates": "candidates",
                           "starts": "n_starts", "global_search": "global_search"}
#: ``[identify]`` keys of the found model's sampler (``runs.identify.FinalSpec`` fields).
IDENTIFY_FINAL_KEYS = ("walkers", "steps", "burn", "thin", "prune", "crossval_steps",
                       "population")


@dataclass(frozen=True)
class PriorOverride:
    """Uniform prior bounds for one parameter; ``scale="log"`` for log-uniform."""

    lo: float
    hi: float
    scale: str = "linear"


@dataclass(frozen=True)
class RunConfig:
    """A validated run configuration.  See the module docstring for the file format."""

    name: str
    source: str
    data_files: tuple[str, ...]
    m_per_count: float = ECP_M_PER_COUNT
    springs_n_m: tuple[float, ...] = ECP210_SPRINGS_N_M
    damping: str = "free"
    extensions: tuple[str, ...] = ()
    priors: dict[str, PriorOverride] = field(default_factory=dict)
    noise: str = "ar1"
    walkers: int = 32
    steps: int = 5000
    burn: int = 1000
    thin: int = 5
    seed: int = 1
    moves: str = "de"
    restart: int | None = None
    prune: int | None = None
    init: str = "ball"
    threads: int = 1  # execution only: the chain is the same with any number
    out_dir: str = ""
    plots: bool = True
    report: bool = True
    predictive_draws: int = 200
    heldout_files: tuple[str, ...] = ()
    ema: bool = True
    checkpoint_every_s: float = 5.0
    pointwise_loglik: bool = True
    chain_storage: str = "compact"
    evidence: bool = False
    evidence_nlive: int = 250
    evidence_dlogz: float = 0.5
    rig: dict | None = None
    per_record: dict[str, str] = field(default_factory=dict)
    noise_per_record: bool = False
    noise_scale: str = "none"
    temperature: float | str = 1.0  # or "loro" (calibrated, inference.temperature)
    crossval: bool = False
    crossval_draws: int = 200
    crossval_walkers: int | None = None
    crossval_steps: int | None = None
    columns: dict[str, str] | None = None
    input_scale: float = 1.0
    time_scale: float = 1.0
    time_base: str = "auto"
    t_start: float | None = None
    t_end: float | None = None
    rest_offset: str = "none"
    identify: dict | None = None  # the [identify] table (the workflow), None without

    #: Fields left out of the hash at their defaults (configs written before them keep
    #: their hashes).
    _NEW_DEFAULTS = {"per_record": {}, "noise_per_record": False, "noise_scale": "none",
                     "temperature": 1.0,
                     "crossval": False, "crossval_draws": 200, "crossval_walkers": None,
                     "crossval_steps": None, "columns": None, "input_scale": 1.0,
                     "time_scale": 1.0, "time_base": "auto", "init": "ball", "prune": None,
                     "t_start": None, "t_end": None, "rest_offset": "none",
                     "identify": None}

    def read_options(self):
        """The ``ReadOptions`` of ``[data]`` (column map and scales; ``m_per_count`` is
        given to the loader separately, for encoder files)."""

        return ReadOptions(columns=self.columns, input_scale=self.input_scale,
                           time_scale=self.time_scale, time_base=self.time_base,
                           t_start=self.t_start, t_end=self.t_end,
                           rest_offset=self.rest_offset)

    def make_rig(self):
        """The ``Rig``: the description of ``[rig]`` (``rig``), else the chain of springs."""

        if self.rig is None:
            return Rig(self.springs_n_m)
        return rig_from_dict(self.rig, where=f"{self.source}: [rig]")

    @property
    def layout(self):
        """The per-record layout (``RecordLayout``), or None for shared parameters."""

        if not self.per_record and not self.noise_per_record and self.noise_scale == "none":
            # AR(p) noise lives in the several-record likelihood: shared layout
            return None if parse_noise(self.noise).one_record else RecordLayout({})

        return RecordLayout(dict(self.per_record), self.noise_per_record, self.noise_scale)

    def crossval_spec(self):
        """The ``CrossvalSpec`` of this configuration (model, noise, layout, sampler)."""

        return CrossvalSpec(
            damping=self.damping, noise=self.noise,
            extension="+".join(self.extensions) if self.extensions else None,
            layout=self.layout or RecordLayout({}),
            n_walkers=self.crossval_walkers or self.walkers,
            n_steps=self.crossval_steps or self.steps, burn=None if self.crossval_steps
            else self.burn, n_predictive=self.crossval_draws, seed=self.seed,
            temperature=1.0 if self.temperature == "loro" else self.temperature,
            springs_n_m=self.springs_n_m, init=self.init, moves=self.moves,
            prune=self.prune, restart=self.restart,
            rig=None if self.rig is None else self.make_rig())

    def to_dict(self) -> dict:
        d = asdict(self)
        d["priors"] = {k: asdict(v) for k, v in self.priors.items()}
        return d

    def hash(self) -> str:
        """SHA-256 of the canonical JSON of everything that affects the result."""
        d = self.to_dict()
        for k in ("source", "name", "out_dir", "plots", "report", "ema",
                  "checkpoint_every_s", "pointwise_loglik", "chain_storage", "threads"):
            d.pop(k)
        if d["restart"] is None:  # keeps the hashes of configs written before the key
            d.pop("restart")
        for k, default in self._NEW_DEFAULTS.items():
            if d[k] == default:
                d.pop(k)
        if d["rig"] is None:  # likewise for a chain given by springs_n_m
            d.pop("rig")
        # where the data live does not change the result; their content is hashed separately
        d["data_files"] = [Path(f).name for f in self.data_files]
        d["heldout_files"] = [Path(f).name for f in self.heldout_files]
        revised = {m: r for m, r in MOVE_REVISIONS.items() if m in d["moves"]}
        if revised:
            d["move_revisions"] = revised
        ext_revised = extension_revisions(d["extensions"])
        if ext_revised:
            d["extension_revisions"] = ext_revised
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()


def _type_name(t) -> str:
    if isinstance(t, tuple):
        return " or ".join(x.__name__ for x in t)
    return t.__name__


def _resolve_data(path_text: str, base: Path) -> Path | None:
    p = Path(path_text).expanduser()
    candidates = [p] if p.is_absolute() else [base / p]
    candidates += in_data_root(p)
    for c in candidates:
        if c.is_file():
            return c.resolve()
    return None


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
    files = values.get(("data", "files"))
    if files is None:
        err("data.files", "missing: list the data files to fit")
        files = []
    elif not files or not all(isinstance(f, str) for f in files):
        err("data.files", f"must be a non-empty list of paths, got {files!r}")
        files = []
    resolved = []
    for f in files:
        if not isinstance(f, str):
            continue
        p = _resolve_data(f, base)
        if p is None and check_files:
            err("data.files", f"file not found: {f!r} (looked relative to {base} and in the "
                "data root $BAYESMODAL_DATA or ../shared/data)")
        resolved.append(str(p) if p is not None else f)
    kw["data_files"] = tuple(resolved)

    heldout = values.get(("data", "heldout"))
    if heldout is not None:
        if not all(isinstance(f, str) for f in heldout):
            err("data.heldout", f"must be a list of paths, got {heldout!r}")
        else:
            found = []
            for f in heldout:
                p = _resolve_data(f, base)
                if p is None and check_files:
                    err("data.heldout", f"file not found: {f!r} (looked relative to {base} "
                        "and in the data root $BAYESMODAL_DATA or ../shared/data)")
                found.append(str(p) if p is not None else f)
            kw["heldout_files"] = tuple(found)

    mpc = values.get(("data", "m_per_count"))
    if mpc is not None:
        if not (0 < abs(mpc) < 1):  # negative: encoders counting the other way
            err("data.m_per_count", f"must be non-zero and within (-1, 1) m per count "
                f"(negative for encoders counting the other way), got {mpc!r}")
        kw["m_per_count"] = float(mpc)

    cols = values.get(("data", "columns"))
    if cols is not None:
        bad = [k for k, c in cols.items()
               if isinstance(c, bool) or not isinstance(c, (str, int))]
        if bad:
            err(f"data.columns.{bad[0]}", "must be a column name or a 1-based column number, "
                f"got {cols[bad[0]]!r}")
        else:
            try:
                opts = ReadOptions(columns={k: str(c) for k, c in cols.items()})
                kw["columns"] = opts.column_map
            except ConfigError as exc:
                err("data.columns", str(exc))
    for key in ("input_scale", "time_scale"):
        val = values.get(("data", key))
        if val is None:
            continue

        try:
            # the input may be reversed (a negative input_scale); time runs forwards
            kw[key] = parse_scale(str(val), key, signed=key == "input_scale")
        except ConfigError as exc:
            err(f"data.{key}", str(exc))

    time_base = values.get(("data", "time_base"))
    if time_base is not None:
        if time_base not in TIME_BASES:
            err("data.time_base",
                f"must be one of {', '.join(TIME_BASES)}, got {time_base!r}")
        else:
            kw["time_base"] = time_base

    rest_offset = values.get(("data", "rest_offset"))
    if rest_offset is not None:
        if rest_offset not in REST_OFFSETS:
            err("data.rest_offset", f"must be one of {', '.join(REST_OFFSETS)} (subtract "
                "each output's rest level before the first input, or its final rest), got "
                f"{rest_offset!r}")
        else:
            kw["rest_offset"] = rest_offset
    release = values.get(("data", "release"))
    if release == "auto":
        # the cut decay starts displaced, and a run starts every record from rest
        err("data.release", "a hand-released decay needs its initial state estimated, and a "
            "run starts every record from rest; fit it with `bayesmodal lsq` or `bayesmodal "
            "sample` and --release auto --initial-state estimate")
    elif release is not None and release != "none":
        err("data.release", f"must be 'none' in a run (a hand release is fitted with "
            f"`bayesmodal lsq --release auto`), got {release!r}")

    window = {k: values[("data", k)] for k in ("t_start", "t_end") if ("data", k) in values}
    if window:
        try:
            ReadOptions(**window)
            kw.update(window)
        except ConfigError as exc:
            err("data." + next(iter(window)), str(exc))

    springs = values.get(("rig", "springs_n_m"))
    if springs is not None:
        if not springs or not all(isinstance(k, (int, float)) and not isinstance(k, bool)
                                  and k > 0 for k in springs):
            err("rig.springs_n_m", f"must be a non-empty list of positive N/m, got {springs!r}")
        else:
            kw["springs_n_m"] = tuple(float(k) for k in springs)
    _parse_rig(raw.get("rig"), values, kw, base, err)
    if mpc is None and kw.get("rig") is not None:
        # encoder files take the scale of the rig's count sensors, as on the command line
        scales = {float(s["m_per_unit"]) for s in kw["rig"].get("sensors", [])
                  if s.get("unit") == "count" and s.get("m_per_unit") is not None}
        if len(scales) == 1:
            kw["m_per_count"] = scales.pop()

    # a rig description may declare its damping ([dampers] proportional = true/false)
    prop = ((kw.get("rig") or {}).get("dampers") or {}).get("proportional")
    declared = None if prop is None else ("proportional" if prop else "free")
    given = values.get(("model", "damping"))
    damping = given if given is not None else (declared or "free")
    if damping not in DAMPING_MODELS:
        err("model.damping", f"must be one of {DAMPING_MODELS}, got {damping!r}")
    elif given is not None and declared is not None and given != declared:
        err("model.damping", f"{given!r} contradicts the rig's [dampers] proportional = "
            f"{str(prop).lower()}; drop one of the two")
    kw["damping"] = damping
    exts = values.get(("model", "extensions"), [])
    try:
        known = tuple(EXTENSIONS)
    except ImportError:
        known = ()
    for e in exts:
        if e not in known:
            err("model.extensions", f"unknown extension {e!r}; known: {list(known)}")
    kw["extensions"] = tuple(str(e) for e in exts)

    temp = values.get(("likelihood", "temperature"))
    if isinstance(temp, str):
        if temp != "loro":
            err("likelihood.temperature", "must be a number > 0 or \"loro\" (calibrated "
                f"by leave-one-record-out coverage), got {temp!r}")
        else:
            kw["temperature"] = temp
    elif temp is not None:
        if not temp > 0:
            err("likelihood.temperature", f"must be > 0, got {temp!r}")
        kw["temperature"] = float(temp)
    per = values.get(("records", "per_record"))
    if per is not None:
        for pname, kind in per.items():
            if kind not in ("independent", "hierarchical", "shared"):
                err(f"records.per_record.{pname}", "must be 'independent', 'hierarchical' or "
                    "'shared', "
                    f"got {kind!r}")
        kw["per_record"] = {str(k): str(v) for k, v in per.items()}
    if ("records", "noise_per_record") in values:
        kw["noise_per_record"] = values[("records", "noise_per_record")]
    if ("records", "noise_scale") in values:
        v = values[("records", "noise_scale")]
        if v not in NOISE_SCALES:
            err("records.noise_scale", f"must be 'none', 'response' or 'power', got {v!r}")
        kw["noise_scale"] = v
    if ("crossval", "enabled") in values:
        kw["crossval"] = values[("crossval", "enabled")]
    for key, lo in (("draws", 2), ("walkers", 4), ("steps", 10)):
        v = values.get(("crossval", key))
        if v is not None:
            if v < lo:
                err(f"crossval.{key}", f"must be >= {lo}, got {v}")
            kw[f"crossval_{key}"] = v
    if kw.get("crossval") and len(files) < 2:
        err("crossval.enabled", "leave-one-record-out needs at least two [data.files]")
    _parse_identify(raw.get("identify"), err, kw)

    noise = values.get(("likelihood", "noise"), "ar1")

    try:
        parse_noise(noise)
    except ConfigError:
        err("likelihood.noise", f"must be one of {NOISE_MODELS}, 'arP' (e.g. 'ar4'), "
            f"'ar(p1,...,pn)', 'ar:auto', 'iar1' or 'process', got {noise!r}")
    kw["noise"] = noise

    for key, lo in (("walkers", 4), ("steps", 1), ("burn", 0), ("thin", 1), ("seed", 0)):
        v = values.get(("sampler", key))
        if v is not None:
            if v < lo:
                err(f"sampler.{key}", f"must be >= {lo}, got {v}")
            kw[key] = v
    if values.get(("sampler", "burn"), 0) >= values.get(("sampler", "steps"), 5000):
        err("sampler.burn", "must be smaller than sampler.steps")
    burn = values.get(("sampler", "burn"), RunConfig.burn)
    for key in ("restart", "prune"):  # steps of the burn-in, one or the other
        step = values.get(("sampler", key))
        if step is None:
            continue
        if key == "prune" and "restart" in kw:
            err("sampler.prune", "give restart or prune, not both: restart re-centres "
                "every walker, prune moves only the stranded ones")
        elif not 1 <= step < burn:
            err(f"sampler.{key}", f"must be in [1, sampler.burn) = [1, {burn}) so that "
                f"every retained draw comes after it, got {step}")
        kw[key] = step
        cv_steps = values.get(("crossval", "steps"))
        if cv_steps is not None and step >= cv_steps // 2:  # the folds burn half their steps
            err("crossval.steps", f"the folds burn in {cv_steps // 2} steps (half of "
                f"crossval.steps), not more than sampler.{key} = {step}; give at least "
                f"{2 * step + 2} steps")
    init = values.get(("sampler", "init"))
    if init is not None:
        if init not in ("ball", "laplace"):
            err("sampler.init", f"must be 'ball' or 'laplace', got {init!r}")
        kw["init"] = init
    threads = values.get(("sampler", "threads"))
    if threads is not None:
        try:
            kw["threads"] = resolve_threads(threads)
        except ConfigError as exc:
            err("sampler.threads", str(exc))
    moves = values.get(("sampler", "moves"))
    if moves is not None:
        for problem in move_spec(moves)[1]:
            err("sampler.moves", problem)
        kw["moves"] = moves

    out = values.get(("outputs", "dir"))
    if out is not None:
        pp = PurePosixPath(out.replace("\\", "/"))
        if pp.is_absolute() or Path(out).is_absolute() or ".." in pp.parts or not out.strip():
            err("outputs.dir", f"must be a relative folder inside the output root, got {out!r}")
        kw["out_dir"] = out
    for key in ("plots", "report", "ema", "pointwise_loglik"):
        if ("outputs", key) in values:
            kw[key] = values[("outputs", key)]
    chain = values.get(("outputs", "chain"))
    if chain is not None:
        if chain not in ("compact", "full"):
            err("outputs.chain", f"must be 'compact' or 'full', got {chain!r}")
        kw["chain_storage"] = chain
    ck = values.get(("outputs", "checkpoint_every_s"))
    if ck is not None:
        if not ck > 0:
            err("outputs.checkpoint_every_s", f"must be > 0 seconds, got {ck!r}")
        kw["checkpoint_every_s"] = float(ck)
    if ("evidence", "enabled") in values:
        kw["evidence"] = values[("evidence", "enabled")]
    nlive = values.get(("evidence", "nlive"))
    if nlive is not None:
        if nlive < 10:
            err("evidence.nlive", f"must be >= 10 live points, got {nlive}")
        kw["evidence_nlive"] = nlive
    dlogz = values.get(("evidence", "dlogz"))
    if dlogz is not None:
        if not dlogz > 0:
            err("evidence.dlogz", f"must be > 0, got {dlogz!r}")
        kw["evidence_dlogz"] = float(dlogz)
    pd = values.get(("outputs", "predictive_draws"))
    if pd is not None:
        if pd < 0:
            err("outputs.predictive_draws", f"must be >= 0, got {pd}")
        kw["predictive_draws"] = pd

    priors: dict[str, PriorOverride] = {}
    ptable = raw.get("priors", {})
    if isinstance(ptable, dict):
        for pname, spec in ptable.items():
            key = f"priors.{pname}"
            lo = hi = None
            scale = "linear"
            if isinstance(spec, list) and len(spec) == 2:
                lo, hi = spec
            elif isinstance(spec, dict):
                extra = set(spec) - {"lo", "hi", "scale"}
                if extra:
                    err(key, f"unknown field(s) {sorted(extra)}; use lo, hi, scale")
                lo, hi, scale = spec.get("lo"), spec.get("hi"), spec.get("scale", "linear")
            else:
                err(key, f"must be [lo, hi] or {{lo, hi, scale}}, got {spec!r}")
                continue
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (lo, hi)):
                err(key, f"lo and hi must be numbers, got {lo!r}, {hi!r}")
                continue
            if not lo < hi:
                err(key, f"impossible prior: lo = {lo} is not below hi = {hi}")
            if scale not in ("linear", "log"):
                err(key, f"scale must be 'linear' or 'log', got {scale!r}")
            if scale == "log" and lo <= 0:
                err(key, f"a log-uniform prior needs lo > 0, got {lo}")
            priors[_noise_alias(pname)] = PriorOverride(float(lo), float(hi), str(scale))
        if not kw.get("per_record") and not kw.get("noise_per_record"):
            # several records rename parameters (g_v[rec], mu_g_v): the runner checks them
            _check_prior_names(priors, kw, err)
    kw["priors"] = priors

    if errors:
        raise ConfigError(f"{len(errors)} problem(s) in the configuration:\n" + "\n".join(errors))
    return RunConfig(**kw)


def _check_prior_names(priors, kw, err) -> None:
    try:
        if kw.get("rig") is not None:
            rig = rig_from_dict(kw["rig"])
        else:
            rig = Rig(kw.get("springs_n_m", ECP210_SPRINGS_N_M))
        model = LinearModel(rig, kw.get("damping", "free"))
    except ValueError:
        return
    n = model.n_outputs
    allowed = set(model.names) | {f"sigma_{i + 1}" for i in range(n)} | {
        f"phi_{i + 1}" for i in range(n)}
    try:
        for e in kw.get("extensions", ()):
            if e in EXTENSIONS:
                allowed |= set(EXTENSIONS[e].names(model.rig))
    except (ImportError, AttributeError):
        pass
    for pname, pr in priors.items():
        if pname not in allowed:
            err(f"priors.{pname}", f"unknown parameter; expected one of {sorted(allowed)}")
        elif (pname.startswith("m") or pname == "g_v") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: {pname} must be positive, lo = {pr.lo}")
        elif pname.startswith("c") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: damping cannot be negative, lo = {pr.lo}")
        elif pname.startswith("sigma_") and pr.lo < 0:
            err(f"priors.{pname}", f"impossible prior: a noise scale cannot be negative, "
                f"lo = {pr.lo}")
        elif pname.startswith("phi_") and not -1 <= pr.lo < pr.hi <= 1:
            err(f"priors.{pname}", f"impossible prior: an AR(1) coefficient lies in [-1, 1], "
                f"got [{pr.lo}, {pr.hi}]")


def _noise_alias(name: str) -> str:
    """``sigma1`` -> ``sigma_1`` and ``phi2`` -> ``phi_2`` (the inference names)."""
    for stem in ("sigma", "phi"):
        rest = name[len(stem):]
        if name.startswith(stem) and rest.isdigit():
            return f"{stem}_{rest}"
    return name


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


def _parse_identify(table, err, kw) -> None:
    """``[identify]``: the workflow's options (types are checked by ``_SCHEMA``)."""
    if not isinstance(table, dict) or not table.get("enabled", False):
        return
    opts = {k: v for k, v in table.items() if k != "enabled"}
    for key, allowed in (("split", ("auto", "none")), ("weights", ("auto", "none", "spread"))):
        if key in opts and opts[key] not in allowed:
            err(f"identify.{key}", f"must be one of {allowed}, got {opts[key]!r}")
    cands = opts.get("candidates")
    if cands is not None:
        unknown = [c for c in cands if c not in EXTENSIONS]
        if unknown or not cands:
            err("identify.candidates", f"unknown effects {unknown}; known: {list(EXTENSIONS)}"
                if unknown else "must name at least one effect")
        opts["candidates"] = tuple(cands)
    for key, lo in (("null", 19), ("max_effects", 1), ("starts", 1), ("walkers", 4),
                    ("steps", 10),
                    ("burn", 0), ("thin", 1), ("prune", 1), ("crossval_steps", 10)):
        if isinstance(opts.get(key), int) and opts[key] < lo:
            err(f"identify.{key}", f"must be >= {lo}, got {opts[key]}"
                + (" (19 null data sets are the fewest a 5 % test allows)" if key == "null"
                   else ""))
    steps, burn = opts.get("steps", 12000), opts.get("burn", 1000)
    if isinstance(steps, int) and isinstance(burn, int) and burn >= steps:
        err("identify.burn", f"must be < identify.steps ({steps}), got {burn}")
    prune = opts.get("prune")
    if isinstance(prune, int) and isinstance(burn, int) and prune >= burn:
        err("identify.prune", f"must be < identify.burn ({burn}), got {prune}: stranded "
            "walkers are pruned within the burn-in")
    kw["identify"] = opts


def _parse_rig(table, values, kw, base: Path, err) -> None:
    """``[rig] file = ...`` or an inline description: the canonical description in kw."""
    if not isinstance(table, dict):
        return
    inline = {k: v for k, v in table.items() if k not in ("springs_n_m", "file")}
    given = [k for k in ("springs_n_m", "file") if k in table] + (["inline tables"] if inline
                                                                   else [])
    if len(given) > 1:
        err("rig", f"give one of springs_n_m, file or an inline description, got {given}")
        return
    if not (inline or "file" in table):
        return

    try:
        if inline:
            rig = rig_from_dict(inline, where="inline description")
        else:
            f = values.get(("rig", "file"))
            if f is None:
                return
            p = Path(f).expanduser()
            rig = load_rig(f if f in PRESETS else (p if p.is_absolute() else base / p))
    except ModelError as exc:
        err("rig", str(exc))
        return
    kw["rig"] = rig_to_dict(rig)
    kw["springs_n_m"] = rig.springs_n_m
