"""bayesmodal: Bayesian identification of vibrating mass-spring-damper rigs."""

from ._errors import ConfigError, DataError, ModelError
from .model.simulate import discretize_zoh, simulate_linear
from .model.system import LinearModel, Rig

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "DataError",
    "ModelError",
    "LinearModel",
    "Rig",
    "discretize_zoh",
    "simulate_linear",
    "__version__",
]
