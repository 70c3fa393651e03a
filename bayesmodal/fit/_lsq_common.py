"""Optimiser coordinates of a model with effects, and the forward differences of
:func:`bayesmodal.fit.fit_lsq`.

A fit of a model with effects, one parameter vector for all records or some parameters
per record, works on the linear free-damping parameters followed by the extension's, in
the same optimiser coordinates: log for the positive linear parameters
(``log_scale_mask``), the relative dampers divided by their size in a reference fit (at
least 1e-3) with a zero lower bound, and the extension's parameters in the extension's
own coordinates (``Extension.to_opt``) divided by their typical size
(``ParamSpec.scale``), within ``Extension.opt_bounds``.  It is differentiated by forward
differences that step away from an upper bound, with steps of 1e-6 (log) and 1e-4
(linear) for the linear parameters and ``fd_step`` for the extension's (larger than the
jumps of a stick-slip cost); ``_engine`` solves by ``trf`` at tolerances 1e-10.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import DataError
from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig, log_scale_mask


def check_outputs(experiments: Sequence[Experiment], rig: Rig, hint: str = "") -> None:
    """Raise ``DataError`` for a record whose outputs are not one per cart of ``rig``
    (``hint`` ends the message)."""
    for e in experiments:
        if e.n_outputs != rig.n_carts:
            raise DataError(f"{e.name}: {e.n_outputs} outputs but the rig has {rig.n_carts} "
                            f"carts{hint}")


@dataclass(frozen=True)
class Coordinates:
    """Optimiser coordinates of one parameter vector (linear first, then the extension's).

    Attributes
    ----------
    ext : Extension or None
        The model's extension (None: the linear model alone).
    rig : Rig
    p_lin : int
        Number of linear parameters.
    log_mask : ndarray of bool, shape (n_params,)
        Parameters optimised on a log scale (linear ones only).
    scale : ndarray, shape (n_params,)
        Divisor of each coordinate (1 for the log ones).
    lower, upper : ndarray, shape (n_params,)
        Bounds in optimiser coordinates.
    """

    ext: Extension | None
    rig: Rig
    p_lin: int
    log_mask: np.ndarray
    scale: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def to_opt(self, theta: np.ndarray) -> np.ndarray:
        """Optimiser coordinates of parameter vectors ``theta`` (shape (..., n_params))."""
        w = np.array(theta, dtype=float)
        w[..., self.log_mask] = np.log(w[..., self.log_mask])
        if self.ext is not None:
            w[..., self.p_lin:] = self.ext.to_opt(self.rig, theta[..., self.p_lin:])
        return w / self.scale

    def to_theta(self, w: np.ndarray, quiet: bool = False) -> np.ndarray:
        """Parameter vectors of optimiser coordinates ``w`` (shape (..., n_params)).

        ``quiet``: a long trial step that overflows a log parameter to inf (or underflows
        a mass to 0) gives no floating-point warning; such a point is left for the
        caller's residuals to refuse."""
        w = np.asarray(w, dtype=float) * self.scale
        theta = np.array(w)
        ctx = np.errstate(over="ignore", under="ignore") if quiet else contextlib.nullcontext()
        with ctx:
            theta[..., self.log_mask] = np.exp(w[..., self.log_mask])
        if self.ext is not None:
            theta[..., self.p_lin:] = self.ext.from_opt(self.rig, w[..., self.p_lin:])
        return theta

    def fd_steps(self, fd_step: float) -> np.ndarray:
        """Forward-difference step of each coordinate: 1e-6 for a log one, 1e-4 for another
        linear one, ``fd_step`` for an extension parameter; shape (n_params,)."""
        n = self.scale.size
        steps = np.full(n, fd_step, dtype=float)
        steps[:self.p_lin] = np.where(self.log_mask[:self.p_lin], 1e-6, 1e-4)
        return steps


def coordinates(ext: Extension | None, rig: Rig, theta_lin: np.ndarray) -> Coordinates:
    """The optimiser coordinates of ``ext`` on ``rig`` (module docstring); ``theta_lin``,
    shape (n_linear,), gives the size of the relative dampers."""
    model = LinearModel(rig, "free")
    p_lin = model.n_params
    lin_log = log_scale_mask(model)
    lin_scale = np.where(lin_log, 1.0, np.maximum(np.abs(theta_lin), 1e-3))
    lower = np.where(lin_log, -np.inf, 0.0)
    upper = np.full(p_lin, np.inf)
    log_mask, scale = lin_log, lin_scale
    if ext is not None:
        ext_scale = np.array([sp.scale for sp in ext.specs(rig)])
        lo_e, hi_e = ext.opt_bounds(rig)
        log_mask = np.r_[lin_log, np.zeros(ext_scale.size, bool)]
        scale = np.r_[lin_scale, ext_scale]
        lower = np.r_[lower, lo_e / ext_scale]
        upper = np.r_[upper, hi_e / ext_scale]
    return Coordinates(ext=ext, rig=rig, p_lin=p_lin, log_mask=log_mask, scale=scale,
                       lower=lower, upper=upper)


def fd_jacobian(resid: Callable[[np.ndarray], np.ndarray], w: np.ndarray,
                cols: Sequence[int], steps: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Forward-difference derivatives of ``resid`` at ``w`` along the coordinates ``cols``.

    Each coordinate ``c`` is stepped by ``steps[c]``, or by ``-steps[c]`` where that would
    cross ``upper[c]``; ``resid`` maps the batch of points (shape (len(cols) + 1, n), ``w``
    first) to their residual rows.  Returns shape (n_residuals, len(cols))."""
    ws = np.repeat(w[None], len(cols) + 1, axis=0)
    h = np.empty(len(cols))
    for k, c in enumerate(cols):
        h[k] = steps[c] if w[c] + steps[c] <= upper[c] else -steps[c]
        ws[k + 1, c] += h[k]
    r = resid(ws)
    return ((r[1:] - r[0]) / h[:, None]).T

