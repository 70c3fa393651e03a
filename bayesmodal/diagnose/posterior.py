"""Posterior step of ``diagnose``: emcee samples of the accepted extended model.

Uses ``bayesmodal.inference.sample_posterior(..., extension=...)`` when the installed
sampler supports extensions; returns None otherwise (the workflow then reports Laplace
intervals and says so).
"""

from __future__ import annotations

import inspect

__all__ = ["posterior_summary", "sampler_supports_extensions"]


def sampler_supports_extensions() -> bool:
    """True when ``sample_posterior`` accepts an ``extension`` argument."""
    from ..inference import sample_posterior

    return "extension" in inspect.signature(sample_posterior).parameters


def posterior_summary(*, exps, ext, rig, fit, linear, rng, options):
    """Credible intervals (90 %) and ELPD change, or None without sampler support."""
    if not sampler_supports_extensions():
        return None
    raise NotImplementedError  # filled in when the sampler API is known
