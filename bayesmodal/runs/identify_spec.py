"""The options of the identification workflow, checked in one place.

``[identify]`` of a run configuration and the flags of ``bayesmodal identify`` set them:
:class:`DiagnosisSpec` for the diagnosis stage, :class:`FinalSpec` for the found model's
sampler.  :func:`identify_problems` holds every bound and choice of those options; the
configuration reports each problem under its key, the specs refuse the first.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .._errors import ConfigError
from ..discrepancy.diagnosis import DEFAULT_CANDIDATES, DiagnoseSpec
from ..model.effects import EXTENSIONS

__all__ = ["DiagnosisSpec", "FinalSpec", "identify_problems", "IDENTIFY_DIAGNOSIS_KEYS",
           "IDENTIFY_FINAL_KEYS"]

#: ``[identify]`` keys of the diagnosis stage (``DiagnosisSpec`` fields).
IDENTIFY_DIAGNOSIS_KEYS = {"null": "n_null", "max_effects": "max_effects", "split": "split",
                           "weights": "weights", "seed": "seed", "candidates": "candidates",
                           "starts": "n_starts", "global_search": "global_search"}
#: ``[identify]`` keys of the found model's sampler (``FinalSpec`` fields).
IDENTIFY_FINAL_KEYS = ("walkers", "steps", "burn", "thin", "prune", "crossval_steps",
                       "population")
#: The values an ``[identify]`` key may take, where it names a choice.
IDENTIFY_CHOICES = {"split": ("auto", "none"), "weights": ("auto", "none", "spread")}
#: The smallest value of each integer ``[identify]`` key.
IDENTIFY_MINIMA = {"null": 19, "max_effects": 1, "starts": 1, "walkers": 4, "steps": 10,
                   "burn": 0, "thin": 1, "prune": 1, "crossval_steps": 10}


def identify_problems(opts: Mapping) -> list[tuple[str, str]]:
    """Every ``[identify]`` option out of its range.

    Parameters
    ----------
    opts : mapping
        ``[identify]`` keys (as in the file) to values; absent keys take the defaults of
        :class:`FinalSpec` where another key is checked against them.

    Returns
    -------
    list of (str, str)
        ``(key, message)`` per problem, the message starting "must be".
    """
    out = []
    for key, allowed in IDENTIFY_CHOICES.items():
        if key in opts and opts[key] not in allowed:
            out.append((key, f"must be one of {allowed}, got {opts[key]!r}"))
    for key, lo in IDENTIFY_MINIMA.items():
        v = opts.get(key)
        if isinstance(v, int) and not isinstance(v, bool) and v < lo:
            out.append((key, f"must be >= {lo}, got {v}" + (
                " (19 null data sets are the fewest a 5 % test allows)" if key == "null"
                else "")))
    steps, burn = opts.get("steps", FinalSpec.steps), opts.get("burn", FinalSpec.burn)
    if isinstance(steps, int) and isinstance(burn, int) and burn >= steps:
        out.append(("burn", f"must be < identify.steps ({steps}), got {burn}"))
    prune = opts.get("prune")
    if isinstance(prune, int) and isinstance(burn, int) and prune >= burn:
        out.append(("prune", f"must be < identify.burn ({burn}), got {prune}: stranded "
                    "walkers are pruned within the burn-in"))
    return out


def _refuse(problems: list[tuple[str, str]]) -> None:
    if problems:
        key, message = problems[0]
        raise ConfigError(f"[identify] {key} {message}")


@dataclass(frozen=True)
class DiagnosisSpec:
    """How the diagnosis stage runs ``diagnose`` (its options of the same names).

    Attributes
    ----------
    n_null : int
        Null data sets of the calibration (19 is the least a 5 % test allows).
    max_effects : int
        Largest number of effects forward selection puts in the model.
    candidates : tuple of str or None
        The effects tried; None: ``DEFAULT_CANDIDATES`` plus the end stop of the driven
        cart where the rig has exactly one.
    weights : {"auto", "none", "spread"}
        ``"auto"``: ``"spread"`` with several training records, else ``"none"``.
    split : {"auto", "none"}
        ``"auto"``: cut the record whose driven cart moves furthest at its rests (when it
        has rests and there are other records), so that its parts predict each other.
    seed : int
    n_starts : int
    global_search : bool
    """

    n_null: int = 19
    max_effects: int = 4
    candidates: tuple[str, ...] | None = None
    weights: str = "auto"
    split: str = "auto"
    seed: int = 0
    n_starts: int = 3
    global_search: bool = True

    def __post_init__(self) -> None:
        _refuse(identify_problems({k: getattr(self, f)
                                   for k, f in IDENTIFY_DIAGNOSIS_KEYS.items()}))

    def candidate_names(self, rig) -> list[str]:
        """The effects tried on ``rig``: ``candidates``, or ``DEFAULT_CANDIDATES`` plus the
        end stop of the driven cart where ``rig`` has exactly one.

        Parameters
        ----------
        rig : Rig
        """
        if self.candidates is not None:
            return list(self.candidates)
        out = list(DEFAULT_CANDIDATES)
        if "end_stop" not in out and EXTENSIONS["end_stop"].unsupported(rig) is None:
            out.append("end_stop")
        return out

    def resolved_weights(self, n_train: int) -> str:
        """``weights`` with ``"auto"`` resolved: ``"spread"`` for several training records.

        Parameters
        ----------
        n_train : int
            Training records of the diagnosis.
        """
        return self.weights if self.weights != "auto" else (
            "spread" if n_train > 1 else "none")

    def diagnose_spec(self, rig, n_train: int, *, posterior: bool = True) -> DiagnoseSpec:
        """The ``DiagnoseSpec`` of these options on ``rig`` with ``n_train`` training records.

        Parameters
        ----------
        rig : Rig
        n_train : int
            Training records of the diagnosis (``"auto"`` weights depend on it).
        posterior : bool
            Sample the found model's posterior at the end of the diagnosis (the workflow
            samples it in its own stage).
        """
        weights = self.resolved_weights(n_train)
        return DiagnoseSpec(candidates=self.candidate_names(rig), n_null=self.n_null,
                            posterior=posterior, n_starts=self.n_starts,
                            max_effects=self.max_effects,
                            global_search=self.global_search,
                            weights=None if weights == "none" else weights)


@dataclass(frozen=True)
class FinalSpec:
    """The sampler of the found model's posterior (``[sampler]`` keys of a run config).

    The defaults are those that converge on the measured ECP records
    (``runs/records_friction.toml``): walkers started at the posterior mode, a
    mode-jumping move, stranded walkers pruned after ``prune`` steps.  ``per_record``
    None keeps the linear configuration's; ``crossval`` None too.  ``population`` adds a
    population layer on the physical parameters: every mass of the linear core per
    record, drawn from a log-normal population sampled with them (``[records]
    per_record`` "hierarchical"; with the springs known, a spring that changes between
    experiments moves the frequencies as a mass does), so that the modal intervals for a
    new record hold the spread between experiments.
    """

    walkers: int = 56  # raised to twice the sampled parameters where needed
    steps: int = 12000
    burn: int = 1000
    thin: int | None = None  # None: about 1000 retained draws over all walkers
    prune: int | None = 500
    moves: str = "de:0.8,de-jump:0.2"
    init: str = "laplace"
    threads: int | str = "auto"
    per_record: dict | None = None
    crossval: bool | None = None
    crossval_steps: int | None = None
    population: bool = False

    def __post_init__(self) -> None:
        _refuse(identify_problems({k: getattr(self, k) for k in IDENTIFY_FINAL_KEYS}))

    @property
    def retained_thin(self) -> int:
        """``thin``, or the thinning that keeps about 1000 draws over all walkers."""
        if self.thin is not None:
            return int(self.thin)
        return max(1, self.walkers * (self.steps - self.burn) // 1000)
