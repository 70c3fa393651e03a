"""numpy containers and scalars to plain JSON types (one conversion for every writer)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def to_jsonable(obj):
    """Plain JSON types from numpy containers and scalars.

    Mappings become dicts with string keys, tuples and arrays lists, numpy scalars Python
    scalars; non-finite floats become None (JSON ``null``).  Anything else is returned
    as it is.
    """
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if np.isfinite(f) else None
    return obj
