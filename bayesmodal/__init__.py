"""bayesmodal: Bayesian identification of vibrating mass-spring-damper rigs.

The public API, one import away::

    from bayesmodal import Rig, load_rig, load_experiment, fit_lsq, sample_posterior

=================================  ==========================================================
the rig and its model              ``Rig``, ``load_rig``, ``LinearModel``, ``simulate_linear``,
                                   ``discretize_zoh``, ``EXTENSIONS``, ``get_extension``
records                            ``Experiment``, ``load_experiment``
least squares                      ``fit_lsq``, ``LSQOptions`` (``fit_extension_lsq``: the
                                   same as ``fit_lsq(..., extension=...)``)
posterior                          ``sample_posterior``, ``LikelihoodSpec``, ``SamplerSpec``,
                                   ``crossval``
what the model misses              ``diagnose``, ``DiagnoseSpec``
runs                               ``RunConfig``, ``load_config``
errors                             ``ConfigError``, ``DataError``, ``ModelError``,
                                   ``IdentificationError``
=================================  ==========================================================

The inference, diagnosis and run names load their layers (emcee, ArviZ) on first use, so
that ``import bayesmodal`` starts quickly.
"""

from importlib import import_module

from ._errors import ConfigError, DataError, IdentificationError, ModelError
from ._version import __version__
from .data import Experiment, load_experiment
from .fit import LSQOptions, fit_extension_lsq, fit_lsq
from .model import EXTENSIONS, LinearModel, Rig, get_extension, load_rig
from .model.simulate import discretize_zoh, simulate_linear

#: Names loaded on first use: name -> module.
_LAZY = {
    "sample_posterior": "bayesmodal.inference.sampling",
    "crossval": "bayesmodal.inference.crossval",
    "diagnose": "bayesmodal.discrepancy.diagnosis.workflow",
    "DiagnoseSpec": "bayesmodal.discrepancy.diagnosis.spec",
    "LikelihoodSpec": "bayesmodal.inference.spec",
    "SamplerSpec": "bayesmodal.inference.spec",
    "RunConfig": "bayesmodal.runs.config",
    "load_config": "bayesmodal.runs.config",
}

__all__ = [
    "Rig", "load_rig", "LinearModel", "simulate_linear", "discretize_zoh", "EXTENSIONS",
    "get_extension", "Experiment", "load_experiment", "fit_lsq", "LSQOptions",
    "fit_extension_lsq",
    "sample_posterior", "LikelihoodSpec", "SamplerSpec", "crossval", "diagnose",
    "DiagnoseSpec", "RunConfig", "load_config",
    "ConfigError", "DataError", "ModelError", "IdentificationError", "__version__",
]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'bayesmodal' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
