"""Cross-correlation between the input and the residuals (delay, lag).

A model that responds too early (a missing time delay or motor lag) leaves residuals that
follow the input: the residual ``y - yhat`` is then close to ``-D dyhat/dt``, locked to
every change of the input.  Under a correct model the residual is independent of the input.

Test: each output's residual is whitened by an AR model (order by AIC) and the same filter
is applied to the input, which keeps their relation but makes the residual white; then the
normalised cross-correlation ``r(tau) = sum e[t] u~[t - tau] / sqrt(sum e^2 sum u~^2)`` has
variance ``1/N`` at every lag under independence, and ``N sum_{tau=0}^{L} r(tau)^2`` is
chi-square with ``L + 1`` degrees of freedom.  The lag of the largest ``|r|`` tells how long
after the input the misfit appears.  A direct delay estimate, the shift that best aligns
measurement and prediction (sub-sample by parabolic interpolation), is given as well.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ...model.effects import suggested_by
from ._result import Diagnostic
from ._stats import ar_filter, ar_select, bonferroni
from .residuals import LinearResiduals

__all__ = ["input_residual_correlation", "prediction_lag", "lag_phrase"]


def _xcorr(e: np.ndarray, w: np.ndarray, lags: np.ndarray) -> np.ndarray:
    e = e - e.mean()
    w = w - w.mean()
    norm = np.sqrt(np.dot(e, e) * np.dot(w, w))
    out = np.empty(lags.size)
    n = e.size
    for i, tau in enumerate(lags):
        if tau >= 0:
            out[i] = np.dot(e[tau:], w[: n - tau])
        else:
            out[i] = np.dot(e[: n + tau], w[-tau:])
    return out / norm if norm > 0 else out * 0.0


def prediction_lag(y: np.ndarray, y_pred: np.ndarray, dt: float, max_lag: int) -> float:
    """Shift (s) that best aligns ``y`` with ``y_pred``: positive when ``y`` lags.

    Maximises ``sum y[t] y_pred[t - tau]`` over integer ``|tau| <= max_lag`` and refines it
    by a parabola through the best three lags.
    """
    lags = np.arange(-max_lag, max_lag + 1)
    n = y.size
    c = np.array([np.dot(y[max(t, 0): n + min(t, 0)], y_pred[max(-t, 0): n - max(t, 0)])
                  for t in lags])
    i = int(np.argmax(c))
    if 0 < i < lags.size - 1:
        den = c[i - 1] - 2 * c[i] + c[i + 1]
        off = 0.5 * (c[i - 1] - c[i + 1]) / den if den != 0 else 0.0
    else:
        off = 0.0
    return float((lags[i] + off) * dt)


def lag_phrase(lag_s: float, resolution_s: float = 0.0) -> str:
    """Plain words for a :func:`prediction_lag`: which signal is late, by how much.

    Examples
    --------
    >>> lag_phrase(-0.0049)
    'prediction lags measurement by 4.9 ms'
    >>> lag_phrase(0.003)
    'measurement lags prediction by 3.0 ms'
    """
    if abs(lag_s) <= resolution_s:
        return f"measurement and prediction aligned (within {resolution_s * 1e3:.1f} ms)"
    late, early = ("measurement", "prediction") if lag_s > 0 else ("prediction", "measurement")
    return f"{late} lags {early} by {abs(lag_s) * 1e3:.1f} ms"


def input_residual_correlation(
    res: LinearResiduals,
    *,
    max_lag_s: float = 0.1,
    max_ar_order: int = 10,
    alpha: float = 0.01,
    min_delay_s: float | None = None,
) -> Diagnostic:
    """Is the residual correlated with the (past) input?

    Parameters
    ----------
    res : LinearResiduals
    max_lag_s : float
        Largest lag tested, s (``L = round(max_lag_s / dt)`` samples).
    max_ar_order : int
        Largest order of the whitening AR model.
    alpha : float
        Family-wise significance level (Bonferroni over outputs).
    min_delay_s : float, optional
        Prediction lag that every output must exceed for a detection to point to a delay
        or lag (default a quarter sample).  Other input-locked misfits (friction while the
        motor pushes, an unmodelled mode) correlate with the input too, without a lag.

    Returns
    -------
    Diagnostic
        ``statistic``: the largest ``N sum r^2`` over outputs; ``p_value``: Bonferroni.
        Detail: ``lags_s`` (2L+1,), ``xcorr`` (n_out, 2L+1), ``band`` (the pointwise
        +-3/sqrt(N) band), ``peak_lag_s`` (n_out,), ``chi2``, ``p_values``,
        ``prediction_lag_s`` (n_out,).  Suggests ``input_delay`` and ``motor_lag`` when
        detected with every output lagging the prediction by more than ``min_delay_s``.
    """
    dt = res.dt
    L = max(1, int(round(max_lag_s / dt)))
    lags = np.arange(-L, L + 1)
    r = res.residual
    u = res.u
    n_out = r.shape[1]
    xc = np.empty((n_out, lags.size))
    chi = np.empty(n_out)
    p = np.empty(n_out)
    peak = np.empty(n_out)
    plag = np.empty(n_out)
    N = r.shape[0]
    for j in range(n_out):
        phi, _ = ar_select(r[:, j], max_ar_order)
        e = ar_filter(r[:, j] - r[:, j].mean(), phi)
        w = ar_filter(u - u.mean(), phi)
        xc[j] = _xcorr(e, w, lags)
        N = e.size
        pos = xc[j, L:]
        chi[j] = N * np.sum(pos**2)
        p[j] = stats.chi2.sf(chi[j], pos.size)
        peak[j] = lags[np.argmax(np.abs(xc[j]))] * dt
        plag[j] = prediction_lag(res.y[:, j], res.y_pred[:, j], dt, L)
    p_fw = bonferroni(p)
    j = int(np.argmax(chi))
    detected = p_fw < alpha
    min_delay = 0.25 * dt if min_delay_s is None else min_delay_s
    lagging = bool(np.min(plag) > min_delay)  # a delay or lag delays every output
    summary = (
        f"input-residual correlation {'significant' if detected else 'not significant'}: "
        f"worst output {j + 1}, peak at lag {peak[j] * 1e3:.0f} ms, p = {p_fw:.2g}; "
        + lag_phrase(plag[j], 0.25 * dt)
    )
    return Diagnostic(
        name="input_correlation",
        statistic=float(chi[j]),
        p_value=p_fw,
        threshold=None,
        detected=bool(detected),
        suggests=suggested_by("lag") if detected and lagging else (),
        location=f"output {j + 1}" if detected else None,
        summary=summary,
        detail={"lags_s": lags * dt, "xcorr": xc, "band": 3.0 / np.sqrt(N), "chi2": chi,
                "p_values": p, "peak_lag_s": peak, "prediction_lag_s": plag,
                "alpha": alpha},
    )
