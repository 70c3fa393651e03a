"""The optimiser coordinates and starts of each kind of fit (``_engine.Problem``).

``linear_problem``: the linear model, its positive parameters on a log scale, the others
(relative dampers, estimated initial states) on a linear scale divided by a typical size.
``extension_problem``: a model with effects, one vector for all records, in
``_lsq_common.coordinates`` scaled from the linear fit.  ``records_problem``: the same
coordinates with some parameters per record.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import LinearModel
from ..model.system import log_scale_mask as _log_mask
from ._engine import Problem, barrier_value
from .linear import initial_state_guess

#: ``least_squares`` settings of each kind of fit.
_LINEAR_SOLVE = dict(method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-10)
_EXT_SOLVE = dict(method="trf", xtol=1e-10, ftol=1e-10, gtol=1e-10, x_scale=1.0)
_RECORDS_SOLVE = dict(method="trf", xtol=1e-10, ftol=1e-10, gtol=1e-10)


def linear_problem(model: LinearModel, exps: Sequence[Experiment], theta0: np.ndarray,
                   initial_state: str, root_w: np.ndarray | None):
    """The linear fit's problem and its one start ``(z0, theta0)``.

    Positive parameters on a log scale (scale-free, masses stay positive); dampers that
    may vanish on a linear scale with a zero bound, divided by their start value (at
    least 1e-3; ``cb`` of proportional damping at least 1e-4); with ``initial_state=
    "estimate"`` each record's initial state in units of a millimetre and a centimetre
    per second, unbounded.
    """
    n_p, n_s, R = model.n_params, 2 * model.n_carts, len(exps)
    n_x = n_s * R if initial_state == "estimate" else 0
    mask = np.r_[_log_mask(model), np.zeros(n_x, bool)]

    z0 = np.array(theta0, dtype=float)
    z0[mask[:n_p]] = np.log(z0[mask[:n_p]])
    # Scale the linear-scale parameters so that a unit step is a sensible size.
    scale = np.where(mask[:n_p], 1.0, np.maximum(np.abs(theta0), 1e-3))
    if model.damping == "proportional":
        icb = model.names.index("cb")
        scale[icb] = max(abs(theta0[icb]), 1e-4)
    z0 = z0 / scale
    lower = np.where(mask[:n_p], -np.inf, 0.0)
    upper = np.full(n_p, np.inf)
    z0 = np.clip(z0, lower + 1e-12 * ~mask[:n_p], upper)
    index = np.tile(np.arange(n_p), (R, 1))
    if n_x:  # initial states: unbounded, linear
        x00 = np.concatenate([initial_state_guess(model, e) for e in exps])
        # a unit step moves a position by a millimetre and a velocity by a centimetre/s
        x_scale = np.tile(np.r_[np.full(n_s // 2, 1e-3), np.full(n_s // 2, 1e-2)], R)
        scale = np.r_[scale, x_scale]
        z0 = np.r_[z0, x00 / x_scale]
        lower = np.r_[lower, np.full(n_x, -np.inf)]
        upper = np.r_[upper, np.full(n_x, np.inf)]
        index = np.array([np.r_[np.arange(n_p), n_p + r * n_s + np.arange(n_s)]
                          for r in range(R)])
    scale_r, mask_r = scale[index[0]], mask[index[0]]

    def to_params(w):
        th = np.array(w * scale_r, dtype=float)
        with np.errstate(over="ignore", under="ignore"):  # such trial points: the barrier
            th[..., mask_r] = np.exp(th[..., mask_r])
        return th[:, :n_p], (th[:, n_p:] if n_x else None)

    p = Problem(kind="linear", experiments=tuple(exps), model=model, ext=None, index=index,
                to_params=to_params, lower=lower, upper=upper,
                fd_steps=lambda w: 1e-7 * np.maximum(np.abs(w), 1.0), root_w=root_w,
                barrier=barrier_value(exps), solve_options=_LINEAR_SOLVE, keep_start=False,
                lin_scale=scale, lin_mask=mask)
    return p, [(z0, np.asarray(theta0, float))]


def extension_problem(ext: Extension, coords, exps: Sequence[Experiment], fd_step: float,
                      root_w: np.ndarray | None) -> Problem:
    """A model with effects, one parameter vector for every record, in the coordinates
    ``coords`` (``_lsq_common.coordinates``); steps ``coords.fd_steps(fd_step)``."""
    steps = coords.fd_steps(fd_step)
    n = steps.size
    return Problem(
        kind="extension", experiments=tuple(exps), model=ext.linear_model(coords.rig),
        ext=ext, index=np.tile(np.arange(n), (len(exps), 1)),
        # a long trial step can overflow a log parameter to inf (or a mass to 0): such
        # points are not a model and get the barrier
        to_params=lambda w: (coords.to_theta(w, quiet=True), None),
        lower=coords.lower, upper=coords.upper, fd_steps=lambda z: steps, root_w=root_w,
        barrier=barrier_value(exps), solve_options=_EXT_SOLVE)


def extension_starts(coords, starts: Sequence[np.ndarray]) -> list:
    """``(z0, theta)`` of each start vector: kept strictly inside finite bounds, with an
    infinite value (e.g. "no saturation") replaced by the upper bound or 1e3."""
    out = []
    for start in starts:
        w0 = coords.to_opt(start)
        w0 = np.where(np.isfinite(w0), w0,
                      np.where(np.isfinite(coords.upper), coords.upper, 1e3))
        out.append((np.clip(w0, coords.lower, coords.upper), start))
    return out


def records_problem(ext: Extension | None, model: LinearModel, coords,
                    exps: Sequence[Experiment], names: Sequence[str],
                    per: Sequence[str], theta0: np.ndarray, fd_step: float,
                    root_w: np.ndarray | None, cart_spread: bool):
    """Several records, the parameters ``per`` one per record, the others shared.

    ``z`` holds the shared coordinates first, then each per-record parameter for every
    record in turn.  With ``cart_spread`` each record's residuals are divided, output by
    output, by the spread of the measured signal, so that the cost is ``0.5 sum_{r,j}
    (1 - fit_rj / 100)^2``.  Returns the problem and its start ``(z0, theta0)``.
    """
    R, P = theta0.shape
    shared = [i for i, n in enumerate(names) if n not in per]
    own = [list(names).index(q) for q in per]
    n_sh = len(shared)
    index = np.empty((R, P), dtype=int)
    index[:, shared] = np.arange(n_sh)
    for j, i in enumerate(own):
        index[:, i] = n_sh + j * R + np.arange(R)
    n_z = n_sh + len(own) * R
    lower, upper, steps = np.empty(n_z), np.empty(n_z), np.empty(n_z)
    step = coords.fd_steps(fd_step)
    for r in range(R):
        lower[index[r]], upper[index[r]], steps[index[r]] = coords.lower, coords.upper, step
    w = coords.to_opt(theta0)
    z0 = np.empty(n_z)
    for r in reversed(range(R)):  # the shared values of the first record
        z0[index[r]] = w[r]
    norms = (tuple(np.linalg.norm(e.y_m - e.y_m.mean(axis=0), axis=0) for e in exps)
             if cart_spread else None)
    p = Problem(kind="records", experiments=tuple(exps), model=model, ext=ext, index=index,
                to_params=lambda w: (coords.to_theta(w), None), lower=lower, upper=upper,
                fd_steps=lambda z: steps, root_w=root_w, norms=norms,
                barrier=barrier_value(exps), solve_options=_RECORDS_SOLVE,
                jac_all_columns=False)
    return p, [(np.clip(z0, lower, upper), theta0)]
