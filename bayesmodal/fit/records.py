"""Least squares of one model on several records, with per-record parameters, and its
leave-one-record-out check.

The records of the ECP rig share the physics (masses, dampers, friction levels, ...) but
ask for their own drive gain and amplifier offset (``bayesmodal.inference.records``).
``fit_records_lsq`` fits them jointly (``fit_lsq(..., per_record=...,
weights="cart_spread")``): every parameter is shared except those named in
``per_record`` (default the drive gain ``g_v`` and, when the model has it, the input
offset ``v_offset``), which get one value per record.  The cost is the sum over records
and carts of the squared residual relative to the signal's spread, ``sum_{r,j} |y_rj -
yhat_rj|^2 / |y_rj - mean y_rj|^2 = sum_{r,j} (1 - fit_rj / 100)^2``, so a small-amplitude
sweep weighs as much as the 3 V impulses (an unweighted sum would hand the fit to the
largest record).

``loro_lsq`` fits on all records but one and predicts the one left out as a *new* record:
its per-record parameters are not fitted but taken from the training records, the
geometric mean for a positive parameter (``g_v``) and the arithmetic mean otherwise.
What a model explains about why records differ (a dead band, an amplitude-dependent
gain) therefore carries over to the held-out record; what a per-record gain absorbs does
not.

Examples
--------
>>> from bayesmodal.model.effects import get_extension
>>> from bayesmodal.data import find_data, load_experiment
>>> p = find_data("ecp210-3dof/data_steps.mat")
>>> fit = (fit_records_lsq([load_experiment(p)], get_extension("input_offset"), max_nfev=5)
...        if p else None)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import DataError
from ..data import Experiment
from ..metrics import fit_percent
from ..model.effects._base import Extension
from ..model.system import Rig
from .lsq import CART_SPREAD, fit_lsq
from .residuals import default_per_record, model_names, new_record_theta, simulate_model

__all__ = ["RecordsFit", "LOROFit", "fit_records_lsq", "loro_lsq", "new_record_theta",
           "simulate_model"]


@dataclass(frozen=True)
class RecordsFit:
    """A joint least-squares fit of several records (the result of ``fit_records_lsq``,
    drawn from :class:`~bayesmodal.fit.result.LSQResult`).

    Attributes
    ----------
    extension : Extension or None
        The model (None: the linear free-damping model).
    rig : Rig
    names : tuple of str
        Parameter names of one record's full vector (linear first).
    per_record : tuple of str
        The parameters fitted per record; all others are shared.
    record_names : tuple of str
    theta : ndarray, shape (n_records, n_params)
        Each record's full parameter vector (shared values repeated).
    fit_percent : ndarray, shape (n_records, n_outputs)
        Fit percentage per record and cart.
    cost : float
        ``0.5 * sum_{r,j} (1 - fit_rj / 100)^2`` (dimensionless).
    success : bool
    message : str
    n_evaluations : int
    """

    extension: Extension | None
    rig: Rig
    names: tuple
    per_record: tuple
    record_names: tuple
    theta: np.ndarray
    fit_percent: np.ndarray
    cost: float
    success: bool
    message: str
    n_evaluations: int

    @property
    def params(self) -> dict[str, float | list[float]]:
        """Name-to-value mapping; per-record parameters map to one value per record."""
        out: dict = {}
        for i, n in enumerate(self.names):
            col = self.theta[:, i]
            out[n] = col.tolist() if n in self.per_record else float(col[0])
        return out


@dataclass(frozen=True)
class LOROFit:
    """Leave-one-record-out least squares.

    Attributes
    ----------
    record_names : tuple of str
    fit_percent : ndarray, shape (n_records, n_outputs)
        Fit of each record predicted by the model fitted on the others.
    theta : ndarray, shape (n_records, n_params)
        The parameter vector each held-out record was predicted with.
    folds : tuple of RecordsFit
        The fit on the other records, one per held-out record.
    """

    record_names: tuple
    fit_percent: np.ndarray
    theta: np.ndarray
    folds: tuple


def fit_records_lsq(
    experiments: Sequence[Experiment],
    ext: Extension | None,
    rig: Rig | None = None,
    *,
    per_record: Sequence[str] | None = None,
    theta0: np.ndarray | None = None,
    max_nfev: int = 100,
    fd_step: float = 1e-3,
) -> RecordsFit:
    """Joint least squares of several records with per-record parameters: ``fit_lsq(
    experiments, rig, extension=ext, per_record=per_record, weights="cart_spread",
    theta0=theta0, max_nfev=max_nfev, fd_step=fd_step)`` (:func:`bayesmodal.fit.fit_lsq`),
    its result in the layout below (``theta`` is the result's ``theta_records``).

    Parameters
    ----------
    experiments : sequence of Experiment
        One or more records of the same rig.
    ext : Extension or None
        The model (``get_extension(...)``); None for the linear free-damping model.
    rig : Rig, optional
        Default ``Rig()``.
    per_record : sequence of str, optional
        Parameters fitted per record; default ``g_v`` and, if the model has it,
        ``v_offset``.
    theta0 : ndarray, shape (n_params,) or (n_records, n_params), optional
        Start.  Default: the linear free-damping least-squares fit of all records with the
        extension at its null values.
    max_nfev : int
        Maximum number of residual evaluations.
    fd_step : float
        Forward-difference step of the extension parameters in scaled optimiser
        coordinates (stick-slip costs have small jumps; see ``fit_extension_lsq``).

    Returns
    -------
    RecordsFit

    Raises
    ------
    DataError
        For no records or a record with the wrong number of outputs.
    ConfigError
        For a per-record name that is not a model parameter.
    ModelError
        For an impossible ``theta0``.
    """
    exps = list(experiments) if not isinstance(experiments, Experiment) else [experiments]
    if not exps:
        raise DataError("no records given; pass at least one Experiment")
    rig = Rig() if rig is None else rig
    names = model_names(ext, rig)
    per = default_per_record(names) if per_record is None else tuple(per_record)
    res = fit_lsq(exps, rig, extension=ext, per_record=per, weights=CART_SPREAD,
                  theta0=theta0, max_nfev=max_nfev, fd_step=fd_step)
    return RecordsFit(
        extension=ext, rig=rig, names=tuple(names), per_record=per,
        record_names=res.record_names, theta=res.theta_records, fit_percent=res.fit_percent,
        cost=res.cost, success=res.success, message=res.message,
        n_evaluations=res.n_evaluations)


def loro_lsq(
    experiments: Sequence[Experiment],
    ext: Extension | None,
    rig: Rig | None = None,
    *,
    per_record: Sequence[str] | None = None,
    theta0: np.ndarray | None = None,
    max_nfev: int = 100,
    fd_step: float = 1e-3,
) -> LOROFit:
    """Leave-one-record-out least squares: fit on all records but one, predict it.

    Parameters
    ----------
    experiments : sequence of Experiment
        At least two records.
    ext, rig, per_record, max_nfev, fd_step
        As in ``fit_records_lsq``.
    theta0 : ndarray, shape (n_params,) or (n_records, n_params), optional
        Start of every fold (a fold starts from the rows of its training records).  Do not
        start from a fit that has seen the held-out record when the cost is flat (stick-
        slip friction): a fold that stops near its start then predicts with information
        from the record it should not know, and the held-out fit is optimistic
        (``docs/make_discrepancy_table.py`` fits every fold's chain of models from the
        linear fit of its training records instead).

    Returns
    -------
    LOROFit
        The held-out record is predicted with the per-record parameters averaged over the
        training records (``new_record_theta``).

    Raises
    ------
    DataError
        For fewer than two records.
    """
    exps = list(experiments)
    if len(exps) < 2:
        raise DataError("leave-one-record-out needs at least two records")
    rig = Rig() if rig is None else rig
    R = len(exps)
    names = model_names(ext, rig)
    per = default_per_record(names) if per_record is None else tuple(per_record)
    start = None if theta0 is None else np.array(
        np.broadcast_to(np.asarray(theta0, float), (R, len(names))))
    folds, fits, thetas = [], [], []
    for r in range(R):
        keep = [k for k in range(R) if k != r]
        fold = fit_records_lsq([exps[k] for k in keep], ext, rig, per_record=per,
                               theta0=None if start is None else start[keep],
                               max_nfev=max_nfev, fd_step=fd_step)
        th = new_record_theta(fold.theta, names, per)
        fits.append(fit_percent(exps[r].y_m, simulate_model(ext, rig, th[None], exps[r])[0]))
        thetas.append(th)
        folds.append(fold)
    return LOROFit(record_names=tuple(e.name for e in exps), fit_percent=np.array(fits),
                   theta=np.array(thetas), folds=tuple(folds))
