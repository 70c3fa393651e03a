"""Exception types of bayesmodal.

Each subclasses a built-in so that callers may catch either the specific type or the
built-in one (``except ValueError``).
"""


class DataError(ValueError):
    """Measured data are missing, malformed, or physically implausible."""


class ModelError(ValueError):
    """Model parameters are impossible (non-positive mass, negative damping, ...)."""


class ConfigError(ValueError):
    """A run configuration is invalid."""
