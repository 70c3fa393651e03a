"""Least squares of one model on several records, with per-record parameters, and its
leave-one-record-out check.

The records of the ECP rig share the physics (masses, dampers, friction levels, ...) but
ask for their own drive gain and amplifier offset (``bayesmodal.inference.records``).
``fit_records_lsq`` fits them jointly: every parameter is shared except those named in
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

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..metrics import fit_percent
from ..model.effects._base import Extension
from ..model.effects._input import linear_lanes_run
from ..model.system import LinearModel, Rig
from ._lsq_common import check_outputs, coordinates, fd_jacobian, solve
from .linear import fit_lsq

__all__ = ["RecordsFit", "LOROFit", "fit_records_lsq", "loro_lsq", "new_record_theta",
           "simulate_model"]


@dataclass(frozen=True)
class RecordsFit:
    """A joint least-squares fit of several records.

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


def _names(ext: Extension | None, rig: Rig) -> tuple[str, ...]:
    return LinearModel(rig, "free").names if ext is None else ext.names(rig)


def simulate_model(ext: Extension | None, rig: Rig, theta: np.ndarray, e: Experiment
                   ) -> np.ndarray:
    """Cart positions of one record for a batch of parameter sets.

    Parameters
    ----------
    ext : Extension or None
        None for the linear free-damping model.
    theta : ndarray, shape (nb, n_params)

    Returns
    -------
    ndarray, shape (nb, N, n_outputs), m
    """
    theta = np.atleast_2d(np.asarray(theta, dtype=float))
    if ext is not None:
        return ext.simulate(rig, theta, e.v_volt, e.dt)
    model = LinearModel(rig, "free")
    if not np.all(model.valid(theta)):
        raise ModelError("linear model: impossible parameters (masses and dampers must be "
                         "positive, relative dampers >= 0)")
    x0 = np.zeros((theta.shape[0], 2 * rig.n_carts))
    return linear_lanes_run(rig, np.ascontiguousarray(theta), np.asarray(e.v_volt, float),
                            float(e.dt), x0)


def new_record_theta(theta: np.ndarray, names: Sequence[str], per_record: Sequence[str]
                     ) -> np.ndarray:
    """The parameter vector of a record not in the fit.

    Per-record parameters are averaged over the fitted records: geometrically for
    ``g_v`` (a positive scale), arithmetically otherwise.

    Parameters
    ----------
    theta : ndarray, shape (n_records, n_params)
    names : sequence of str
    per_record : sequence of str

    Returns
    -------
    ndarray, shape (n_params,)
    """
    theta = np.asarray(theta, dtype=float)
    out = theta[0].copy()
    for p in per_record:
        i = list(names).index(p)
        col = theta[:, i]
        out[i] = np.exp(np.mean(np.log(col))) if p == "g_v" else np.mean(col)
    return out


def _default_per_record(names) -> tuple[str, ...]:
    return ("g_v",) + (("v_offset",) if "v_offset" in names else ())


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
    """Joint least squares of several records with per-record parameters.

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
    check_outputs(exps, rig, "; use a rig description with as many carts")
    names = _names(ext, rig)
    per = _default_per_record(names) if per_record is None else tuple(per_record)
    unknown = [p for p in per if p not in names]
    if unknown:
        raise ConfigError(f"per_record {unknown} are not parameters of the model {names}; "
                          "name model parameters only")
    R, P = len(exps), len(names)
    p_lin = LinearModel(rig, "free").n_params
    if theta0 is None:
        lin = fit_lsq(exps, LinearModel(rig, "free"))
        start = np.array(lin.theta, float) if ext is None else ext.null_theta(rig, lin.theta)
        theta0 = np.tile(start, (R, 1))
    theta0 = np.array(np.broadcast_to(np.asarray(theta0, float), (R, P)))
    valid = (LinearModel(rig, "free").valid(theta0) if ext is None else ext.valid(rig, theta0))
    if not np.all(valid):
        raise ModelError(f"theta0 is not admissible for {names}; start inside the prior "
                         "bounds (masses, dampers, friction levels >= 0)")

    # optimiser coordinates, per parameter of one record's vector
    coords = coordinates(ext, rig, theta0[0, :p_lin])
    lo, hi = coords.lower, coords.upper
    from_opt = coords.to_theta

    shared = [i for i, n in enumerate(names) if n not in per]
    own = [names.index(p) for p in per]
    n_sh = len(shared)

    def unpack(z):  # (nb, n_z) -> (nb, R, P) optimiser coordinates per record
        z = np.atleast_2d(z)
        w = np.empty((z.shape[0], R, P))
        w[:, :, shared] = z[:, None, :n_sh]
        w[:, :, own] = z[:, n_sh:].reshape(z.shape[0], len(own), R).transpose(0, 2, 1)
        return w

    def pack(theta):  # (R, P) -> (n_z,)
        w = coords.to_opt(theta)
        return np.r_[w[0, shared], w[:, own].T.ravel()]

    norms = [np.linalg.norm(e.y_m - e.y_m.mean(axis=0), axis=0) for e in exps]
    z_lo = np.r_[lo[shared], np.repeat(lo[own], R)]
    z_hi = np.r_[hi[shared], np.repeat(hi[own], R)]

    def record_resid(r, w_r):  # w_r (nb, P) optimiser coordinates -> (nb, N * n)
        yh = simulate_model(ext, rig, from_opt(w_r), exps[r])
        res = (exps[r].y_m[None] - yh) / norms[r]
        return res.reshape(res.shape[0], -1)

    def fun(z):
        w = unpack(z)[0]
        return np.concatenate([record_resid(r, w[r:r + 1])[0] for r in range(R)])

    n_z = n_sh + len(own) * R
    step = coords.fd_steps(fd_step)
    steps = np.r_[step[shared], np.repeat(step[own], R)]

    def jac(z):  # record by record: its residuals depend on the shared and its own columns
        blocks = []
        for r in range(R):
            cols = list(range(n_sh)) + [n_sh + j * R + r for j in range(len(own))]
            d = fd_jacobian(lambda zs, r=r: record_resid(r, unpack(zs)[:, r]), z, cols, steps,
                            z_hi)
            J = np.zeros((d.shape[0], n_z))
            J[:, cols] = d
            blocks.append(J)
        return np.concatenate(blocks, axis=0)

    z0 = np.clip(pack(theta0), z_lo, z_hi)
    sol = solve(fun, z0, jac, z_lo, z_hi, max_nfev)
    z = sol.x if np.sum(sol.fun**2) <= np.sum(fun(z0) ** 2) else z0
    theta = from_opt(unpack(z)[0])
    fits = np.array([fit_percent(e.y_m, simulate_model(ext, rig, theta[r:r + 1], e)[0])
                     for r, e in enumerate(exps)])
    return RecordsFit(
        extension=ext, rig=rig, names=tuple(names), per_record=per,
        record_names=tuple(e.name for e in exps), theta=theta, fit_percent=fits,
        cost=0.5 * float(np.sum((1 - fits / 100) ** 2)), success=bool(sol.success),
        message=str(sol.message), n_evaluations=int(sol.nfev))


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
    names = _names(ext, rig)
    per = _default_per_record(names) if per_record is None else tuple(per_record)
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
