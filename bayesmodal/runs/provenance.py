"""What a run's results depend on: package and dependency versions, data digests."""

from __future__ import annotations

from pathlib import Path

from .._versions import DEPENDENCIES, dependency_versions
from ..data import file_sha256

__all__ = ["DEPENDENCIES", "dependency_versions", "data_digests"]


def data_digests(paths) -> list[dict]:
    """``[{"file", "name", "sha256", "bytes"}]`` for each data file (SHA-256 of its bytes)."""
    out = []
    for p in paths:
        p = Path(p)
        out.append({"file": str(p), "name": p.name, "sha256": file_sha256(p),
                    "bytes": p.stat().st_size})
    return out
