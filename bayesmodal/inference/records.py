"""Several records, one physical system: shared, per-record and hierarchical parameters.

The records of one rig share its physics (masses, dampers, springs, extension
parameters) but not everything: the drive gain ``g_v`` differs from record to record on
the ECP 210 (about 6.1 N/V on the steps, 5.5 on the impulses, 4.5-5.2 on the sweeps), and
the amplifier has an input offset ``v0`` (V).  A :class:`RecordLayout` says which
parameters are per record and how (``"shared"``, ``"independent"`` or
``"hierarchical"``, drawn from a population), and where each sits in the parameter
vector (:mod:`.record_layout`, whose names stay importable from here).  The priors and
a starting point are in :mod:`.record_priors`, the choice of the noise model in
:mod:`.noise_choice`.

The input offset ``v0`` is not a parameter of the single-record model; declaring it adds
``v0[r]`` to every record (``v = v_measured + v0``).  For the linear model the output is
linear in ``g_v`` and in the input, so with unit-gain simulations ``a = S(v)`` and
``b = S(1)`` the prediction is ``y = g_v (a + v0 b)`` (two simulations per record).

Noise parameters (``sigma_j``, ``phi_j``) are shared by the records unless
``noise_per_record``; a new record is then predicted with the shared noise model (or, per
record, with a training record's noise parameters drawn at random).

The likelihood is :class:`~bayesmodal.inference.likelihood.Likelihood` with a ``layout``;
:class:`RecordsLikelihood` is the same class with the package's default layout
(:data:`DEFAULT_LAYOUT`) when none is given.
"""

from __future__ import annotations

from dataclasses import dataclass

from .likelihood import Likelihood
from .noise_choice import choose_noise, resolve_noise
from .record_layout import (
    DEFAULT_LAYOUT,
    PER_RECORD_KINDS,
    RecordLayout,
    model_layout,
    parameter_index,
    parse_layout,
    population_log_density,
    record_key,
    record_values,
)
from .record_priors import TAU_SCALE, record_priors, records_start

__all__ = [
    "RecordLayout",
    "RecordsLikelihood",
    "record_priors",
    "records_start",
    "parse_layout",
    "resolve_noise",
    "choose_noise",
    "PER_RECORD_KINDS",
    "TAU_SCALE",
    "DEFAULT_LAYOUT",
    "model_layout",
    "parameter_index",
    "population_log_density",
    "record_key",
    "record_values",
]


@dataclass(frozen=True, eq=False)
class RecordsLikelihood(Likelihood):
    """:class:`~bayesmodal.inference.likelihood.Likelihood` with a record layout, by
    default :data:`DEFAULT_LAYOUT` (a drive gain per record from a population, one input
    offset for all records).

    Parameters
    ----------
    model, experiments, noise, extension, scale_at
        As for ``Likelihood``; record names must be distinct (they name the per-record
        parameters).
    layout : RecordLayout
        Per-record parameters (default :data:`DEFAULT_LAYOUT`).

    Examples
    --------
    >>> import numpy as np
    >>> from bayesmodal.data import Experiment
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> t = np.arange(200) * 0.005
    >>> exps = [Experiment(t, 3.0 * (t < 0.05), np.zeros((200, 3)), name=n) for n in "ab"]
    >>> lik = RecordsLikelihood(LinearModel(Rig(), "proportional"), exps, "white")
    >>> lik.names[:5]
    ('m1', 'm2', 'm3', 'ca', 'cb')
    >>> lik.names[5:9]
    ('mu_g_v', 'tau_g_v', 'g_v[a]', 'g_v[b]')
    """

    layout: RecordLayout | None = DEFAULT_LAYOUT

