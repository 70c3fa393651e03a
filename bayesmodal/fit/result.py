"""The result of :func:`bayesmodal.fit.fit_lsq`, whatever the model and the records' layout.

``LSQResult`` is the one result type of the least-squares fitter: the linear model, a model
with effects (``extension``), one or several records, shared or per-record parameters.
``ExtensionFit`` is the same class under the name the fits of extended models had.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..identified import identify
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig

__all__ = ["LSQResult", "ExtensionFit"]


@dataclass(frozen=True)
class LSQResult:
    """Result of an output-error least-squares fit.

    Attributes
    ----------
    model : LinearModel
        The linear model (with an extension: its free-damping linear part).
    theta : ndarray, shape (n_params,)
        Estimate in ``names`` order.  With per-record parameters, the vector of a record
        not in the fit (``residuals.new_record_theta``); each record's is in
        ``theta_records``.
    fit_percent : ndarray, shape (n_experiments, n_outputs)
        Fit percentage per experiment and output.
    cost : float
        Half the sum of squared residuals, weighted by ``weights`` (m^2); with the
        ``"cart_spread"`` weighting ``0.5 * sum_{r,j} (1 - fit_rj / 100)^2``
        (dimensionless).
    sigma_m : ndarray, shape (n_outputs,)
        RMS residual per output (pooled over experiments, unweighted), m.
    cov : ndarray, shape (n_params, n_params), or None
        Gauss-Newton covariance ``s^2 (J^T J)^-1`` of the linear model's fit (white-noise
        assumption: optimistic for correlated residuals); None with an extension or
        per-record parameters.
    success : bool
    message : str
    n_evaluations : int
        Residual evaluations of the optimiser, summed over its starts.
    x0 : ndarray, shape (n_experiments, 2 n_carts), or None
        Estimated initial positions (m) and velocities (m/s) per experiment with
        ``initial_state="estimate"``; None when every record starts from rest.
    jac_singular_values : ndarray, shape (n_columns,), or None
        Singular values of the linear fit's final Jacobian with each column scaled to unit
        norm (parameters and estimated initial states), largest first; NaN where the
        Jacobian is not finite.  Read by :func:`bayesmodal.identified.identify`.
    jac_shape : tuple of int
        Shape ``(n_residuals, n_columns)`` of that Jacobian.
    extension : Extension or None
        The model's effects (None: the linear model).
    linear : LSQResult or None
        The linear free-damping fit an extended model was started from.
    theta_start : ndarray, shape (n_params,) or (n_records, n_params), or None
        Where the chosen local search started.
    weights : ndarray, shape (n_experiments,), or None
        The records' weights in the cost (None: unweighted).
    per_record : tuple of str
        Parameters fitted per record (all others are shared).
    record_names : tuple of str
    theta_records : ndarray, shape (n_experiments, n_params), or None
        Each record's full parameter vector (shared values repeated); None for a fit
        whose parameters are all shared.
    """

    model: LinearModel
    theta: np.ndarray
    fit_percent: np.ndarray
    cost: float
    sigma_m: np.ndarray
    cov: np.ndarray | None
    success: bool
    message: str
    n_evaluations: int
    x0: np.ndarray | None = None
    jac_singular_values: np.ndarray | None = None
    jac_shape: tuple[int, int] = (0, 0)
    extension: Extension | None = None
    linear: LSQResult | None = None
    theta_start: np.ndarray | None = None
    weights: np.ndarray | None = None
    per_record: tuple[str, ...] = ()
    record_names: tuple[str, ...] = ()
    theta_records: np.ndarray | None = None

    @property
    def rig(self) -> Rig:
        """The rig of the model."""
        return self.model.rig

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, linear first."""
        if self.extension is None:
            return self.model.names
        return self.extension.names(self.rig)

    @property
    def params(self) -> dict[str, float]:
        """Estimate as a name-to-value mapping."""
        if self.extension is None:
            return self.model.as_dict(self.theta)
        return self.extension.as_dict(self.rig, self.theta)

    @property
    def stderr(self) -> np.ndarray:
        """Gauss-Newton standard errors, shape (n_params,); NaN without ``cov``."""
        if self.cov is None:
            return np.full(np.shape(self.theta)[-1], np.nan)
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    @property
    def improvement_percent(self) -> np.ndarray:
        """Fit percentage gained over the linear start, shape (n_experiments, n_outputs).

        Raises
        ------
        AttributeError
            For a fit that was not started from a linear fit (``linear`` None).
        """
        if self.linear is None:
            raise AttributeError("improvement_percent needs the linear start (linear=None); "
                                 "fit an extended model to compare with its linear fit")
        return self.fit_percent - self.linear.fit_percent

    @property
    def identification(self):
        """The identifiability verdict of the fit (:func:`bayesmodal.identified.identify`).

        Returns
        -------
        Identification
            ``identified`` False, with the reason and the fix, when a gain or mass ended
            at 0, a standard error is not finite or above its estimate, the Jacobian is
            rank-deficient, or the fit is below 0 % on some record and cart.
        """
        return identify(self)


#: The result of a fit of an extended model: the same class (``extension`` set).
ExtensionFit = LSQResult
