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


class IdentificationError(ValueError):
    """A fit ended without determining its parameters (``Identification.identified`` is
    False); the message names the cause and the fix."""


def one_line(exc: BaseException) -> str:
    """Every problem of a (configuration) error on one line, joined by ``"; "``."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    if len(lines) > 1 and lines[0].endswith("in the configuration:"):
        lines = lines[1:]
    return "; ".join(lines) or type(exc).__name__
