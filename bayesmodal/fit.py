"""Output-error least squares (the report's ``lsqnonlin`` fit, section 2.2).

The parameters minimise ``sum_e sum_k ||y_e[k] - yhat_e[k; theta]||^2`` over one or more
experiments, with ``yhat`` the exact ZOH simulation from rest.  Positive parameters are
optimised in log space (which makes the problem scale-free and keeps masses positive);
damping coefficients that may vanish (``c12, c23, ..., cb``) are optimised on a linear scale
with a zero lower bound.  The Jacobian is by forward differences, evaluated in one batched
simulator call.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ._errors import DataError, ModelError
from .data import Experiment, check_identifiable
from .metrics import fit_percent
from .simulate import simulate_linear
from .system import LinearModel

__all__ = ["LSQResult", "fit_lsq", "default_start"]


@dataclass(frozen=True)
class LSQResult:
    """Result of an output-error least-squares fit.

    Attributes
    ----------
    model : LinearModel
    theta : ndarray, shape (n_params,)
        Estimate in ``model.names`` order.
    fit_percent : ndarray, shape (n_experiments, n_outputs)
        Fit percentage per experiment and output.
    cost : float
        Half the sum of squared residuals, m^2.
    sigma_m : ndarray, shape (n_outputs,)
        RMS residual per output (pooled over experiments), m.
    cov : ndarray, shape (n_params, n_params)
        Gauss-Newton covariance ``s^2 (J^T J)^-1`` (white-noise assumption: optimistic for
        correlated residuals).
    success : bool
    message : str
    n_evaluations : int
    """

    model: LinearModel
    theta: np.ndarray
    fit_percent: np.ndarray
    cost: float
    sigma_m: np.ndarray
    cov: np.ndarray
    success: bool
    message: str
    n_evaluations: int

    @property
    def params(self) -> dict[str, float]:
        """Estimate as a name-to-value mapping."""
        return self.model.as_dict(self.theta)

    @property
    def stderr(self) -> np.ndarray:
        """Gauss-Newton standard errors, shape (n_params,)."""
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))


def default_start(model: LinearModel) -> np.ndarray:
    """A neutral starting point: g_v 5.25 N/V (nominal), masses 1 kg, small damping."""
    n = model.n_carts
    if model.damping == "proportional":
        tail = [1.0, 1e-4]
    else:
        tail = [1.0] * n + [0.1] * (n - 1)
    return np.array([5.25] + [1.0] * n + tail)


def _log_mask(model: LinearModel) -> np.ndarray:
    n = model.n_carts
    mask = np.zeros(model.n_params, bool)
    mask[: 1 + n] = True  # g_v and masses
    if model.damping == "free":
        mask[1 + n : 1 + 2 * n] = True  # absolute dampers are clearly non-zero on a rig
    else:
        mask[1 + n] = True  # ca
    return mask


def _check_experiments(model: LinearModel, experiments: Sequence[Experiment]) -> None:
    if not experiments:
        raise DataError("no experiments given")
    for e in experiments:
        if e.n_outputs != model.n_carts:
            raise DataError(
                f"{e.source or e.name}: {e.n_outputs} outputs but the model has "
                f"{model.n_carts} carts"
            )
        check_identifiable(e)


def residuals(model: LinearModel, theta: np.ndarray, experiments: Sequence[Experiment]):
    """Stacked residuals ``y - yhat`` for a batch of parameter sets.

    Parameters
    ----------
    theta : ndarray, shape (nb, n_params)

    Returns
    -------
    ndarray, shape (nb, sum_e N_e * n_outputs), m
    """
    parts = []
    for e in experiments:
        yh = simulate_linear(model, theta, e.v_volt, e.dt)
        parts.append((e.y_m[None] - yh).reshape(theta.shape[0], -1))
    return np.concatenate(parts, axis=1)


def fit_lsq(
    experiments: Experiment | Sequence[Experiment],
    model: LinearModel,
    *,
    theta0: np.ndarray | None = None,
    max_nfev: int = 400,
) -> LSQResult:
    """Output-error least-squares fit of the linear model.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    model : LinearModel
    theta0 : ndarray, shape (n_params,), optional
        Starting point (``default_start(model)`` if omitted).
    max_nfev : int
        Maximum number of Jacobian/residual evaluations.

    Returns
    -------
    LSQResult

    Examples
    --------
    >>> from bayesmodal.system import LinearModel, Rig
    >>> from bayesmodal.simulate import simulate_linear
    >>> model = LinearModel(Rig(), "proportional")
    >>> truth = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])
    >>> t = np.arange(2000) * 0.005
    >>> v = (t < 0.05) * 3.0
    >>> e = Experiment(t, v, simulate_linear(model, truth, v, 0.005))
    >>> res = fit_lsq(e, model)
    >>> bool(np.allclose(res.theta, truth, rtol=1e-4))
    True
    """
    if isinstance(experiments, Experiment):
        experiments = [experiments]
    experiments = list(experiments)
    _check_experiments(model, experiments)
    theta0 = default_start(model) if theta0 is None else model.check(np.asarray(theta0, float))
    mask = _log_mask(model)

    def to_z(theta):
        z = np.array(theta, dtype=float)
        z[..., mask] = np.log(z[..., mask])
        return z

    def to_theta(z):
        th = np.array(z, dtype=float)
        th[..., mask] = np.exp(th[..., mask])
        return th

    # Scale the linear-scale parameters so that a unit step is a sensible size.
    scale = np.where(mask, 1.0, np.maximum(np.abs(theta0), 1e-3))
    if model.damping == "proportional":
        scale[-1] = max(abs(theta0[-1]), 1e-4)
    z0 = to_z(theta0) / scale
    lower = np.where(mask, -np.inf, 0.0)
    upper = np.full(model.n_params, np.inf)
    z0 = np.clip(z0, lower + 1e-12 * ~mask, upper)

    def fun(w):
        return residuals(model, to_theta(w[None] * scale), experiments)[0]

    def jac(w):
        # forward differences, all perturbed parameter sets in one batched simulation
        h = 1e-7 * np.maximum(np.abs(w), 1.0)
        ws = np.repeat(w[None], model.n_params + 1, axis=0)
        for i in range(model.n_params):
            # step away from the zero bound
            ws[i + 1, i] += h[i]
        r = residuals(model, to_theta(ws * scale), experiments)
        return ((r[1:] - r[0]) / h[:, None]).T

    sol = least_squares(fun, z0, jac=jac, bounds=(lower, upper), method="trf",
                        x_scale="jac", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-10)
    theta = to_theta(sol.x * scale)
    try:
        theta = model.check(theta)
    except ModelError as exc:  # pragma: no cover - bounds make this unreachable
        raise ModelError(f"least squares ended at impossible parameters: {exc}") from exc

    fits, sq = [], []
    for e in experiments:
        yh = simulate_linear(model, theta, e.v_volt, e.dt)
        fits.append(fit_percent(e.y_m, yh))
        sq.append(((e.y_m - yh) ** 2).sum(axis=0))
    n_total = sum(e.n_samples for e in experiments)
    sigma = np.sqrt(np.sum(sq, axis=0) / n_total)

    # Covariance in theta space: J_theta = J_w / (scale * dtheta/dz)
    Jw = sol.jac
    dtheta_dw = scale * np.where(mask, theta, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):  # a log parameter ended at 0
        J = Jw / dtheta_dw
    dof = max(Jw.shape[0] - model.n_params, 1)
    s2 = 2 * sol.cost / dof
    cov = np.full((model.n_params, model.n_params), np.nan)
    if np.all(np.isfinite(J)):
        try:
            cov = s2 * np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            pass
    return LSQResult(
        model=model,
        theta=theta,
        fit_percent=np.array(fits),
        cost=float(sol.cost),
        sigma_m=sigma,
        cov=cov,
        success=bool(sol.success),
        message=str(sol.message),
        n_evaluations=int(sol.nfev),
    )
