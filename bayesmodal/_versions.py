"""Versions of Python and of the packages a result depends on (stamped on every result)."""

from __future__ import annotations

import platform
from importlib import metadata

__all__ = ["DEPENDENCIES", "dependency_versions"]

#: Distributions whose versions are stamped on every result.
DEPENDENCIES = ("numpy", "scipy", "emcee", "arviz", "numba", "h5py", "netCDF4", "matplotlib")


def dependency_versions(names=DEPENDENCIES) -> dict[str, str | None]:
    """Installed version of each distribution (None if absent), plus Python's.

    Examples
    --------
    >>> "numpy" in dependency_versions()
    True
    """
    out: dict[str, str | None] = {"python": platform.python_version()}
    for nm in names:
        try:
            out[nm] = metadata.version(nm)
        except metadata.PackageNotFoundError:
            out[nm] = None
    return out
