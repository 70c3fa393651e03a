"""Residual proportional to the prediction: a gain error.

If the measurement is ``(1 + g_j) yhat_j`` (a sensor calibration error on output ``j``,
or a wrong actuator gain when the parameters come from another experiment), the residual
is ``g_j yhat_j``.  Regressing each output's residual on its prediction (with an intercept
for offsets) estimates ``g_j``; the standard error allows for autocorrelated residuals
(Newey-West with the Andrews bandwidth).  On the experiment the model was fitted to, the
least-squares fit of ``g_v`` makes the pooled gain error vanish, so only gains that differ
between outputs show; on held-out experiments a common gain error shows too.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ...model.effects import suggested_by
from ._result import Diagnostic
from ._stats import bonferroni, regress_hac
from .residuals import LinearResiduals

__all__ = ["gain_error"]


def gain_error(
    res: LinearResiduals,
    *,
    alpha: float = 0.01,
    min_gain: float = 0.01,
) -> Diagnostic:
    """Relative gain error of every output.

    Parameters
    ----------
    res : LinearResiduals
    alpha : float
        Family-wise significance level (two-sided, Bonferroni over outputs).
    min_gain : float
        Smallest relative gain error reported as detected (effect-size guard).

    Returns
    -------
    Diagnostic
        ``statistic``: the largest ``|g_j| / stderr``; ``p_value``: Bonferroni.  Detail:
        ``gain`` (n,), ``stderr`` (n,), ``p_values`` (n,).  Suggests ``"sensor_gain"`` when
        the outputs disagree, ``"input_gain"`` when they agree.
    """
    n = res.n_outputs
    g = np.empty(n)
    se = np.empty(n)
    for j in range(n):
        X = np.column_stack([np.ones(res.y.shape[0]), res.y_pred[:, j]])
        reg = regress_hac(res.residual[:, j], X)
        g[j], se[j] = reg.coef[1], reg.stderr[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(se > 0, np.abs(g) / se, 0.0)
    p = 2 * stats.norm.sf(z)
    p_fw = bonferroni(p)
    j = int(np.argmax(z))
    detected = bool(p_fw < alpha and np.abs(g[j]) > min_gain)
    if detected:
        # do the outputs share one gain error (within 3 standard errors)?
        common = np.all(np.abs(g - g.mean()) < 3 * np.sqrt(se**2 + np.mean(se**2)))
        suggests = suggested_by("input_gain" if common and np.all(np.abs(g) > min_gain)
                                else "sensor_gain")
    else:
        suggests = ()
    gains = ", ".join(f"{100 * x:+.1f}" for x in g)
    summary = f"gain error per output [{gains}] % (worst output {j + 1}, p = {p_fw:.2g})"
    return Diagnostic(
        name="gain_error",
        statistic=float(z[j]),
        p_value=p_fw,
        threshold=None,
        detected=detected,
        suggests=suggests,
        location=f"output {j + 1}" if detected else None,
        summary=summary,
        detail={"gain": g, "stderr": se, "p_values": p, "alpha": alpha, "min_gain": min_gain},
    )
