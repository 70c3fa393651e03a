"""The local search of :func:`bayesmodal.fit.fit_lsq`: one path for every model and layout.

A :class:`Problem` states a fit in optimiser coordinates ``z``: which entries of ``z`` make
each record's coordinate vector (``index``: a parameter shared by the records has one
entry, a per-record parameter or an estimated initial state one per record), how those
coordinates become parameters (``to_params``), the bounds, the forward-difference steps
and how each record's residuals are simulated, weighted and refused (a barrier for a
point that is not a model).  :func:`local_search` runs ``scipy.optimize.least_squares``
(``trf``) from each start and keeps the best; :func:`summarize` turns the best point into
an :class:`~bayesmodal.fit.result.LSQResult`.

Three families of problems (``kind``) keep the arithmetic the fits have always had, so
their numbers stay the same to the bit:

``"linear"``
    The linear model with shared parameters: log coordinates for the positive
    parameters, steps ``1e-7 max(|z|, 1)``, ``x_scale="jac"``, tolerances 1e-12 (gtol
    1e-10), no return to the start, and the Gauss-Newton covariance at the end.
``"extension"``
    A model with effects and shared parameters (``_lsq_common.coordinates``), fixed steps,
    ``x_scale=1``, tolerances 1e-10; a search that ends above its start returns the start.
``"records"``
    Per-record parameters (or the ``"cart_spread"`` weighting): the same coordinates,
    SciPy's default ``x_scale``, the Jacobian built record by record on the columns
    each record depends on, the linear model simulated by the effects' kernel.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .._errors import ModelError
from ..data import Experiment
from ..metrics import fit_percent
from ..model.effects._base import Extension
from ..model.simulate import simulate_linear
from ..model.system import LinearModel
from ._lsq_common import fd_jacobian
from ._threads import thread_map
from .linear import equilibrated_singular_values
from .residuals import new_record_theta, simulate_model
from .result import LSQResult

KINDS = ("linear", "extension", "records")


@dataclass(frozen=True)
class Problem:
    """A least-squares fit in optimiser coordinates (module docstring).

    Attributes
    ----------
    kind : {"linear", "extension", "records"}
    experiments : tuple of Experiment
    model : LinearModel
    ext : Extension or None
    index : ndarray of int, shape (n_records, n_coords)
        Entry of ``z`` of each coordinate of each record's vector (parameters, then the
        record's initial state when it is estimated).
    to_params : callable
        ``(nb, n_coords)`` coordinates to ``(theta (nb, n_params), x0 (nb, 2 n_carts) or
        None)``.
    lower, upper : ndarray, shape (n_z,)
        Bounds of ``z``.
    fd_steps : callable
        ``z`` to the forward-difference step of each entry, shape (n_z,).
    root_w : ndarray, shape (n_records,), or None
        Square roots of the records' weights (None: unweighted).
    norms : tuple of ndarray, shape (n_outputs,) each, or None
        Divisor of each record's residuals per output (the ``"cart_spread"`` weighting).
    barrier : float
        Residual of every sample of a point that is not a model, m.
    solve_options : dict
        Passed to ``least_squares``.
    jac_all_columns : bool
        A shared fit: every record differentiated along every entry of ``z`` in one
        batch, rather than record by record along its own entries.
    keep_start : bool
        Return the start when the search ends at a higher cost.
    lin_scale, lin_mask : ndarray, shape (n_z,), or None
        The linear fit's divisors and log mask of ``z`` (for the covariance).
    """

    kind: str
    experiments: tuple[Experiment, ...]
    model: LinearModel
    ext: Extension | None
    index: np.ndarray
    to_params: Callable
    lower: np.ndarray
    upper: np.ndarray
    fd_steps: Callable
    root_w: np.ndarray | None = None
    norms: tuple | None = None
    barrier: float = 1.0
    solve_options: dict = field(default_factory=dict)
    jac_all_columns: bool = True
    keep_start: bool = True
    lin_scale: np.ndarray | None = None
    lin_mask: np.ndarray | None = None

    @property
    def n_z(self) -> int:
        """Number of optimiser coordinates."""
        return self.lower.size


def barrier_value(experiments: Sequence[Experiment]) -> float:
    """``1000 max|y| + 1`` m (``linear.barrier_residuals``)."""
    return 1e3 * max(float(np.max(np.abs(e.y_m))) for e in experiments) + 1.0


def simulate(p: Problem, e: Experiment, theta: np.ndarray, x0: np.ndarray | None
             ) -> np.ndarray:
    """Outputs of record ``e`` for a batch ``theta`` (nb, n_params), shape (nb, N, n)."""
    if p.kind == "records":
        return simulate_model(p.ext, p.model.rig, theta, e)
    if p.ext is not None:
        return p.ext.simulate(p.model.rig, theta, e.v_volt, e.dt)
    return simulate_linear(p.model, theta, e.v_volt, e.sim_dt, x0)


def _valid(p: Problem, theta: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
    ok = p.model.valid(theta) if p.ext is None else p.ext.valid(p.model.rig, theta)
    if x0 is not None:
        ok &= np.all(np.isfinite(x0), axis=1)
    return ok


def _raw(p: Problem, r: int, theta: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
    """Weighted residuals of record ``r`` for admissible parameter sets, (nb, N_r n)."""
    e = p.experiments[r]
    res = e.y_m[None] - simulate(p, e, theta, x0)
    if p.norms is not None:
        res = res / p.norms[r]
    res = res.reshape(res.shape[0], -1)
    return res if p.root_w is None else res * p.root_w[r]


def params_residuals(p: Problem, r: int, theta: np.ndarray, x0: np.ndarray | None = None
                     ) -> np.ndarray:
    """Weighted residuals of record ``r`` for a batch of parameter sets, a barrier where a
    set is not a model (a long trial step overflowed a log parameter, or crossed a rule
    the box cannot state, e.g. backlash's ``m_p < m1``): the trust region then shrinks
    instead of the fit stopping with an error.

    Returns
    -------
    ndarray, shape (nb, N_r * n_outputs)
    """
    e = p.experiments[r]
    ok = _valid(p, theta, x0)
    out = np.full((theta.shape[0], e.n_samples * e.n_outputs), p.barrier)
    if np.any(ok):
        out[ok] = _raw(p, r, theta[ok], None if x0 is None else x0[ok])
    return out


def theta_residuals(p: Problem, theta: np.ndarray) -> np.ndarray:
    """Stacked residuals of every record for shared parameter sets ``theta`` (nb,
    n_params), shape (nb, n_residuals)."""
    return _stacked(p, [(theta, None)] * len(p.experiments))


def _stacked(p: Problem, params) -> np.ndarray:
    """Every record's residuals side by side, for each record's ``(theta, x0)`` batch.

    A row is a barrier on every record when its point is not a model on one.  The array
    is laid out in memory as the shared fits always had it (the linear model's straight
    from the records' residuals, the extended model's in a new array), since
    ``least_squares`` rounds its products differently on another layout."""
    ok = np.logical_and.reduce([_valid(p, th, x0) for th, x0 in params])
    if p.kind == "linear" and np.all(ok):
        return np.concatenate([_raw(p, r, th, x0) for r, (th, x0) in enumerate(params)],
                              axis=1)
    rows = sum(e.n_samples * e.n_outputs for e in p.experiments)
    out = np.full((ok.size, rows), p.barrier)
    if np.any(ok):
        out[ok] = np.concatenate([_raw(p, r, th[ok], None if x0 is None else x0[ok])
                                  for r, (th, x0) in enumerate(params)], axis=1)
    return out


def _z_residuals(p: Problem, zs: np.ndarray) -> np.ndarray:
    """Residuals of a batch of points ``zs`` (nb, n_z) of a shared fit."""
    return _stacked(p, [p.to_params(zs[:, p.index[r]]) for r in range(len(p.experiments))])


def _record_z(p: Problem, r: int, zs: np.ndarray) -> np.ndarray:
    return params_residuals(p, r, *p.to_params(zs[:, p.index[r]]))


def residual_vector(p: Problem, z: np.ndarray) -> np.ndarray:
    """All residuals at one point ``z``, shape (n_residuals,)."""
    if p.jac_all_columns:
        return _z_residuals(p, z[None])[0]
    return np.concatenate([_record_z(p, r, z[None])[0] for r in range(len(p.experiments))])


def jacobian(p: Problem, z: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian at ``z``, shape (n_residuals, n_z), each step away from
    an upper bound: a shared fit in one batch of points for every record, a fit with
    per-record parameters record by record along the entries it depends on."""
    steps = p.fd_steps(z)
    if p.jac_all_columns:
        return fd_jacobian(lambda zs: _z_residuals(p, zs), z, range(p.n_z), steps, p.upper)
    rows = [e.n_samples * e.n_outputs for e in p.experiments]
    J = np.zeros((sum(rows), p.n_z))
    start = 0
    for r, n in enumerate(rows):
        cols = np.unique(p.index[r])
        J[start:start + n, cols] = fd_jacobian(lambda zs, r=r: _record_z(p, r, zs), z, cols,
                                               steps, p.upper)
        start += n
    return J


def decode(p: Problem, z: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Each record's parameters (n_records, n_params) and initial state (n_records,
    2 n_carts; None from rest) at ``z``."""
    parts = [p.to_params(z[None][:, p.index[r]]) for r in range(len(p.experiments))]
    theta = np.concatenate([t for t, _ in parts])
    x0 = None if parts[0][1] is None else np.concatenate([x for _, x in parts])
    return theta, x0


@dataclass(frozen=True)
class Best:
    """The best end of the local searches: each record's parameters and initial state,
    the start it came from, SciPy's result and the evaluations of all searches."""

    theta: np.ndarray
    x0: np.ndarray | None
    start: np.ndarray
    sol: object
    n_evaluations: int


def local_search(p: Problem, starts: Sequence[tuple[np.ndarray, np.ndarray]],
                 max_nfev: int) -> Best:
    """``least_squares`` from each ``(z0, theta_start)``; the lowest final cost wins.

    With ``keep_start`` a search that ends above its start returns the start (the
    shared extended fit its ``theta_start`` as given, the others their decoded ``z0``).
    The searches run side by side on the fits' threads (``_threads``), with the numbers
    of one thread."""
    starts = list(starts)

    def search(start):
        return least_squares(lambda z: residual_vector(p, z), start[0],
                             jac=lambda z: jacobian(p, z), bounds=(p.lower, p.upper),
                             max_nfev=max_nfev, **p.solve_options)

    best, cost_best, n_eval = None, np.inf, 0
    for (z0, start), sol in zip(starts, thread_map(search, starts), strict=True):
        n_eval += int(sol.nfev)
        z, cost = sol.x, np.sum(sol.fun**2)
        if p.keep_start:
            cost_start = np.sum(residual_vector(p, z0) ** 2)
            if not cost <= cost_start:
                z, cost = z0, cost_start
        theta, x0 = decode(p, z)
        if p.kind == "extension":
            theta = (np.array(start, dtype=float)[None] if z is z0
                     else p.ext.check(p.model.rig, theta))
        elif p.kind == "linear":
            try:
                theta = p.model.check(theta)
            except ModelError as exc:  # pragma: no cover - bounds make this unreachable
                raise ModelError(f"least squares ended at impossible parameters: {exc}"
                                 ) from exc
        if best is None or cost < cost_best:
            best, cost_best = (theta, x0, start, sol), cost
    return Best(*best, n_evaluations=n_eval)


def summarize(p: Problem, best: Best, *, weights: np.ndarray | None, linear, per_record=(),
              names: Sequence[str] = ()) -> LSQResult:
    """The :class:`LSQResult` of the best point: fits, cost, RMS residual, and for the
    linear model the Gauss-Newton covariance and the Jacobian's singular values."""
    exps, sol = p.experiments, best.sol
    fits, sq = [], []
    for r, e in enumerate(exps):
        x0 = None if best.x0 is None else best.x0[r]
        if p.kind == "records":
            yh = simulate_model(p.ext, p.model.rig, best.theta[r:r + 1], e)[0]
        elif p.ext is not None:
            yh = p.ext.simulate(p.model.rig, best.theta[r], e.v_volt, e.dt)
        else:
            yh = simulate_linear(p.model, best.theta[r], e.v_volt, e.sim_dt, x0)
        fits.append(fit_percent(e.y_m, yh))
        sq.append(((e.y_m - yh) ** 2).sum(axis=0))
    fits = np.array(fits)
    w = np.ones(len(exps)) if weights is None else weights
    if p.kind == "linear":
        cost = float(sol.cost)
    elif p.norms is not None:
        cost = 0.5 * float(np.sum((1 - fits / 100) ** 2))
    else:
        cost = 0.5 * float(np.sum(w[:, None] * np.array(sq)))
    n_total = sum(e.n_samples for e in exps)
    per = tuple(per_record)
    if p.kind == "records":
        theta = new_record_theta(best.theta, names, per) if per else best.theta[0].copy()
    else:
        theta = best.theta[0]
    extra = _linear_extras(p, best, theta) if p.kind == "linear" else {}
    return LSQResult(
        model=p.model, theta=theta, fit_percent=fits, cost=cost,
        sigma_m=np.sqrt(np.sum(sq, axis=0) / n_total), cov=extra.pop("cov", None),
        success=bool(sol.success), message=str(sol.message),
        n_evaluations=best.n_evaluations, extension=p.ext, linear=linear,
        theta_start=best.start, weights=weights, per_record=per,
        record_names=tuple(e.name for e in exps),
        theta_records=best.theta if p.kind == "records" else None, **extra)


def _linear_extras(p: Problem, best: Best, theta: np.ndarray) -> dict:
    """Covariance, initial states and Jacobian spectrum of a linear fit."""
    sol = best.sol
    n_p = p.model.n_params
    n_x = p.n_z - n_p
    # Covariance in theta space: J_theta = J_w / (scale * dtheta/dz)
    # (the initial states are nuisance parameters: the block of the full covariance is their
    # marginal covariance)
    Jw = sol.jac
    dtheta_dw = p.lin_scale * np.where(p.lin_mask, np.r_[theta, np.ones(n_x)], 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):  # a log parameter ended at 0
        J = Jw / dtheta_dw
    dof = max(Jw.shape[0] - n_p - n_x, 1)
    s2 = 2 * sol.cost / dof
    cov = np.full((n_p, n_p), np.nan)
    if np.all(np.isfinite(J)):
        try:
            cov = s2 * np.linalg.inv(J.T @ J)[:n_p, :n_p]
        except np.linalg.LinAlgError:
            pass
    return dict(cov=cov, x0=best.x0, jac_singular_values=equilibrated_singular_values(Jw),
                jac_shape=(int(Jw.shape[0]), int(Jw.shape[1])))
