"""Output-error least squares (the report's ``lsqnonlin`` fit, section 2.2).

The parameters minimise ``sum_e sum_k ||y_e[k] - yhat_e[k; theta]||^2`` over one or more
experiments, with ``yhat`` the exact ZOH simulation from rest (or, for free decays with
``initial_state="estimate"``, from an initial state estimated with the parameters), on
each record's own time base: a uniform grid, or a logger's recorded stamps, each step
with its own exact hold (``Experiment.sim_dt``).
Positive parameters are optimised in log space (which makes the problem scale-free and
keeps masses positive); damping coefficients that may vanish (``c12, c23, ..., cb``) are
optimised on a linear scale with a zero lower bound.  The Jacobian is by forward
differences, evaluated in one batched simulator call.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._errors import DataError, ModelError
from ..data import Experiment, check_identifiable
from ..identified import identify
from ..metrics import fit_percent
from ..model.simulate import simulate_linear
from ..model.system import LinearModel, default_start
from ..model.system import log_scale_mask as _log_mask
from ..structure import check_structure

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
    x0 : ndarray, shape (n_experiments, 2 n_carts), or None
        Estimated initial positions (m) and velocities (m/s) per experiment with
        ``initial_state="estimate"``; None when every record starts from rest.
    jac_singular_values : ndarray, shape (n_columns,), or None
        Singular values of the final Jacobian with each column scaled to unit norm
        (parameters and estimated initial states), largest first; NaN where the Jacobian
        is not finite.  Read by :func:`bayesmodal.identified.identify`.
    jac_shape : tuple of int
        Shape ``(n_residuals, n_columns)`` of that Jacobian.
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
    x0: np.ndarray | None = None
    jac_singular_values: np.ndarray | None = None
    jac_shape: tuple[int, int] = (0, 0)

    @property
    def params(self) -> dict[str, float]:
        """Estimate as a name-to-value mapping."""
        return self.model.as_dict(self.theta)

    @property
    def stderr(self) -> np.ndarray:
        """Gauss-Newton standard errors, shape (n_params,)."""
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

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


INITIAL_STATES = ("rest", "estimate")


def check_records(model: LinearModel, experiments: Sequence[Experiment],
                  initial_state: str = "rest") -> None:
    """Refuse records that do not match the model or cannot identify its parameters.

    Parameters
    ----------
    model : LinearModel
    experiments : sequence of Experiment
    initial_state : {"rest", "estimate"}
        ``"estimate"`` admits free decays (records with no input).

    Raises
    ------
    DataError
        No records, a record with the wrong number of outputs, a record with no input when
        it starts from rest, or a record where nothing moves.
    ModelError
        Free decays only while ``g_v`` is unknown, or with nothing but the gain to fix the
        scale of masses and springs, or a layout whose unknowns no such record can
        identify (``structure.check_structure``); the message names what to add.
    """
    if initial_state not in INITIAL_STATES:
        raise ModelError(f"initial_state must be one of {INITIAL_STATES}, got {initial_state!r}")
    if not experiments:
        raise DataError("no experiments given")
    for e in experiments:
        if e.n_outputs != model.n_outputs:
            raise DataError(
                f"{e.source or e.name}: {e.n_outputs} outputs but the model has "
                f"{model.n_outputs} {'carts' if model.rig.is_chain else 'sensors'}"
            )
        if initial_state == "rest":
            check_identifiable(e)
        elif np.all(np.ptp(e.y_m, axis=0) == 0):
            raise DataError(f"{e.source or e.name}: every output is constant (no cart ever "
                            "moves); nothing is identifiable")
    if all(not np.any(e.v_volt != 0) for e in experiments):
        rig = model.rig
        if "g_v" in model.names:
            raise ModelError(
                "g_v cannot be estimated from free decays only (no record has an input); give "
                "the input gain (gain_n_v in the rig's [drive] table, from `bayesmodal "
                "static`), or add a forced record")
        free = rig.free_carts
        if not (any(s.known and (s.a in free or s.b in free) for s in rig.springs)
                or any(c.mass == "known" for c in rig.carts if c.name in free)):
            raise ModelError(
                "free decays fix only the ratios of masses, dampers and springs; add a known "
                "mass (mass = \"known\", mass_kg) or a known spring (known = true)")

    check_structure(model, experiments, initial_state)


def _check_experiments(model: LinearModel, experiments: Sequence[Experiment]) -> None:
    check_records(model, experiments, "rest")


def initial_state_guess(model: LinearModel, experiment: Experiment) -> np.ndarray:
    """Initial state from a record's first samples, shape (2 n_carts,): m and m/s.

    Carts with a position sensor take the first sample and the first difference, a
    velocity sensor gives its cart's first velocity; the others start at 0.
    """
    spec = getattr(model, "output_spec", None)
    if spec is not None:
        n = model.n_carts
        x0 = np.zeros(2 * n)
        first_step = (experiment.dt if experiment.is_uniform
                      else experiment.t_s[1] - experiment.t_s[0])
        for j, (dof, order) in enumerate(spec):
            col = experiment.y_m[:, j]
            if order == 0:
                x0[dof] = col[0]
                x0[n + dof] = (col[1] - col[0]) / first_step
            elif order == 1:
                x0[n + dof] = col[0]
        return x0
    n = model.n_carts
    out = model.output_index
    idx = np.arange(n) if out is None else out
    x0 = np.zeros(2 * n)
    x0[idx] = experiment.y_m[0]
    first_step = (experiment.dt if experiment.is_uniform
                  else experiment.t_s[1] - experiment.t_s[0])
    x0[n + idx] = (experiment.y_m[1] - experiment.y_m[0]) / first_step
    return x0


def residuals(model: LinearModel, theta: np.ndarray, experiments: Sequence[Experiment],
              x0: np.ndarray | None = None):
    """Stacked residuals ``y - yhat`` for a batch of parameter sets.

    Parameters
    ----------
    theta : ndarray, shape (nb, n_params)
    x0 : ndarray, shape (nb, n_experiments, 2 n_carts), optional
        Initial states (m, m/s); rest by default.

    Returns
    -------
    ndarray, shape (nb, sum_e N_e * n_outputs), m
    """
    parts = []
    for i, e in enumerate(experiments):
        yh = simulate_linear(model, theta, e.v_volt, e.sim_dt, None if x0 is None else x0[:, i])
        parts.append((e.y_m[None] - yh).reshape(theta.shape[0], -1))
    return np.concatenate(parts, axis=1)


def fit_lsq(
    experiments: Experiment | Sequence[Experiment],
    model: LinearModel,
    *,
    theta0: np.ndarray | None = None,
    max_nfev: int = 400,
    initial_state: str = "rest",
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
    initial_state : {"rest", "estimate"}
        ``"rest"`` (default): every record starts at rest.  ``"estimate"``: each record's
        initial positions and velocities are estimated with the parameters (free decays:
        records with no input and an initial displacement); see ``LSQResult.x0``.

    Returns
    -------
    LSQResult

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> from bayesmodal.model.simulate import simulate_linear
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
    check_records(model, experiments, initial_state)
    theta0 = default_start(model) if theta0 is None else model.check(np.asarray(theta0, float))
    n_p = model.n_params
    n_s = 2 * model.n_carts
    n_x = n_s * len(experiments) if initial_state == "estimate" else 0
    mask = np.r_[_log_mask(model), np.zeros(n_x, bool)]
    if n_x:
        x00 = np.concatenate([initial_state_guess(model, e) for e in experiments])
        # a unit step moves a position by a millimetre and a velocity by a centimetre/s
        x_scale = np.tile(np.r_[np.full(n_s // 2, 1e-3), np.full(n_s // 2, 1e-2)],
                          len(experiments))

    def to_z(theta):  # model parameters only
        z = np.array(theta, dtype=float)
        z[..., mask[:n_p]] = np.log(z[..., mask[:n_p]])
        return z

    def to_theta(z):
        th = np.array(z, dtype=float)
        with np.errstate(over="ignore", under="ignore"):  # such trial points: _res's barrier
            th[..., mask] = np.exp(th[..., mask])
        return th

    # Scale the linear-scale parameters so that a unit step is a sensible size.
    scale = np.where(mask[:n_p], 1.0, np.maximum(np.abs(theta0), 1e-3))
    if model.damping == "proportional":
        icb = model.names.index("cb")
        scale[icb] = max(abs(theta0[icb]), 1e-4)
    z0 = to_z(theta0) / scale
    lower = np.where(mask[:n_p], -np.inf, 0.0)
    upper = np.full(n_p, np.inf)
    z0 = np.clip(z0, lower + 1e-12 * ~mask[:n_p], upper)
    if n_x:  # initial states: unbounded, linear
        scale = np.r_[scale, x_scale]
        z0 = np.r_[z0, x00 / x_scale]
        lower = np.r_[lower, np.full(n_x, -np.inf)]
        upper = np.r_[upper, np.full(n_x, np.inf)]

    def split(ws):
        th = to_theta(ws * scale)
        if not n_x:
            return th, None
        return th[:, :n_p], th[:, n_p:].reshape(ws.shape[0], len(experiments), n_s)

    def fun(w):
        return _res(model, split(w[None]), experiments)[0]

    def jac(w):
        # forward differences, all perturbed parameter sets in one batched simulation
        h = 1e-7 * np.maximum(np.abs(w), 1.0)
        ws = np.repeat(w[None], w.size + 1, axis=0)
        for i in range(w.size):
            # step away from the zero bound
            ws[i + 1, i] += h[i]
        r = _res(model, split(ws), experiments)
        return ((r[1:] - r[0]) / h[:, None]).T

    sol = least_squares(fun, z0, jac=jac, bounds=(lower, upper), method="trf",
                        x_scale="jac", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-10)
    theta, x0_hat = split(sol.x[None])
    theta = theta[0]
    x0_hat = None if x0_hat is None else x0_hat[0]
    try:
        theta = model.check(theta)
    except ModelError as exc:  # pragma: no cover - bounds make this unreachable
        raise ModelError(f"least squares ended at impossible parameters: {exc}") from exc

    fits, sq = [], []
    for i, e in enumerate(experiments):
        yh = simulate_linear(model, theta, e.v_volt, e.sim_dt,
                             None if x0_hat is None else x0_hat[i])
        fits.append(fit_percent(e.y_m, yh))
        sq.append(((e.y_m - yh) ** 2).sum(axis=0))
    n_total = sum(e.n_samples for e in experiments)
    sigma = np.sqrt(np.sum(sq, axis=0) / n_total)

    # Covariance in theta space: J_theta = J_w / (scale * dtheta/dz)
    # (the initial states are nuisance parameters: the block of the full covariance is their
    # marginal covariance)
    Jw = sol.jac
    dtheta_dw = scale * np.where(mask, np.r_[theta, np.ones(n_x)], 1.0)
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
        x0=x0_hat,
        jac_singular_values=equilibrated_singular_values(Jw),
        jac_shape=(int(Jw.shape[0]), int(Jw.shape[1])),
    )


def equilibrated_singular_values(jac: np.ndarray) -> np.ndarray:
    """Singular values of a Jacobian whose columns are scaled to unit norm.

    Scaling the columns removes the parameters' units (a mass in kg and a damper in
    N s/m), so that a small singular value means a direction the residuals do not see,
    not a parameter measured in large units.  A zero column stays zero.

    Parameters
    ----------
    jac : ndarray, shape (n_residuals, n_columns)

    Returns
    -------
    ndarray, shape (n_columns,)
        Largest first; all NaN when the Jacobian is not finite.
    """
    jac = np.asarray(jac, float)
    if not np.all(np.isfinite(jac)):
        return np.full(jac.shape[1], np.nan)
    norms = np.linalg.norm(jac, axis=0)
    return np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), compute_uv=False)


def barrier_residuals(experiments: Sequence[Experiment], nb: int) -> np.ndarray:
    """Residuals of an inadmissible trial point: ``1000 max|y| + 1`` m on every sample.

    Returns
    -------
    ndarray, shape (nb, sum_e N_e * n_outputs), m
        A cost far above any fit's, for the rows of a batch that are not a model.
    """
    barrier = 1e3 * max(float(np.max(np.abs(e.y_m))) for e in experiments) + 1.0
    return np.full((nb, sum(e.n_samples * e.n_outputs for e in experiments)), barrier)


def _res(model, theta_x0, experiments):
    """Residuals of each trial point, a barrier where the point is not a model.

    The optimiser works on logarithms of the positive parameters; a long trial step can
    overflow one to ``inf`` (or a mass to 0), which the simulator rejects.  Such points
    get ``barrier_residuals``, so the trust region shrinks instead of the fit stopping
    with an error (measured: a damper overflowed on the pair benchmark's friction +
    offset data, seed 20007).
    """
    theta, x0 = theta_x0
    ok = model.valid(theta)
    if x0 is not None:
        ok &= np.all(np.isfinite(x0.reshape(x0.shape[0], -1)), axis=1)
    if np.all(ok):
        return residuals(model, theta, experiments, x0)
    r = barrier_residuals(experiments, theta.shape[0])
    if np.any(ok):
        r[ok] = residuals(model, theta[ok], experiments, None if x0 is None else x0[ok])
    return r
