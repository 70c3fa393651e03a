"""Which noise model a run uses: resolved from its name, or AR orders chosen by BIC.

A run names its residual model (``"white"``, ``"ar1"``, ``"iar1"``, ``"arP"``,
``"process"``...; :mod:`.noise_spec` reads the spelling) or asks for AR orders fitted
to the residuals of a least-squares estimate (``"ar:auto"``).  The several-record
likelihood (:mod:`bayesmodal.inference.records`), ``sample_posterior`` and the
cross-validation resolve it here.
"""

from __future__ import annotations

import numpy as np

from ..model.effects import resolve_extension
from ..model.simulate import simulate_linear
from .noise import ARpNoise, NoiseModel, choose_order
from .noise_spec import parse_noise

__all__ = ["resolve_noise", "choose_noise", "AUTO_MAX_ORDER"]


def resolve_noise(noise, n_outputs: int):
    """A ``NoiseModel`` for ``"white"``, ``"ar1"``, ``"iar1"``, ``"arP"`` /
    ``"ar(p1,...,pn)"``, ``"process"``, a ``NoiseSpec`` (``noise_spec.parse_noise``) or an
    instance (``bayesmodal.inference.noise``).

    Parameters
    ----------
    noise : str, NoiseSpec or NoiseModel
        The noise model, by name (``noise_spec.parse_noise`` reads it) or built.
    n_outputs : int
        Outputs of the records: AR orders given per output must match, and an instance
        must accept it.

    Returns
    -------
    NoiseModel

    Examples
    --------
    >>> resolve_noise("ar3", 2).name
    'ar(3,3)'
    """
    if isinstance(noise, NoiseModel):
        noise.names(n_outputs)  # checks the number of outputs
        return noise
    return parse_noise(noise).model(n_outputs)


#: Largest AR order ``"ar:auto"`` considers.  On the measured ECP 210 residuals BIC keeps
#: choosing the largest order offered (docs/noise_models.md): the cap is a modelling
#: decision, not a property of the data.
AUTO_MAX_ORDER = 8


def choose_noise(experiments, model, start, *, extension=None, max_p: int = AUTO_MAX_ORDER):
    """AR orders per output chosen by BIC on the residuals of a least-squares fit.

    Parameters
    ----------
    experiments : sequence of Experiment
    model : LinearModel
    start : LSQResult, ExtensionFit or ndarray
        The fit (its ``theta``) whose residuals are used; records are pooled by taking,
        per output, the largest order any record asks for.
    extension : Extension, optional

    Returns
    -------
    ARpNoise
    """
    theta = np.asarray(getattr(start, "theta", start), dtype=float)
    orders = np.ones(model.n_outputs, int)
    for e in experiments:
        if extension is None:
            yh = simulate_linear(model, theta, e.v_volt, e.dt)
        else:
            yh = resolve_extension(extension, model).simulate(model.rig, theta[None],
                                                              e.v_volt, e.dt)[0]
        choice = choose_order(e.y_m - yh, max_p=max_p)
        orders = np.maximum(orders, np.asarray(choice.orders, int))
    return ARpNoise(tuple(int(p) for p in orders))
