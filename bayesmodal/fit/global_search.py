"""A global search before the local fit, for models whose cost is terraced (stick-slip):
``fit_extension_global(records, ext, rig, ...)`` is the same as ``fit_lsq(records, rig,
extension=ext, search="global", ...)`` (:func:`bayesmodal.fit.fit_lsq`), kept under its
name.  The search itself (its box, the evolution, the pruned starts and the measurements
behind them) is in ``bayesmodal.fit._global_start``.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import Rig
from ._global_start import (
    DAMPER_BOX,
    DAMPER_PAD,
    MASS_BOX,
    PRUNE_ROUNDS,
    STICK_SLIP,
    UNBOUNDED_SCALES,
    ZERO_SHARE,
    is_stick_slip,
    pruned_starts,
    search_box,
)
from .lsq import fit_lsq
from .result import ExtensionFit, LSQResult

__all__ = ["fit_extension_global", "is_stick_slip", "search_box", "pruned_starts", "MASS_BOX",
           "DAMPER_BOX", "DAMPER_PAD", "UNBOUNDED_SCALES", "ZERO_SHARE", "PRUNE_ROUNDS",
           "STICK_SLIP"]


def fit_extension_global(
    experiments: Experiment | Sequence[Experiment],
    ext: Extension,
    rig: Rig | None = None,
    *,
    linear: LSQResult | None = None,
    generations: int = 200,
    popsize: int = 30,
    rng=None,
    max_nfev: int = 200,
    max_samples: int = 4000,
    weights: Sequence[float] | str | None = None,
) -> ExtensionFit:
    """Differential evolution over the model's box, then the least-squares polish:
    ``fit_lsq(experiments, rig, extension=ext, search="global", ...)``.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    ext : Extension
    rig : Rig, optional
        Default ``Rig()``.
    linear : LSQResult, optional
        Linear free-damping fit to the same experiments (the box's centre).
    generations : int
        Generations of the evolution (each one batched call per experiment).
    popsize : int
        Population per parameter (SciPy's ``popsize``): ``popsize * n_params`` members.
    rng : int or numpy.random.Generator, optional
        Seeds the evolution.
    max_nfev : int
        Evaluation budget of the polish.
    max_samples : int
        Samples the evolution sees, shared equally by the records (the first ones of
        each; the polish fits all): it bounds the search's cost whatever the data's size.
    weights : sequence of float or "spread", optional
        Weight of each record in the cost (``fit_extension_lsq``), decided on the whole
        records and kept for the searched samples.

    Returns
    -------
    ExtensionFit
        The polished fit (its ``theta_start`` is where its last polish started).

    Raises
    ------
    ConfigError
        For ``generations``, ``popsize`` or ``max_samples`` below 1.
    """
    return fit_lsq(experiments, Rig() if rig is None else rig, extension=ext,
                   search="global", linear=linear, generations=generations, popsize=popsize,
                   rng=rng, max_nfev=max_nfev, max_samples=max_samples, weights=weights)
