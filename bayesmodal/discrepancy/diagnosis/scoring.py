"""Gain of an extended model: AR(1)-whitened log-likelihood, output error, intervals.

The residuals of a model that misses an effect are strongly autocorrelated, so the
comparison on one record uses the exact Gaussian AR(1) log-likelihood with the noise
parameters ``(sigma_j, phi_j)`` of every output profiled out (moment estimates on each
model's own residuals).  Its pointwise terms (the innovations) give a plug-in ELPD
difference with the usual standard error ``sqrt(n var(d_i))`` of a sum of pointwise
differences.

With ``phi`` near 1 the AR(1) score does not see a *level*: a constant added to a
residual changes its innovations by ``(1 - phi)`` times the constant.  On the four
measured ECP records an input offset that halves the least-squares cost (sweeps from
75 to 89 %) scores 796 nats *below* the model without it.  With several training
records a gain therefore counts when the AR(1) test or a test of the output error finds
it (``output_error_pointwise``: an independent Gaussian per output with its variance
profiled, i.e. ``N/2 log`` of the ratio of the sums of squares, tested by a z-test whose
standard error accounts for the autocorrelation of the pointwise differences,
``autocorr_se``), each at half the level; see :class:`Criterion`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ...data import Experiment
from ...model.effects import Extension
from ...model.system import Rig

__all__ = ["ar1_pointwise", "output_error_pointwise", "autocorr_se", "Criterion",
           "AR1", "OUTPUT_ERROR", "EITHER", "criterion_for", "held_out_significant",
           "profiled_nll", "laplace_sd"]

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


def output_error_pointwise(residuals: Sequence[np.ndarray]) -> np.ndarray:
    """Pointwise log densities of independent Gaussian output errors, the variance of
    every output of every record profiled (its mean square).

    Their sum over one output is ``-N/2 (log(2 pi s2) + 1)`` with ``s2`` the mean square,
    so a difference between two models is ``N/2 log(s2_cur / s2_new)``: the fit
    percentages' criterion (sums of squares) on a log scale, which sees a level.

    Parameters
    ----------
    residuals : sequence of ndarray, each shape (N_e, n_out), m

    Returns
    -------
    ndarray, shape (sum_e N_e * n_out,)
        Log densities in the layout of :func:`ar1_pointwise` (rows of each record
        raveled), nats.
    """
    parts = []
    for r in residuals:
        r = np.asarray(r, float)
        s2 = np.maximum(np.mean(r**2, axis=0), 1e-300)
        parts.append((-_HALF_LOG_2PI - 0.5 * np.log(s2) - 0.5 * r**2 / s2).ravel())
    return np.concatenate(parts)


def autocorr_se(d: np.ndarray, shapes: Sequence[tuple[int, int]]) -> float:
    """Standard error of the sum of autocorrelated pointwise differences ``d``.

    Each output of each record is one series; its sum has variance ``n var(d) tau``
    with ``tau = (1 + rho) / (1 - rho)`` the integrated autocorrelation time of an AR(1)
    series of lag-1 autocorrelation ``rho`` (clipped to ``[0, 1 - 1/n]``).  The outputs
    of one record move together, so their standard deviations add (the bound of
    perfectly correlated outputs); records are independent, so their variances add.

    Parameters
    ----------
    d : ndarray, shape (sum_e N_e * n_out,)
        Pointwise differences in the layout of :func:`ar1_pointwise`.
    shapes : sequence of (N_e, n_out)
        The records' shapes, in order.

    Returns
    -------
    float
        Standard error of ``d.sum()``, in the units of ``d``.
    """
    d = np.asarray(d, float)
    if d.size != sum(n * m for n, m in shapes):
        raise ValueError(f"autocorr_se: {d.size} differences for records of shapes "
                         f"{list(shapes)}")
    var, i = 0.0, 0
    for n, m in shapes:
        x = d[i:i + n * m].reshape(n, m)
        i += n * m
        xc = x - x.mean(axis=0)
        v = np.mean(xc**2, axis=0)
        rho = np.sum(xc[1:] * xc[:-1], axis=0) / np.maximum(n * v, 1e-300)
        rho = np.clip(rho, 0.0, 1.0 - 1.0 / n)
        tau = (1 + rho) / (1 - rho)
        var += float(np.sum(np.sqrt(n * v * tau)) ** 2)
    return float(np.sqrt(var))


@dataclass(frozen=True)
class Criterion:
    """How diagnose scores a model and tests a gain.

    Attributes
    ----------
    name : {"ar1", "output_error", "either"}
        ``"ar1"`` (one training record): the AR(1) log density (:func:`ar1_pointwise`),
        a gain tested by the likelihood ratio against ``chi2(k)`` and a positive BIC
        gain; held-out gains against the SE ``sqrt(n var(d_i))``.  ``"output_error"``:
        the output error (:func:`output_error_pointwise`), which sees a level, a gain
        tested by ``z = gain / autocorr_se`` against the normal quantile and a positive
        BIC gain; held-out gains against ``autocorr_se``.  ``"either"`` (several training
        records): both, each at half the level (Bonferroni); a gain is significant when
        either test finds it.  The output error alone lacks power where the current
        model's misfit is strongly autocorrelated (its SE counts a few independent
        pieces of evidence per record): on two records of hidden friction + offset (pair
        benchmark seed 20000) it found no effect at all, where the AR(1) score finds
        both.  Scores that rank or choose between points are the AR(1) row's.
    """

    name: str

    def pointwise(self, residuals: Sequence[np.ndarray]) -> np.ndarray:
        """Pointwise log densities of ``residuals`` (shape (N_e, n_out) each), nats:
        shape (n,), or (2, n) for ``"either"`` (AR(1) row, output-error row)."""
        if self.name == "ar1":
            return ar1_pointwise(residuals)
        if self.name == "output_error":
            return output_error_pointwise(residuals)
        return np.stack([ar1_pointwise(residuals), output_error_pointwise(residuals)])

    @staticmethod
    def total(pw: np.ndarray) -> float:
        """The score that ranks models: the sum of ``pw`` (its AR(1) row for
        ``"either"``), nats."""
        pw = np.asarray(pw, float)
        return float(np.sum(pw if pw.ndim == 1 else pw[0]))

    def se(self, d: np.ndarray, shapes: Sequence[tuple[int, int]]) -> float:
        """Standard error of the summed pointwise differences ``d`` (of the AR(1) row
        for ``"either"``), nats."""
        d = np.asarray(d, float)
        if self.name == "output_error":
            return autocorr_se(d, shapes)
        d = d if d.ndim == 1 else d[0]
        return float(np.sqrt(d.size * np.var(d)))

    def held_out(self, d: np.ndarray, shapes: Sequence[tuple[int, int]]) -> dict:
        """Summary of held-out pointwise differences ``d``: ``delta_lpd``, ``se``, ``z``
        (for ``"either"``: of the AR(1) row, with the output error's under
        ``output_error``); see :func:`held_out_significant`."""
        d = np.asarray(d, float)
        if self.name == "either":
            out = AR1.held_out(d[0], shapes)
            out["output_error"] = OUTPUT_ERROR.held_out(d[1], shapes)
            return out
        g, se = float(d.sum()), self.se(d, shapes)
        return {"delta_lpd": g, "se": se, "z": g / se if se > 0 else np.inf}

    def test(self, pw_new: np.ndarray, pw_cur: np.ndarray, k: int,
             shapes: Sequence[tuple[int, int]], level: float) -> tuple:
        """In-sample test of a model with ``k`` more parameters than the current one.

        Returns
        -------
        tuple
            ``(gain, LR, p-value, BIC gain, significant)``: ``gain`` the summed
            difference (nats), ``LR = 2 gain``, the p-value of the LR against
            ``chi2(max(k, 1))`` (``"ar1"``) or of ``z`` against the normal
            (``"output_error"``), ``BIC gain = LR - k ln N``; significant when the
            p-value is below ``level`` and the BIC gain is positive.  ``"either"``: the
            AR(1) gain, LR and BIC gain, the Bonferroni p-value ``2 min(p_ar1, p_oe)``,
            significant when either test is at ``level / 2``.
        """
        if self.name == "either":
            a = AR1.test(pw_new[0], pw_cur[0], k, shapes, level / 2)
            o = OUTPUT_ERROR.test(pw_new[1], pw_cur[1], k, shapes, level / 2)
            return a[0], a[1], min(1.0, 2 * min(a[2], o[2])), a[3], bool(a[4] or o[4])
        d = np.asarray(pw_new, float) - np.asarray(pw_cur, float)
        g = float(d.sum())
        lr = 2.0 * g
        n_total = d.size
        if self.name == "ar1":
            pv = float(stats.chi2.sf(max(lr, 0.0), max(k, 1)))
        else:
            se = autocorr_se(d, shapes)
            pv = float(stats.norm.sf(g / se)) if se > 0 else float(g <= 0)
        bic = lr - k * np.log(n_total)
        return g, lr, pv, bic, bool(pv < level and bic > 0)


AR1 = Criterion("ar1")
OUTPUT_ERROR = Criterion("output_error")
EITHER = Criterion("either")


def held_out_significant(held_out: dict, level: float) -> bool:
    """Is a held-out summary (``Criterion.held_out``, with its ``criterion``) significant
    at ``level``?  ``z`` above the normal quantile; for ``"either"``, the AR(1) or the
    output-error ``z`` above the quantile of ``level / 2``."""
    if held_out.get("criterion") == "either":
        q = stats.norm.ppf(1 - level / 2)
        return bool(held_out["z"] > q or held_out["output_error"]["z"] > q)
    return bool(held_out["z"] > stats.norm.ppf(1 - level))


def criterion_for(experiments: Sequence[Experiment]) -> Criterion:
    """The criterion of ``diagnose`` on these training records: AR(1) for one record,
    ``"either"`` (AR(1) or output error) for several (module docstring)."""
    return EITHER if len(experiments) >= 2 else AR1


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
