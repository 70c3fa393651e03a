"""Steps of the linear model's least squares (:func:`bayesmodal.fit.fit_lsq`).

The checks of the records against the model (``check_records``), the first guess of a free
decay's initial state, the stacked residuals of a batch of parameter sets (from rest or
from given initial states, each record on its own time base: a uniform grid, or a
logger's recorded stamps, each step with its own exact hold, ``Experiment.sim_dt``), the
barrier of a trial point that is not a model, and the Jacobian's equilibrated spectrum.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError, ModelError
from ..data import Experiment, check_identifiable
from ..model.simulate import simulate_linear
from ..model.system import LinearModel, default_start
from ..structure import check_structure

__all__ = ["check_records", "initial_state_guess", "residuals", "barrier_residuals",
           "equilibrated_singular_values", "default_start", "INITIAL_STATES"]


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
        model.check_record(e)
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


def initial_state_guess(model: LinearModel, experiment: Experiment) -> np.ndarray:
    """Initial state from a record's first samples.

    Carts with a position sensor take the first sample and the first difference, a
    velocity sensor gives its cart's first velocity; the others start at 0.

    Parameters
    ----------
    model : LinearModel
    experiment : Experiment

    Returns
    -------
    ndarray, shape (2 n_carts,)
        Positions (m), then velocities (m/s).
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
    model : LinearModel
    theta : ndarray, shape (nb, n_params)
    experiments : sequence of Experiment
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

    Parameters
    ----------
    experiments : sequence of Experiment
    nb : int
        Number of rows (trial points).

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
