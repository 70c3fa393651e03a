"""The drive gain each input event asks for, against the event's amplitude.

A linear drive has one gain.  A dead band takes a fixed voltage off every command, so
small commands move the rig proportionally less than large ones (the apparent gain rises
with the amplitude); saturation clips the large ones (it falls); an amplitude-dependent
gain does either.  The record is cut into input events: each starts where the input
changes to a non-zero level and lasts until the next such change (a pulse with the free
motion after it; a step with its return to zero).  In each event the residual of all
outputs is regressed on the model's motion since the event began (with an intercept per
output): the coefficient is the relative gain error the event asks for.  The gain errors
are then regressed on the events' amplitudes by weighted least squares (weights from
each event's Newey-West standard error; the slope's standard error is inflated by the
reduced chi-square when the events scatter more than their errors say).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ...model.effects import suggested_by
from ._result import Diagnostic
from ._stats import regress_hac
from .residuals import LinearResiduals

__all__ = ["drive_gain_amplitude", "input_events"]


def input_events(u: np.ndarray, min_samples: int) -> list[tuple[int, int, float]]:
    """``(start, stop, level)`` of every input event of at least ``min_samples`` samples."""
    u = np.asarray(u, float)
    change = np.flatnonzero((np.diff(u) != 0) & (u[1:] != 0)) + 1
    if u.size and u[0] != 0:
        change = np.r_[0, change]
    if change.size == 0:
        return []
    stops = np.r_[change[1:], u.size]
    return [(int(a), int(b), float(u[a])) for a, b in zip(change, stops, strict=True)
            if b - a >= min_samples]


def drive_gain_amplitude(res: LinearResiduals, *, alpha: float = 0.01,
                         min_samples: int = 40, min_change: float = 0.02) -> Diagnostic:
    """Does the gain the residual asks for change with the input amplitude?

    Parameters
    ----------
    res : LinearResiduals
    alpha : float
        Significance level of the slope (two-sided).
    min_samples : int
        Shortest event analysed, samples.
    min_change : float
        Smallest change of the relative gain over the amplitudes seen reported as
        detected (effect-size guard).

    Returns
    -------
    Diagnostic
        ``statistic``: the normal score ``Phi^-1(1 - p/2)`` of the slope's two-sided
        p-value (``p_value``: t with events - 2 degrees of freedom).  Detail: ``amplitude_v``,
        ``gain`` and ``stderr`` per event, ``slope_per_v``, ``slope_se``.  Suggests
        ``drive_deadband`` and ``amplitude_gain`` for a gain rising with the amplitude,
        ``input_saturation`` and ``amplitude_gain`` for a falling one.
    """
    r, yp = res.residual, res.y_pred
    n = r.shape[1]
    amps, gains, ses = [], [], []
    for a, b, level in input_events(res.u, min_samples):
        dy = yp[a:b] - yp[a]
        if not np.any(np.abs(dy) > 0):
            continue
        m = b - a
        X = np.zeros((m * n, n + 1))
        for j in range(n):
            X[j * m : (j + 1) * m, j] = 1.0
        X[:, n] = dy.T.ravel()
        reg = regress_hac(r[a:b].T.ravel(), X)
        if not np.isfinite(reg.stderr[n]) or reg.stderr[n] <= 0:
            continue
        amps.append(abs(level))
        gains.append(reg.coef[n])
        ses.append(reg.stderr[n])
    amps, gains, ses = np.array(amps), np.array(gains), np.array(ses)
    detail = {"amplitude_v": amps, "gain": gains, "stderr": ses, "slope_per_v": np.nan,
              "slope_se": np.nan, "alpha": alpha}
    if amps.size < 3 or np.ptp(amps) == 0:
        return Diagnostic(name="drive_gain", statistic=0.0, p_value=None, threshold=None,
                          detected=False, suggests=(), location=None,
                          summary="too few input events of different amplitudes",
                          detail=detail)
    w = 1.0 / ses**2
    X = np.column_stack([np.ones_like(amps), amps]) * np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(X, gains * np.sqrt(w), rcond=None)
    e = gains * np.sqrt(w) - X @ coef
    dof = amps.size - 2
    cov = np.linalg.pinv(X.T @ X) * max(1.0, float(e @ e) / max(dof, 1))
    slope, se = float(coef[1]), float(np.sqrt(cov[1, 1]))
    t = abs(slope) / se if se > 0 else 0.0
    p = float(2 * stats.t.sf(t, max(dof, 1)))
    # the statistic is the normal score of p: a t with a few degrees of freedom has heavy
    # tails, which would let single events dominate the calibrated maximum over checks
    z = float(stats.norm.isf(max(p, 1e-300) / 2))
    change = slope * np.ptp(amps)
    detected = bool(p < alpha and abs(change) > min_change)
    if not detected:
        suggests = ()
    elif slope > 0:
        suggests = suggested_by("gain_rises")
    else:
        suggests = suggested_by("gain_falls")
    detail.update(slope_per_v=slope, slope_se=se)
    summary = (f"gain asked by {amps.size} input events changes by {100 * change:+.1f} % "
               f"from {amps.min():.2g} to {amps.max():.2g} V (t = {t:.1f}, p = {p:.2g})")
    return Diagnostic(name="drive_gain", statistic=z, p_value=p, threshold=None,
                      detected=detected, suggests=suggests,
                      location="motor input" if detected else None, summary=summary,
                      detail=detail)
