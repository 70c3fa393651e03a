"""Whiteness of the residuals after AR pre-whitening (Ljung-Box).

Measurement noise may be coloured (an AR(1) process is typical of filtered encoder data),
so each output's residual is first whitened with a low-order AR model.  What a low-order
AR model cannot whiten, the transient, input-locked structure that a wrong model leaves, is
detected by the Ljung-Box portmanteau test on the innovations.  A detection says that the
model misses *something*; the other diagnostics say what.
"""

from __future__ import annotations

import numpy as np

from ._result import Diagnostic
from ._stats import ar_filter, ar_fit, ar_select, bonferroni, ljung_box
from .residuals import LinearResiduals

__all__ = ["whiteness"]


def whiteness(
    res: LinearResiduals,
    *,
    ar_order: int | None = 1,
    max_ar_order: int = 4,
    lags: int = 25,
    alpha: float = 0.01,
) -> Diagnostic:
    """Ljung-Box test of the AR-whitened residuals of every output.

    Parameters
    ----------
    res : LinearResiduals
    ar_order : int or None
        Order of the pre-whitening AR model; None chooses it by AIC up to
        ``max_ar_order`` (a high order would whiten model error too).
    max_ar_order : int
    lags : int
        Number of autocorrelation lags in the test.
    alpha : float
        Family-wise significance level (Bonferroni over outputs).

    Returns
    -------
    Diagnostic
        ``statistic`` is the largest Q over outputs; ``p_value`` the Bonferroni p.  Detail:
        ``Q``, ``p_values``, ``ar_phi`` (list per output), ``acf`` (n_out, lags) of the
        innovations, ``band`` (the +-1.96/sqrt(n) band), ``lags``.

    Examples
    --------
    >>> # res = linear_residuals(experiment, model, theta); whiteness(res).p_value
    """
    r = res.residual
    n_out = r.shape[1]
    Q = np.empty(n_out)
    p = np.empty(n_out)
    acfs = np.empty((n_out, lags))
    phis = []
    n_used = r.shape[0]
    for j in range(n_out):
        x = r[:, j] - r[:, j].mean()
        phi, _ = ar_fit(x, ar_order) if ar_order is not None else ar_select(x, max_ar_order)
        e = ar_filter(x, phi)
        Q[j], p[j], acfs[j] = ljung_box(e, lags, n_fitted=len(phi))
        phis.append(phi)
        n_used = e.size
    p_fw = bonferroni(p)
    j = int(np.argmin(p))
    detected = p_fw < alpha
    summary = (
        f"residuals {'not ' if detected else ''}white after AR pre-whitening "
        f"(Ljung-Box, {lags} lags): worst output {j + 1}, Q = {Q[j]:.1f}, p = {p_fw:.2g}"
    )
    return Diagnostic(
        name="whiteness",
        statistic=float(Q[j]),
        p_value=p_fw,
        threshold=None,
        detected=bool(detected),
        suggests=(),
        location=f"output {j + 1}" if detected else None,
        summary=summary,
        detail={"Q": Q, "p_values": p, "ar_phi": phis, "acf": acfs, "lags": lags,
                "band": 1.96 / np.sqrt(n_used), "alpha": alpha},
    )
