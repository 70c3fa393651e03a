"""The run description: one frozen object in the sections of the TOML file.

A :class:`RunConfig` holds one frozen section per table of a run configuration
(``[data]``, ``[rig]`` with ``[model]`` and ``[priors]``, ``[records]``,
``[likelihood]``, ``[sampler]``, ``[crossval]``, ``[outputs]``, ``[evidence]``); each
field of a section is named as its TOML key and has its default here, in one place.
``bayesmodal.runs.config`` builds it from a file, the command line from its flags.

Run folders written before the sections record the configuration flat
(``config.json``, and the SHA-256 ``RunConfig.hash`` of it that identifies a run);
:data:`FLAT_NAMES` maps each flat name to its section and key, so that
:meth:`RunConfig.to_dict` and :meth:`RunConfig.from_flat` read and write that form and
every recorded hash stays the same.
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .._errors import ConfigError
from ..data import ECP_M_PER_COUNT
from ..discrepancy.diagnosis.spec import DiagnoseSpec
from ..inference.crossval import CrossvalSpec
from ..inference.moves import MOVE_REVISIONS, parse_moves
from ..inference.noise_spec import parse_noise
from ..inference.priors import LogUniform, Uniform
from ..inference.record_layout import RecordLayout
from ..inference.spec import LikelihoodSpec, SamplerSpec
from ..model.effects import extension_revisions
from ..model.rigs import rig_from_dict
from ..model.system import ECP210_SPRINGS_N_M, LinearModel, Rig
from ..reading import ReadOptions
from .config_sections import DEFAULT_BURN, PriorOverride
from .identify_spec import IDENTIFY_DIAGNOSIS_KEYS, DiagnosisSpec

__all__ = ["RunConfig", "DataSection", "ModelSection", "RecordsSection",
           "LikelihoodSection", "SamplerSection", "CrossvalSection", "OutputsSection",
           "EvidenceSection", "FLAT_NAMES"]


@dataclass(frozen=True)
class DataSection:
    """``[data]``: the records and how to read them.

    Attributes
    ----------
    files : tuple of str
        The fitted records (resolved paths).
    heldout : tuple of str
        Records scored, not fitted.
    m_per_count : float
        Metres per encoder count (m).
    columns : dict or None
        A lab file's own column names, ``{"t": ..., "v": ..., "x1": ...}``.
    input_scale, time_scale : float
        V per unit of the input column; s per unit of the time column.
    time_base : {"auto", "stamps", "grid"}
        How the time column is read.
    t_start, t_end : float or None
        A time window (s of the record's clock).
    rest_offset : {"none", "initial", "final"}
        Which rest level is subtracted from each position.
    """

    files: tuple[str, ...]
    heldout: tuple[str, ...] = ()
    m_per_count: float = ECP_M_PER_COUNT
    columns: dict[str, str] | None = None
    input_scale: float = 1.0
    time_scale: float = 1.0
    time_base: str = "auto"
    t_start: float | None = None
    t_end: float | None = None
    rest_offset: str = "none"

    def read_options(self) -> ReadOptions:
        """The ``ReadOptions`` of the section (column map and scales; ``m_per_count`` is
        given to the loader separately, for encoder files)."""
        return ReadOptions(columns=self.columns, input_scale=self.input_scale,
                           time_scale=self.time_scale, time_base=self.time_base,
                           t_start=self.t_start, t_end=self.t_end,
                           rest_offset=self.rest_offset)


@dataclass(frozen=True)
class ModelSection:
    """``[rig]``, ``[model]`` and ``[priors]``: the rig, its damping, effects and priors.

    Attributes
    ----------
    springs_n_m : tuple of float
        Spring stiffnesses of a chain (N/m), or the springs of ``rig``.
    rig : dict or None
        The rig description's tables; None: the chain of ``springs_n_m``.
    damping : {"free", "proportional"}
        Damping model.
    extensions : tuple of str
        Effects of ``bayesmodal.model.effects`` added to the linear model.
    priors : dict of str to PriorOverride
        Per-parameter prior bounds.
    """

    springs_n_m: tuple[float, ...] = ECP210_SPRINGS_N_M
    rig: dict | None = None
    damping: str = "free"
    extensions: tuple[str, ...] = ()
    priors: dict[str, PriorOverride] = field(default_factory=dict)

    def make_rig(self, where: str = "<config>: [rig]") -> Rig:
        """The ``Rig``: the description of ``rig``, else the chain of springs; ``where``
        names the table in messages."""
        if self.rig is None:
            return Rig(self.springs_n_m)
        return rig_from_dict(self.rig, where=where)

    @property
    def extension(self) -> str | None:
        """The effects as one ``"a+b"`` name, None for the linear model."""
        return "+".join(self.extensions) if self.extensions else None


@dataclass(frozen=True)
class RecordsSection:
    """``[records]``: what the records share and what each has of its own.

    Attributes
    ----------
    per_record : dict of str to str
        Parameters given a value per record: ``"hierarchical"`` or ``"independent"``.
    noise_per_record : bool
        Each record its own noise parameters.
    noise_scale : {"none", "response", "power"}
        How each record's noise level is sized.
    """

    per_record: dict[str, str] = field(default_factory=dict)
    noise_per_record: bool = False
    noise_scale: str = "none"


@dataclass(frozen=True)
class LikelihoodSection:
    """``[likelihood]``: the residual model.

    Attributes
    ----------
    noise : str
        Noise model (``bayesmodal.inference.noise_spec.parse_noise``).
    temperature : float or "loro"
        Generalised posterior exponent 1/T, or calibrated by leave-one-record-out.
    initial_state : {"rest", "estimate"}
        ``"estimate"`` samples each record's initial positions and velocities (free
        decays released by hand).
    """

    noise: str = LikelihoodSpec.noise
    temperature: float | str = LikelihoodSpec.temperature
    initial_state: str = LikelihoodSpec.initial_state


@dataclass(frozen=True)
class SamplerSection:
    """``[sampler]``: the emcee ensemble.

    Attributes
    ----------
    walkers, steps, burn, thin : int
        Ensemble size, steps per walker, burn-in steps, thinning.
    seed : int
        Random seed; the same seed gives the same chain.
    moves : str
        Move mixture (``bayesmodal.inference.moves``).
    restart, prune : int or None
        Step of the re-centring on the best walker, or of the pruning of stranded ones.
    init : {"ball", "laplace"}
        How the walkers start.
    threads : int
        Threads evaluating the walkers (execution only: the chain is the same).
    """

    walkers: int = SamplerSpec.n_walkers
    steps: int = SamplerSpec.n_steps
    burn: int = DEFAULT_BURN
    thin: int = 5
    seed: int = 1
    moves: str = "de"
    restart: int | None = None
    prune: int | None = None
    init: str = SamplerSpec.init
    threads: int = SamplerSpec.threads

    def spec(self, moves, *, progress: bool = False, warn: bool = True) -> SamplerSpec:
        """The ``SamplerSpec`` of this section, with ``moves`` parsed
        (``bayesmodal.inference.moves.parse_moves`` of :attr:`moves`)."""
        return SamplerSpec(n_walkers=self.walkers, n_steps=self.steps, burn=self.burn,
                           thin=self.thin, moves=moves, init=self.init,
                           restart=self.restart, prune=self.prune, threads=self.threads,
                           progress=progress, warn=warn)


@dataclass(frozen=True)
class CrossvalSection:
    """``[crossval]``: the leave-one-record-out check of the run.

    Attributes
    ----------
    enabled : bool
        Run the check after the posterior.
    draws : int
        Posterior draws per held-out prediction.
    walkers, steps : int or None
        Per fold; None: the sampler's.
    """

    enabled: bool = False
    draws: int = 200
    walkers: int | None = None
    steps: int | None = None


@dataclass(frozen=True)
class OutputsSection:
    """``[outputs]``: what the run folder holds.

    Attributes
    ----------
    dir : str
        Folder relative to the output root ("": the configuration's name).
    plots, report, ema : bool
        The figures, ``report.html``, the LSCE cross-check.
    predictive_draws : int
        Posterior draws of the posterior predictive.
    checkpoint_every_s : float
        Seconds between checkpoint writes (s).
    pointwise_loglik : bool
        Keep the pointwise log-likelihood in ``posterior.nc``.
    chain : {"compact", "full"}
        How ``chain.h5`` of a finished run is stored.
    """

    dir: str = ""
    plots: bool = True
    report: bool = True
    predictive_draws: int = 200
    ema: bool = True
    checkpoint_every_s: float = 5.0
    pointwise_loglik: bool = True
    chain: str = "compact"


@dataclass(frozen=True)
class EvidenceSection:
    """``[evidence]``: nested-sampling evidence (dynesty).

    Attributes
    ----------
    enabled : bool
        Compute the evidence.
    nlive : int
        Live points.
    dlogz : float
        Stop when the remaining evidence is below this (log units).
    """

    enabled: bool = False
    nlive: int = 250
    dlogz: float = 0.5


#: Flat name of each field (``config.json`` and the hash) -> (section, key), in the order
#: ``config.json`` has always listed them (between ``name``, ``source`` and ``identify``).
FLAT_NAMES: dict[str, tuple[str, str]] = {
    "data_files": ("data", "files"), "m_per_count": ("data", "m_per_count"),
    "springs_n_m": ("model", "springs_n_m"), "damping": ("model", "damping"),
    "extensions": ("model", "extensions"), "priors": ("model", "priors"),
    "noise": ("likelihood", "noise"),
    **{k: ("sampler", k) for k in ("walkers", "steps", "burn", "thin", "seed", "moves",
                                   "restart", "prune", "init", "threads")},
    "out_dir": ("outputs", "dir"), "plots": ("outputs", "plots"),
    "report": ("outputs", "report"), "predictive_draws": ("outputs", "predictive_draws"),
    "heldout_files": ("data", "heldout"), "ema": ("outputs", "ema"),
    "checkpoint_every_s": ("outputs", "checkpoint_every_s"),
    "pointwise_loglik": ("outputs", "pointwise_loglik"),
    "chain_storage": ("outputs", "chain"),
    "evidence": ("evidence", "enabled"), "evidence_nlive": ("evidence", "nlive"),
    "evidence_dlogz": ("evidence", "dlogz"),
    "rig": ("model", "rig"),
    "per_record": ("records", "per_record"),
    "noise_per_record": ("records", "noise_per_record"),
    "noise_scale": ("records", "noise_scale"),
    "temperature": ("likelihood", "temperature"),
    "initial_state": ("likelihood", "initial_state"),
    "crossval": ("crossval", "enabled"), "crossval_draws": ("crossval", "draws"),
    "crossval_walkers": ("crossval", "walkers"), "crossval_steps": ("crossval", "steps"),
    "columns": ("data", "columns"), "input_scale": ("data", "input_scale"),
    "time_scale": ("data", "time_scale"), "time_base": ("data", "time_base"),
    "t_start": ("data", "t_start"), "t_end": ("data", "t_end"),
    "rest_offset": ("data", "rest_offset"),
}

#: The section classes, by ``RunConfig`` field.
SECTIONS = {"data": DataSection, "model": ModelSection, "records": RecordsSection,
            "likelihood": LikelihoodSection, "sampler": SamplerSection,
            "crossval": CrossvalSection, "outputs": OutputsSection,
            "evidence": EvidenceSection}

#: Flat fields left out of the hash at their defaults (configs written before them keep
#: their hashes).
_NEW_DEFAULTS = {"per_record": {}, "noise_per_record": False, "noise_scale": "none",
                 "temperature": 1.0,
                 "crossval": False, "crossval_draws": 200, "crossval_walkers": None,
                 "crossval_steps": None, "columns": None, "input_scale": 1.0,
                 "time_scale": 1.0, "time_base": "auto", "init": "ball", "prune": None,
                 "t_start": None, "t_end": None, "rest_offset": "none",
                 "identify": None, "initial_state": "rest"}

#: Flat fields that do not change the result (left out of the hash).
_EXECUTION_ONLY = ("source", "name", "out_dir", "plots", "report", "ema",
                   "checkpoint_every_s", "pointwise_loglik", "chain_storage", "threads")

#: Every name of the flat form, in ``config.json``'s order.
_FLAT_ORDER = ("name", "source", *FLAT_NAMES, "identify")


@dataclass(frozen=True)
class RunConfig:
    """A validated run description, in the sections of the TOML file.

    Attributes
    ----------
    name : str
        Run name (the configuration file's stem).
    source : str
        Where the description came from (file name used in messages).
    data, model, records, likelihood, sampler, crossval, outputs, evidence
        The sections (:class:`DataSection` ... :class:`EvidenceSection`).
    identify : dict or None
        The ``[identify]`` table (the whole workflow, ``bayesmodal.runs.identify``);
        None without one.
    """

    name: str
    source: str
    data: DataSection
    model: ModelSection = field(default_factory=ModelSection)
    records: RecordsSection = field(default_factory=RecordsSection)
    likelihood: LikelihoodSection = field(default_factory=LikelihoodSection)
    sampler: SamplerSection = field(default_factory=SamplerSection)
    crossval: CrossvalSection = field(default_factory=CrossvalSection)
    outputs: OutputsSection = field(default_factory=OutputsSection)
    evidence: EvidenceSection = field(default_factory=EvidenceSection)
    identify: dict | None = None

    def __post_init__(self) -> None:
        for name, cls in SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"RunConfig.{name} must be a {cls.__name__}, got "
                                  f"{type(getattr(self, name)).__name__}; build it with "
                                  f"RunConfig.from_flat or the section classes")

    @classmethod
    def from_flat(cls, flat: dict) -> RunConfig:
        """The description from its flat form (``config.json``, the parser's values).

        Raises
        ------
        TypeError
            On a name that is no field (``FLAT_NAMES``, ``name``, ``source``,
            ``identify``).
        """
        unknown = sorted(set(flat) - set(FLAT_NAMES) - {"name", "source", "identify"})
        if unknown:
            raise TypeError(f"unknown field(s) {unknown}")
        parts: dict[str, dict] = {s: {} for s in SECTIONS}
        for flat_name, value in flat.items():
            if flat_name in FLAT_NAMES:
                section, key = FLAT_NAMES[flat_name]
                parts[section][key] = value
        return cls(name=flat["name"], source=flat["source"],
                   identify=flat.get("identify"),
                   **{s: SECTIONS[s](**kw) for s, kw in parts.items()})

    def make_rig(self) -> Rig:
        """The ``Rig``: the description of ``[rig]``, else the chain of springs."""
        return self.model.make_rig(where=f"{self.source}: [rig]")

    # ------------------------------------------------ what the library functions read
    # (``bayesmodal.inference.spec.RunDescription``: sample_posterior, crossval, diagnose)
    def make_model(self) -> LinearModel:
        """The ``LinearModel`` of ``[rig]`` with the ``[model] damping``."""
        return LinearModel(self.make_rig(), self.model.damping)

    @property
    def seed(self) -> int:
        """The ``[sampler] seed``."""
        return self.sampler.seed

    def likelihood_spec(self, *, noise=None, temperature: float | None = None
                        ) -> LikelihoodSpec:
        """``[likelihood]``, ``[records]`` and ``[model] extensions`` as a ``LikelihoodSpec``.

        Parameters
        ----------
        noise : str or NoiseSpec, optional
            In place of ``[likelihood] noise`` (e.g. the AR orders that ``"ar:auto"``
            chose).
        temperature : float, optional
            In place of ``[likelihood] temperature`` (needed when it is ``"loro"``, which
            a run calibrates first; 1 otherwise).
        """
        if temperature is None:
            temp = self.likelihood.temperature
            temperature = 1.0 if temp == "loro" else float(temp)
        return LikelihoodSpec(noise=self.likelihood.noise if noise is None else noise,
                              extension=self.model.extension, layout=self.layout,
                              temperature=temperature,
                              initial_state=self.likelihood.initial_state)

    def sampler_spec(self, *, progress: bool = False, warn: bool = True) -> SamplerSpec:
        """``[sampler]`` as a ``SamplerSpec`` (moves parsed).

        Parameters
        ----------
        progress : bool
            A progress bar.
        warn : bool
            Warn when the chain has not converged.
        """
        try:
            moves = parse_moves(self.sampler.moves)
        except ConfigError as exc:
            raise ConfigError(f"{self.source}: {exc}") from exc
        return self.sampler.spec(moves, progress=progress, warn=warn)

    @property
    def diagnosis(self) -> DiagnosisSpec:
        """The diagnosis options of the ``[identify]`` table (its defaults without one)."""
        opts = self.identify or {}
        return DiagnosisSpec(**{IDENTIFY_DIAGNOSIS_KEYS[k]: v for k, v in opts.items()
                                if k in IDENTIFY_DIAGNOSIS_KEYS})

    @property
    def diagnosis_seed(self) -> int:
        """The ``[identify] seed`` of the diagnosis' null data sets."""
        return self.diagnosis.seed

    def diagnose_spec(self, n_train: int = 1) -> DiagnoseSpec:
        """What ``diagnose`` reads of this description: the ``[identify]`` diagnosis
        options on the rig, with the found model's posterior sampled at the end.

        Parameters
        ----------
        n_train : int
            Training records (``weights = "auto"`` depends on it).
        """
        return self.diagnosis.diagnose_spec(self.make_rig(), n_train)

    def prior_overrides(self) -> dict:
        """``[priors]`` as ``{name: Uniform or LogUniform}``."""
        return {name: LogUniform(ov.lo, ov.hi) if ov.scale == "log" else Uniform(ov.lo, ov.hi)
                for name, ov in self.model.priors.items()}

    @property
    def layout(self) -> RecordLayout | None:
        """The per-record layout (``RecordLayout``), or None for shared parameters."""
        rec = self.records
        if not rec.per_record and not rec.noise_per_record and rec.noise_scale == "none":
            # AR(p) noise lives in the several-record likelihood: shared layout
            return None if parse_noise(self.likelihood.noise).one_record else RecordLayout({})
        return RecordLayout(dict(rec.per_record), rec.noise_per_record, rec.noise_scale)

    def crossval_spec(self) -> CrossvalSpec:
        """The ``CrossvalSpec`` of this configuration (model, noise, layout, sampler)."""
        smp, cv, temp = self.sampler, self.crossval, self.likelihood.temperature
        return CrossvalSpec(
            damping=self.model.damping, noise=self.likelihood.noise,
            extension=self.model.extension,
            layout=self.layout or RecordLayout({}),
            n_walkers=cv.walkers or smp.walkers,
            n_steps=cv.steps or smp.steps, burn=None if cv.steps else smp.burn,
            n_predictive=cv.draws, seed=smp.seed,
            temperature=1.0 if temp == "loro" else temp,
            springs_n_m=self.model.springs_n_m, init=smp.init, moves=smp.moves,
            prune=smp.prune, restart=smp.restart,
            rig=None if self.model.rig is None else self.make_rig())

    def to_dict(self) -> dict:
        """The flat form (``config.json``): every field under its flat name."""
        d = {}
        for flat_name in _FLAT_ORDER:
            if flat_name in FLAT_NAMES:
                section, key = FLAT_NAMES[flat_name]
                value = getattr(getattr(self, section), key)
            else:
                value = getattr(self, flat_name)
            d[flat_name] = copy.deepcopy(value)
        d["priors"] = {k: asdict(v) for k, v in d["priors"].items()}
        return d

    def hash(self) -> str:
        """SHA-256 of the canonical JSON of everything that affects the result."""
        d = self.to_dict()
        for k in _EXECUTION_ONLY:
            d.pop(k)
        if d["restart"] is None:  # keeps the hashes of configs written before the key
            d.pop("restart")
        for k, default in _NEW_DEFAULTS.items():
            if d[k] == default:
                d.pop(k)
        if d["rig"] is None:  # likewise for a chain given by springs_n_m
            d.pop("rig")
        # where the data live does not change the result; their content is hashed separately
        d["data_files"] = [Path(f).name for f in self.data.files]
        d["heldout_files"] = [Path(f).name for f in self.data.heldout]
        revised = {m: r for m, r in MOVE_REVISIONS.items() if m in d["moves"]}
        if revised:
            d["move_revisions"] = revised
        ext_revised = extension_revisions(d["extensions"])
        if ext_revised:
            d["extension_revisions"] = ext_revised
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()
