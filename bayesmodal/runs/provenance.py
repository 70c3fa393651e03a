"""What a run's results depend on: package and dependency versions, data digests."""

from __future__ import annotations

import platform
from importlib import metadata
from pathlib import Path

from ..data import file_sha256

__all__ = ["DEPENDENCIES", "dependency_versions", "data_digests"]

#: Distributions whose versions are stamped on every run.
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


def data_digests(paths) -> list[dict]:
    """``[{"file", "name", "sha256", "bytes"}]`` for each data file (SHA-256 of its bytes)."""
    out = []
    for p in paths:
        p = Path(p)
        out.append({"file": str(p), "name": p.name, "sha256": file_sha256(p),
                    "bytes": p.stat().st_size})
    return out
