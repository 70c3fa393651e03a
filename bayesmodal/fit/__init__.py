"""Output-error least squares: the linear model (``linear``), a model with effects
(``effects``), several records with per-record parameters (``records``) and the global
search of a friction model (``global_search``).

Above ``bayesmodal.model`` and ``bayesmodal.data``; inference and diagnosis start from
these fits.
"""

from .effects import ExtensionFit, fit_extension_lsq
from .global_search import fit_extension_global
from .linear import (
    INITIAL_STATES,
    LSQResult,
    _res,
    barrier_residuals,
    check_records,
    default_start,
    fit_lsq,
    residuals,
)
from .records import LOROFit, RecordsFit, fit_records_lsq, loro_lsq

__all__ = ["LSQResult", "fit_lsq", "default_start", "ExtensionFit", "fit_extension_lsq",
           "RecordsFit", "LOROFit", "fit_records_lsq", "loro_lsq", "fit_extension_global"]
# (INITIAL_STATES, barrier_residuals, check_records, residuals and _res are imported for
# code that reads them from bayesmodal.fit)
_ = (INITIAL_STATES, barrier_residuals, check_records, residuals, _res)
