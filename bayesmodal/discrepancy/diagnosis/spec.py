"""How a diagnosis searches: one frozen object with its defaults and checks.

:func:`~bayesmodal.discrepancy.diagnosis.workflow.diagnose` takes the records, this object
and the few things that are not settings (the rig, which records train, the seed,
progress)::

    from bayesmodal.discrepancy.diagnosis import DiagnoseSpec, diagnose

    d = diagnose(records, DiagnoseSpec(n_null=80, max_effects=2), rig=rig, rng=1)

A setting may also be given by name (``diagnose(records, n_null=80)``); an unknown name is
a ``TypeError`` listing the names.  Everything is checked when the object is built, before
any fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..._errors import ConfigError
from ...fit.effects import WEIGHTINGS
from ...inference.spec import put_settings
from ...inference.threads import resolve_threads
from ...model.effects import EXTENSIONS

__all__ = ["DiagnoseSpec", "with_diagnose_settings"]


def _positive_int(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConfigError(f"{name} must be a positive integer, got {value!r}")


@dataclass(frozen=True)
class DiagnoseSpec:
    """The settings of a diagnosis.

    Attributes
    ----------
    candidates : tuple of str or None
        Extensions considered (None: ``DEFAULT_CANDIDATES``, the whole catalogue, less
        what the rig cannot carry).
    n_null : int
        Null data sets of the calibration (at least ``1/alpha - 1``).
    alpha : float
        Family-wise false-positive rate of the discrepancy decision; the candidates'
        likelihood-ratio tests use ``alpha / n_candidates``.
    posterior : bool
        Sample the accepted extended model with emcee for credible intervals and the ELPD
        change (slow); the decision never depends on it.
    posterior_options : dict or None
        ``sample_posterior`` settings of that run (``n_steps``, ``n_walkers``...).
    quantum_m : float or None
        Encoder resolution of the null simulations, m (None: inferred, one ECP count
        when the positions are whole counts, else 0).
    max_fits : int or None
        Fit only the candidates with the strongest signatures (None: all).
    max_nfev : int
        Residual evaluations of each candidate's least-squares fit.
    n_starts : int
        Local fits per candidate, from the best points of the batched grid.
    max_effects : int
        Largest number of effects forward selection puts in the model (1: the first
        cause only).
    global_search : bool
        In forward selection, fit every model with stick-slip friction also by
        differential evolution and a least-squares polish.
    weights : {None, "spread"}
        How the extended models' fits weigh several training records (None: the plain
        sum of squares; ``"spread"``: each record as much as the others).
    threads : int or "auto"
        Threads for the parts of the fits that do not depend on one another (the local
        searches from several starts, each generation of the global search, the folds
        of the leave-one-record-out gains; ``bayesmodal.fit._threads``); ``"auto"``: one
        per core.  The same diagnosis, number for number, on any count.
    """

    candidates: Sequence[str] | None = None
    n_null: int = 40
    alpha: float = 0.05
    posterior: bool = True
    posterior_options: dict | None = None
    quantum_m: float | None = None
    max_fits: int | None = None
    max_nfev: int = 40
    n_starts: int = 3
    max_effects: int = 3
    global_search: bool = True
    weights: str | None = None
    threads: int | str = 1

    def __post_init__(self) -> None:
        if self.candidates is not None:
            cands = tuple(self.candidates)
            unknown = [c for c in cands if c not in EXTENSIONS]
            if unknown or not cands:
                raise ConfigError(f"unknown candidate extension(s) {unknown}; known: "
                                  f"{sorted(EXTENSIONS)}")
            object.__setattr__(self, "candidates", cands)
        if self.weights is not None and self.weights not in WEIGHTINGS:
            raise ConfigError(f"weights must be None or one of {WEIGHTINGS}, "
                              f"got {self.weights!r}")
        if self.quantum_m is not None and not (np.isfinite(self.quantum_m)
                                               and self.quantum_m >= 0):
            raise ConfigError(f"quantum_m must be finite and >= 0, got {self.quantum_m!r}")
        resolve_threads(self.threads)
        _positive_int("n_starts", self.n_starts)
        _positive_int("max_effects", self.max_effects)


def with_diagnose_settings(spec: DiagnoseSpec | None, settings: dict) -> DiagnoseSpec:
    """``spec`` with ``settings`` put in.

    Parameters
    ----------
    spec : DiagnoseSpec or None
        None: the defaults.
    settings : dict
        Field name -> value.

    Returns
    -------
    DiagnoseSpec

    Raises
    ------
    TypeError
        For a name that is not a field, listing the names.

    Examples
    --------
    >>> with_diagnose_settings(None, {"n_null": 80}).n_null
    80
    """
    return put_settings((DiagnoseSpec() if spec is None else spec,), settings,
                        "diagnose")[0]
