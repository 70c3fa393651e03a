"""A constant bias in the drive: the residual's mean and slow content per record.

An amplifier offset ``v0`` adds ``g_v v0`` to the motor force from the start of the record,
so the measurement carries, to first order, ``v0`` times the model's response to a unit
voltage held from ``t = 0`` (a step to the static deflection ``K^-1 b``, the same sign on
every cart of the chain).  No linear parameter can produce that shape, so it stays in the
residual as a mean and slow content of fixed pattern across the carts.

The diagnostic regresses the residual of all outputs (stacked) on that unit-offset
response, without intercept, and tests the coefficient (the offset, V) with Newey-West
standard errors (the residuals of a model that misses an effect are autocorrelated).  It
also reports each output's residual mean and the share of its residual variance below
the lowest modelled mode (a moving average over one period of that mode).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg, stats

from ...model.effects import suggested_by
from ...model.simulate import simulate_linear
from ._result import Diagnostic
from ._stats import regress_hac
from .residuals import LinearResiduals

__all__ = ["input_bias"]


def _slow_share(r: np.ndarray, window: int) -> np.ndarray:
    """Share of each column's variance in its moving average over ``window`` samples."""
    k = np.ones(max(int(window), 1)) / max(int(window), 1)
    out = np.empty(r.shape[1])
    for j in range(r.shape[1]):
        slow = np.convolve(r[:, j], k, mode="same")
        out[j] = np.sum(slow**2) / max(np.sum(r[:, j] ** 2), 1e-300)
    return out


def input_bias(res: LinearResiduals, *, alpha: float = 0.01,
               min_offset_v: float = 0.005) -> Diagnostic:
    """Does the residual carry the response to a constant input offset?

    Parameters
    ----------
    res : LinearResiduals
    alpha : float
        Significance level (two-sided).
    min_offset_v : float
        Smallest estimated offset reported as detected, V (effect-size guard).

    Returns
    -------
    Diagnostic
        ``statistic``: ``|t|`` of the offset coefficient; ``p_value`` two-sided normal.
        Detail: ``offset_v`` and ``stderr_v`` (V), ``mean_m`` (n,) residual mean per
        output, ``slow_share`` (n,) share of residual variance slower than the lowest
        mode, ``unit_response`` (N, n) the regressor, m/V.  Suggests ``input_offset``.
    """
    M, _, K, _ = res.matrices()
    s = simulate_linear(res.model, res.theta, np.ones(res.y.shape[0]), res.dt)
    w_low = float(np.sqrt(linalg.eigh(K, M, eigvals_only=True)[0]))
    window = int(round(2 * np.pi / w_low / res.dt))
    r = res.residual
    reg = regress_hac(r.T.ravel(), s.T.ravel()[:, None])
    v0, se = float(reg.coef[0]), float(reg.stderr[0])
    t = abs(v0) / se if se > 0 else 0.0
    p = float(2 * stats.norm.sf(t))
    detected = bool(p < alpha and abs(v0) > min_offset_v)
    mean = r.mean(axis=0)
    share = _slow_share(r - mean, window)
    means = ", ".join(f"{m / res.quantum_m:+.1f}" for m in mean)
    summary = (f"residual along the constant-offset response: {1e3 * v0:+.1f} mV "
               f"(t = {t:.1f}, p = {p:.2g}); residual means [{means}] counts")
    return Diagnostic(
        name="input_bias", statistic=float(t), p_value=p, threshold=None,
        detected=detected, suggests=suggested_by("bias") if detected else (),
        location="motor input" if detected else None, summary=summary,
        detail={"offset_v": v0, "stderr_v": se, "mean_m": mean, "slow_share": share,
                "unit_response": s, "alpha": alpha})
