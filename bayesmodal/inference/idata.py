"""InferenceData assembly and NetCDF I/O (the only module that builds ArviZ objects)."""

from __future__ import annotations

import warnings


def arviz():
    """Import ArviZ 0.x without its once-a-day refactor announcement.

    ArviZ 0.23 emits a ``FutureWarning`` about its 1.x refactor on the first import of the
    day; it says nothing about this package's use of the 0.x API, so it is silenced here,
    locally, and no other warning is touched.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"\s*ArviZ is undergoing a major refactor",
                                category=FutureWarning)
        import arviz as az
    return az
