"""Small statistics toolbox of the diagnostics: AR pre-whitening, Ljung-Box, regressions
with autocorrelated errors.  NumPy and SciPy only."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = [
    "ar_fit", "ar_select", "ar_filter", "ljung_box", "acf", "regress_hac", "Regression",
    "andrews_bandwidth", "bonferroni",
]


def ar_fit(x: np.ndarray, order: int) -> tuple[np.ndarray, float]:
    """Least-squares AR(p) fit ``x[t] = sum_i phi_i x[t-i] + e[t]`` of a demeaned series.

    Returns
    -------
    phi : ndarray, shape (order,)
    sigma2 : float
        Innovation variance.
    """
    x = np.asarray(x, float) - np.mean(x)
    if order == 0:
        return np.zeros(0), float(np.var(x))
    n = x.size
    X = np.column_stack([x[order - i - 1 : n - i - 1] for i in range(order)])
    y = x[order:]
    phi, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = y - X @ phi
    return phi, float(np.mean(e**2))


def ar_select(x: np.ndarray, max_order: int) -> tuple[np.ndarray, float]:
    """AR fit with the order (0..max_order) that minimises AIC on a common sample."""
    x = np.asarray(x, float) - np.mean(x)
    best = None
    n_eff = x.size - max_order
    for p in range(max_order + 1):
        xs = x[max_order - p :]
        phi, s2 = ar_fit(xs, p)
        aic = n_eff * np.log(max(s2, 1e-300)) + 2 * p
        if best is None or aic < best[0]:
            best = (aic, phi, s2)
    return best[1], best[2]


def ar_filter(x: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Innovations ``e[t] = x[t] - sum_i phi_i x[t-i]`` for ``t >= p`` (axis 0).

    ``x`` may be 2-D (N, k): every column is filtered with the same ``phi``.
    """
    x = np.asarray(x, float)
    p = len(phi)
    e = x[p:].copy()
    for i, c in enumerate(phi):
        e -= c * x[p - i - 1 : x.shape[0] - i - 1]
    return e


def acf(x: np.ndarray, lags: int) -> np.ndarray:
    """Sample autocorrelation at lags 1..lags (biased estimator), shape (lags,)."""
    x = np.asarray(x, float) - np.mean(x)
    d = np.dot(x, x)
    if d == 0:
        return np.zeros(lags)
    return np.array([np.dot(x[k:], x[:-k]) / d for k in range(1, lags + 1)])


def ljung_box(x: np.ndarray, lags: int, n_fitted: int = 0) -> tuple[float, float, np.ndarray]:
    """Ljung-Box portmanteau test of whiteness.

    ``Q = n (n + 2) sum_{k=1}^{h} r_k^2 / (n - k)`` is chi-square with ``h - n_fitted``
    degrees of freedom for white noise (``n_fitted`` AR coefficients estimated first).

    Returns
    -------
    Q : float
    p_value : float
    r : ndarray, shape (lags,)
        The autocorrelations used.
    """
    x = np.asarray(x, float)
    n = x.size
    r = acf(x, lags)
    k = np.arange(1, lags + 1)
    Q = float(n * (n + 2) * np.sum(r**2 / (n - k)))
    dof = max(lags - n_fitted, 1)
    return Q, float(stats.chi2.sf(Q, dof)), r


@dataclass(frozen=True)
class Regression:
    """Least-squares regression with autocorrelation-robust standard errors.

    Attributes
    ----------
    coef : ndarray, shape (k,)
    stderr : ndarray, shape (k,)
    t : ndarray, shape (k,)
    bandwidth : int
        Newey-West bandwidth used, samples.
    n : int
        Observations.
    """

    coef: np.ndarray
    stderr: np.ndarray
    t: np.ndarray
    bandwidth: int
    n: int


def andrews_bandwidth(scores: np.ndarray) -> int:
    """Andrews (1991) plug-in bandwidth of the Bartlett kernel from AR(1) fits of the scores.

    ``L = 1.1447 (a n)^(1/3)`` with ``a = sum 4 rho^2 s^4 / ((1 - rho)^6 (1 + rho)^2) /
    sum s^4 / (1 - rho)^4`` over the score columns (AR(1) coefficient ``rho``, innovation
    variance ``s^2``), capped at ``n / 4``.
    """
    n = scores.shape[0]
    num = den = 0.0
    for col in scores.T:
        phi, s2 = ar_fit(col, 1)
        rho = float(np.clip(phi[0], -0.99, 0.99))
        num += 4 * rho**2 * s2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        den += s2**2 / (1 - rho) ** 4
    a = num / den if den > 0 else 0.0
    return int(min(max(np.ceil(1.1447 * (a * n) ** (1 / 3)), 1), n // 4))


def regress_hac(y: np.ndarray, X: np.ndarray, *, min_lags: int = 1) -> Regression:
    """Ordinary least squares with Newey-West (Bartlett) standard errors.

    OLS stays unbiased when the errors are autocorrelated (GLS pre-whitening would weight
    the high frequencies, where a smoothed step regressor is least like the truth); the
    standard errors allow for the autocorrelation with the Andrews bandwidth, at least
    ``min_lags``.

    Parameters
    ----------
    y : ndarray, shape (N,)
    X : ndarray, shape (N, k)
    min_lags : int
        Smallest bandwidth, samples (e.g. the smoothing window of the series).

    Returns
    -------
    Regression
    """
    y = np.asarray(y, float)
    X = np.asarray(X, float)
    b, *_ = np.linalg.lstsq(X, y, rcond=None)
    e = y - X @ b
    n, k = X.shape
    Xe = X * e[:, None]
    L = max(int(min_lags), andrews_bandwidth(Xe))
    S = Xe.T @ Xe
    for lag in range(1, L + 1):
        w = 1.0 - lag / (L + 1)
        G = Xe[lag:].T @ Xe[:-lag]
        S += w * (G + G.T)
    XtX_inv = np.linalg.pinv(X.T @ X)
    cov = XtX_inv @ S @ XtX_inv * n / max(n - k, 1)
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(se > 0, b / se, 0.0)
    return Regression(coef=b, stderr=se, t=t, bandwidth=L, n=n)


def bonferroni(p: np.ndarray) -> float:
    """Family-wise p-value ``min(1, m min p)`` of m tests."""
    p = np.asarray(p, float)
    return float(min(1.0, p.size * np.min(p))) if p.size else 1.0
