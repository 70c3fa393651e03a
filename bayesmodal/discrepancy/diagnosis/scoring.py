"""Gain of an extended model: AR(1)-whitened log-likelihood, fit percentages, intervals.

The residuals of a model that misses an effect are strongly autocorrelated, so the
comparison uses the exact Gaussian AR(1) log-likelihood with the noise parameters
``(sigma_j, phi_j)`` of every output profiled out (moment estimates on each model's own
residuals).  Its pointwise terms (the innovations) give a plug-in ELPD difference with
the usual standard error ``sqrt(n var(d_i))`` of a sum of pointwise differences.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...data import Experiment
from ...system import Rig
from ..effects import Extension

__all__ = ["ar1_pointwise", "profiled_nll", "laplace_sd"]

_HALF_LOG_2PI = 0.5 * float(np.log(2 * np.pi))


def _ar1_params(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    phi = np.sum(r[1:] * r[:-1], axis=0) / np.maximum(np.sum(r[:-1] ** 2, axis=0), 1e-300)
    phi = np.clip(phi, -0.9999, 0.9999)
    sigma = np.sqrt(np.maximum(np.mean((r[1:] - phi * r[:-1]) ** 2, axis=0), 1e-300))
    return sigma, phi


def ar1_pointwise(residuals: Sequence[np.ndarray]) -> np.ndarray:
    """Pointwise AR(1) log densities with profiled ``(sigma, phi)`` per output.

    Parameters
    ----------
    residuals : sequence of ndarray, each shape (N_e, n_out), m
        One residual record per experiment.

    Returns
    -------
    ndarray, shape (sum_e N_e * n_out,)
        Innovation log densities (first sample: the stationary term), nats.
    """
    parts = []
    for r in residuals:
        r = np.asarray(r, float)
        sigma, phi = _ar1_params(r)
        out = np.empty_like(r)
        e = r[1:] - phi * r[:-1]
        out[1:] = -_HALF_LOG_2PI - np.log(sigma) - 0.5 * (e / sigma) ** 2
        v0 = sigma**2 / (1 - phi**2)
        out[0] = -_HALF_LOG_2PI - 0.5 * np.log(v0) - 0.5 * r[0] ** 2 / v0
        parts.append(out.ravel())
    return np.concatenate(parts)


def profiled_nll(residuals: Sequence[np.ndarray]) -> float:
    """Negative AR(1) log-likelihood with profiled noise parameters, nats."""
    return -float(np.sum(ar1_pointwise(residuals)))


def _whitened(r: np.ndarray, sigma: np.ndarray, phi: np.ndarray) -> np.ndarray:
    # r: (nb, N, n_out)
    e = r[:, 1:] - phi * r[:, :-1]
    return (e / sigma).reshape(r.shape[0], -1)


def laplace_sd(ext: Extension, rig: Rig, theta: np.ndarray,
               experiments: Sequence[Experiment]) -> np.ndarray:
    """Standard deviations of a Laplace (Gauss-Newton) approximation at ``theta``.

    ``cov = (J^T J)^-1`` with ``J`` the Jacobian of the AR(1)-whitened residuals (noise
    parameters profiled at ``theta``), by forward differences with steps of 1e-3 of each
    extension parameter's typical size (the costs of stick-slip and backlash are piecewise
    smooth) and 1e-6 relative for the linear ones.  A parameter that cannot be perturbed
    either way (at a bound of the admissible set) gets NaN.

    Returns
    -------
    ndarray, shape (n_params,)
    """
    theta = np.asarray(theta, float)
    p = theta.size
    p_lin = ext.linear_model(rig).n_params
    scales = np.r_[np.maximum(np.abs(theta[:p_lin]), 1e-6) * 1e-6,
                   [1e-3 * s.scale for s in ext.specs(rig)]]
    cand = np.repeat(theta[None], 2 * p + 1, axis=0)
    for i in range(p):
        cand[1 + i, i] += scales[i]
        cand[1 + p + i, i] -= scales[i]
    ok = ext.valid(rig, cand) & np.all(np.isfinite(cand), axis=1)
    use = np.flatnonzero(ok)
    rows = []
    for e in experiments:
        y = ext.simulate(rig, cand[use], e.v_volt, e.dt)
        rows.append(e.y_m[None] - y)
    base = [r[0] for r in rows]
    pos = {int(k): j for j, k in enumerate(use)}
    cols = []
    keep = []
    for i in range(p):
        if (1 + i) in pos:
            j, step = pos[1 + i], scales[i]
        elif (1 + p + i) in pos:
            j, step = pos[1 + p + i], -scales[i]
        else:
            continue
        parts = []
        for r, b in zip(rows, base, strict=True):
            sigma, phi = _ar1_params(b)
            w1 = _whitened(r[j][None], sigma, phi)[0]
            w0 = _whitened(b[None], sigma, phi)[0]
            parts.append((w1 - w0) / step)
        cols.append(np.concatenate(parts))
        keep.append(i)
    sd = np.full(p, np.nan)
    if cols:
        J = np.column_stack(cols)
        try:
            cov = np.linalg.pinv(J.T @ J)
            sd[keep] = np.sqrt(np.clip(np.diag(cov), 0, None))
        except np.linalg.LinAlgError:  # pragma: no cover
            pass
    return sd
