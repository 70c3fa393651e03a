"""Output-error least squares: one fitter, :func:`fit_lsq`, for the linear model and a
model with effects, one or several records, shared or per-record parameters, weighted or
not, a local or a global search (``lsq``, options :class:`LSQOptions`, result
:class:`LSQResult`).

The older entry points stay as thin calls of it: ``fit_extension_lsq`` (``effects``),
``fit_records_lsq`` and ``loro_lsq`` (``records``), ``fit_extension_global``
(``global_search``).  Above ``bayesmodal.model`` and ``bayesmodal.data``; inference and
diagnosis start from these fits.
"""

from .effects import fit_extension_lsq
from .global_search import fit_extension_global
from .linear import (
    INITIAL_STATES,
    _res,
    barrier_residuals,
    check_records,
    default_start,
    residuals,
)
from .lsq import LSQOptions, fit_lsq
from .records import LOROFit, RecordsFit, fit_records_lsq, loro_lsq
from .result import ExtensionFit, LSQResult

__all__ = ["LSQResult", "LSQOptions", "fit_lsq", "default_start", "ExtensionFit",
           "fit_extension_lsq", "RecordsFit", "LOROFit", "fit_records_lsq", "loro_lsq",
           "fit_extension_global"]
# (INITIAL_STATES, barrier_residuals, check_records, residuals and _res are imported for
# code that reads them from bayesmodal.fit)
_ = (INITIAL_STATES, barrier_residuals, check_records, residuals, _res)
