"""Shape of the free-decay envelope: linear (Coulomb) or exponential (viscous).

Over a stretch of constant input the motion about the rest position decays.  Its energy

    E(t) = 1/2 x'^T M x' + 1/2 (x - x_rest)^T K (x - x_rest)

is smooth even when several modes beat, and its rate of loss tells the damping law: viscous
damping loses ``x'^T C x'``, about proportional to ``E``, so ``s = sqrt(E)`` decays
exponentially; Coulomb friction loses ``sum Fc_i |x_i'|``, about proportional to
``sqrt(E)``, so ``s`` decays *linearly* and reaches zero in finite time.  Regressing the
slope of ``s`` on ``s``,

    ds/dt = -a - b s,

separates the two: ``a`` (J^0.5/s) is the Coulomb-like part, ``b`` (1/s) the viscous part.
The statistic is the share of the initial decay rate due to ``a``,
``a / (a + b s0)``: 0 for pure viscous damping, 1 for pure dry friction.  Noise makes the
tail flatten (``a < 0``), so it errs towards "viscous".  ``x_rest`` is the final position
(the carts stick there under friction).
"""

from __future__ import annotations

import numpy as np

from ...model.effects import suggested_by
from ._result import Diagnostic
from .residuals import (
    LinearResiduals,
    constant_input_segments,
    derivative_noise_gain,
    noise_level,
    smooth_derivative,
)

__all__ = ["decay_envelope"]


def decay_envelope(
    res: LinearResiduals,
    *,
    min_duration_s: float = 1.0,
    floor_fraction: float = 0.05,
    threshold: float = 0.3,
) -> Diagnostic:
    """Coulomb share of the decay of ``sqrt(E)`` on free-decay stretches.

    Parameters
    ----------
    res : LinearResiduals
    min_duration_s : float
        Shortest stretch of constant input analysed, s.
    floor_fraction : float
        A stretch is cut where ``sqrt(E)`` falls below this fraction of its start (or below
        ten times the noise level).
    threshold : float
        Coulomb share (median over stretches) above which dry friction is reported.

    Returns
    -------
    Diagnostic
        ``statistic``: the median Coulomb share; ``threshold``.  Detail per stretch:
        ``segments`` [(start, stop)], ``t_s``, ``sqrt_energy`` (lists of arrays, J^0.5),
        ``a``, ``b``, ``share``, and the fitted pure-exponential and pure-linear curves
        ``fit_exponential``, ``fit_linear`` for plotting.
    """
    dt = res.dt
    w = res.smooth_window
    M, _, K, _ = res.matrices()
    y = smooth_derivative(res.y, dt, w, deriv=0)
    v = res.v_meas
    sigma = noise_level(res.residual, res.quantum_m)
    sv = sigma * derivative_noise_gain(w, dt, deriv=1)
    e_noise = 0.5 * np.sum(np.diag(M) * sv**2) + 0.5 * np.sum(np.diag(K) * sigma**2)
    segs = constant_input_segments(res.u, int(min_duration_s / dt), skip=w)
    out = {"segments": [], "t_s": [], "sqrt_energy": [], "a": [], "b": [], "share": [],
           "fit_exponential": [], "fit_linear": []}
    tail = max(int(0.25 / dt), 3)
    for a0, b0 in segs:
        x_rest = y[b0 - tail : b0].mean(axis=0)
        dx = y[a0:b0] - x_rest
        E = 0.5 * np.einsum("ti,ij,tj->t", v[a0:b0], M, v[a0:b0]) + \
            0.5 * np.einsum("ti,ij,tj->t", dx, K, dx)
        s = np.sqrt(E)
        floor = max(floor_fraction * s[0], 10 * np.sqrt(e_noise))
        below = np.flatnonzero(s < floor)
        stop = below[0] if below.size else s.size
        if stop < max(10, 2 * w) or s[0] <= 10 * np.sqrt(e_noise):
            continue
        s = s[:stop]
        t = np.arange(stop) * dt
        ds = np.gradient(s, dt)
        # ds/dt = -a - b s  by least squares
        A = np.column_stack([-np.ones_like(s), -s])
        (ca, cb), *_ = np.linalg.lstsq(A, ds, rcond=None)
        share = ca / (ca + cb * s[0]) if (ca + cb * s[0]) > 0 else np.nan
        # the two pure laws through the data, for the plot
        pos = s > 0
        lam = -np.polyfit(t[pos], np.log(s[pos]), 1)[0]
        c_exp = np.exp(np.mean(np.log(s[pos]) + lam * t[pos]))
        lin = np.polyfit(t, s, 1)
        out["segments"].append((a0, a0 + stop))
        out["t_s"].append(t)
        out["sqrt_energy"].append(s)
        out["a"].append(float(ca))
        out["b"].append(float(cb))
        out["share"].append(float(share))
        out["fit_exponential"].append(c_exp * np.exp(-lam * t))
        out["fit_linear"].append(np.polyval(lin, t))
    shares = np.array(out["share"], float)
    shares = shares[np.isfinite(shares)]
    if shares.size == 0:
        return Diagnostic(
            name="decay_envelope", statistic=float("nan"), p_value=None, threshold=threshold,
            detected=False, suggests=(), location=None,
            summary="no free-decay stretch long and large enough to judge the decay law",
            detail=out,
        )
    stat = float(np.median(shares))
    detected = stat > threshold
    summary = (
        f"free decay {'linear (dry friction)' if detected else 'exponential (viscous)'}: "
        f"Coulomb share of the decay {stat:.2f} (median of {shares.size} stretches; "
        f"threshold {threshold})"
    )
    return Diagnostic(
        name="decay_envelope",
        statistic=stat,
        p_value=None,
        threshold=threshold,
        detected=bool(detected),
        suggests=suggested_by("decay") if detected else (),
        location=None,
        summary=summary,
        detail=out,
    )
