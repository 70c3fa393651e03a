r"""AR(p) residuals per output with the exact stationary Gaussian likelihood.

Output ``j`` follows ``r_k = sum_{i=1..p_j} a_i r_{k-i} + e_k`` with innovations
``e_k ~ N(0, sigma_j^2)`` and a stationary start.  The orders ``p_j`` may differ between
outputs (:func:`choose_order` picks them from a residual record).

Parametrisation (Monahan 1984).  Each output's coefficients are given by its partial
autocorrelations ``kappa_1..kappa_p`` in ``(-1, 1)``, so that every parameter set is
stationary and the ``tanh`` sampling transform of :mod:`..priors` applies.  The
Durbin-Levinson recursion maps them to the best linear predictors of every order,

    a_{m,m} = kappa_m,   a_{m,i} = a_{m-1,i} - kappa_m a_{m-1,m-i}   (i < m),

and the one-step prediction error variances obey ``v_m = v_{m-1} (1 - kappa_m^2)``.  The
AR coefficients are ``a_i = a_{p,i}`` and ``v_p = sigma^2``, hence
``v_m = sigma^2 / prod_{i>m} (1 - kappa_i^2)`` (``v_0`` is the stationary variance).

Exact likelihood (prediction-error decomposition).  For a stationary AR(p) the best
linear predictor of ``r_k`` from all earlier samples uses the ``min(k, p)`` most recent
ones with the coefficients ``a_{min(k,p),.}``, so

    log p(r) = sum_{k<p}  log N(r_k - sum_{i<=k} a_{k,i} r_{k-i}; 0, v_k)
             + sum_{k>=p} log N(r_k - sum_{i<=p} a_i r_{k-i}; 0, sigma^2),

with nothing conditioned away.  For AR(1) this is ``ar1_terms``.  Outputs of lower order
are padded with ``kappa = 0`` up to the largest order, which leaves the process and
its exact density unchanged.

Fast total (:meth:`ARpNoise.loglik`).  With ``a = (1, -a_1, ..., -a_p)`` the innovation
sum of squares after the start is the quadratic form ``a' S a`` in the lagged sums
``S_{il} = sum_{k=p}^{N-1} r_{k-i} r_{k-l}``, and ``S`` comes from the ``p + 1`` full lag
sums ``G_d = sum_t r_t r_{t+d}`` (one compiled pass over the batch-innermost residual
array) minus ``O(p^2)`` edge products.  As for AR(1) the difference of large sums costs a
few digits (the bound ``N eps sum |a_i a_l S_{il}|`` is what the tests allow).

Order selection (:func:`choose_order`).  For each output and each ``p = 0..max_p``,
Burg's method estimates the partial autocorrelations (it keeps ``|kappa| < 1`` and has
less bias than Yule-Walker for the near-unit roots of the rig residuals), ``sigma^2`` is
profiled out of the exact likelihood above in closed form, and the order minimising
BIC ``= -2 log L + (p + 1) log N`` is chosen (a warning when that is ``max_p`` itself).
BIC rather than AIC because BIC is consistent: for a record that truly is AR(p0) the
probability of choosing ``p0`` tends to one, whereas AIC keeps a fixed probability of
choosing too high an order (about 16 % per extra lag), so on white noise AIC would add
spurious lags.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..._errors import ConfigError, DataError
from .base import HALF_LOG_2PI, NoiseModel, check_residual

__all__ = ["ARpNoise", "OrderChoice", "pacf_to_ar", "levinson_table", "burg",
           "choose_order"]


def levinson_table(kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Durbin-Levinson predictors of every order from partial autocorrelations.

    Parameters
    ----------
    kappa : ndarray, shape (..., p)
        Partial autocorrelations, each in (-1, 1).

    Returns
    -------
    A : ndarray, shape (..., p + 1, p)
        ``A[..., m, :m]`` are the coefficients ``a_{m,1..m}`` of the best linear
        predictor from the ``m`` previous samples (zeros elsewhere); ``A[..., p, :]`` are
        the AR coefficients.
    c : ndarray, shape (..., p + 1)
        Prediction error variance of order ``m`` in units of the innovation variance:
        ``v_m / sigma^2 = 1 / prod_{i>m} (1 - kappa_i^2)``; ``c[..., p] = 1``.
    """
    kappa = np.asarray(kappa, dtype=float)
    p = kappa.shape[-1]
    A = np.zeros(kappa.shape[:-1] + (p + 1, p))
    for m in range(1, p + 1):
        km = kappa[..., m - 1]
        prev = A[..., m - 1, : m - 1]
        A[..., m, : m - 1] = prev - km[..., None] * prev[..., ::-1]
        A[..., m, m - 1] = km
    one_m = 1.0 - kappa**2
    # c_m = prod_{i=m+1..p} 1/(1 - kappa_i^2): reverse cumulative product
    tail = np.cumprod(one_m[..., ::-1], axis=-1)[..., ::-1]  # tail[m-1] = prod_{i>=m}
    c = np.ones(kappa.shape[:-1] + (p + 1,))
    c[..., :p] = 1.0 / tail
    return A, c


def pacf_to_ar(kappa: np.ndarray) -> np.ndarray:
    """AR coefficients ``a_1..a_p``, shape (..., p), from partial autocorrelations.

    Examples
    --------
    >>> pacf_to_ar(np.array([0.5, 0.2]))  # a_1 = 0.5 - 0.2 * 0.5
    array([0.4, 0.2])
    """
    A, _ = levinson_table(kappa)
    return A[..., -1, :]


@njit(cache=False, nogil=True, boundscheck=False)
def _lag_sums(R, n_lags):  # pragma: no cover - compiled
    # G[d, j, b] = sum_t R[t, j, b] R[t + d, j, b]; the lane index b is contiguous
    N, n_out, nb = R.shape
    G = np.zeros((n_lags + 1, n_out, nb))
    for t in range(N):
        top = min(n_lags, N - 1 - t)
        for d in range(top + 1):
            for j in range(n_out):
                for b in range(nb):
                    G[d, j, b] += R[t, j, b] * R[t + d, j, b]
    return G


def _start_terms(r0, A, c, sigma2):
    """Prediction errors and variances of the first p samples.

    r0 : (P, n_out, nb); A : (n_out, nb, P+1, P); c : (n_out, nb, P+1); sigma2 (n_out, nb).
    Returns e (P, n_out, nb) and v (P, n_out, nb).
    """
    P = r0.shape[0]
    e = r0.copy()
    for k in range(1, P):
        for i in range(1, k + 1):
            e[k] -= A[..., k, i - 1] * r0[k - i]
    v = np.moveaxis(c[..., :P], -1, 0) * sigma2
    return e, v


@dataclass(frozen=True)
class ARpNoise(NoiseModel):
    """Stationary AR(p_j) residuals per output with the exact Gaussian likelihood.

    Parameters
    ----------
    orders : tuple of int
        ``p_j >= 1`` per output (length ``n_outputs``).

    Notes
    -----
    Parameters: ``sigma_1..n`` (innovation standard deviations, m), then for each output
    ``j`` its partial autocorrelations ``pacf1_j..pacf{p_j}_j`` in (-1, 1).  With
    ``orders = (1, ..., 1)`` the model is :class:`~.base.AR1Noise` with ``phi_j = pacf1_j``.

    Examples
    --------
    >>> m = ARpNoise((2, 1))
    >>> m.names(2)
    ('sigma_1', 'sigma_2', 'pacf1_1', 'pacf2_1', 'pacf1_2')
    >>> r = m.simulate(np.array([[1.0, 1.0, 0.5, -0.3, 0.9]]), 50, rng=0)
    >>> bool(np.isclose(m.pointwise(r, [[1, 1, 0.5, -0.3, 0.9]]).sum(),
    ...                 m.loglik(np.moveaxis(r, 0, -1), [[1, 1, 0.5, -0.3, 0.9]])[0]))
    True
    """

    orders: tuple[int, ...] = (1,)
    name: str = ""

    def __post_init__(self) -> None:
        try:
            orders = tuple(int(p) for p in self.orders)
        except (TypeError, ValueError):
            raise ConfigError(f"orders must be a tuple of ints >= 1, got {self.orders!r}") from None
        if not orders or min(orders) < 1 or any(int(p) != p for p in self.orders):
            raise ConfigError(
                f"orders must be a non-empty tuple of ints >= 1 (use WhiteNoise for p = 0), "
                f"got {self.orders!r}")
        object.__setattr__(self, "orders", orders)
        object.__setattr__(self, "name", "ar(" + ",".join(map(str, orders)) + ")")

    @property
    def max_order(self) -> int:
        return max(self.orders)

    def _check_n(self, n_outputs: int) -> None:
        if n_outputs != len(self.orders):
            raise DataError(
                f"{self.name} noise has orders for {len(self.orders)} outputs, got "
                f"{n_outputs}; give one order per output")

    def names(self, n_outputs: int) -> tuple[str, ...]:
        self._check_n(n_outputs)
        sig = tuple(f"sigma_{j + 1}" for j in range(n_outputs))
        pac = tuple(f"pacf{i + 1}_{j + 1}" for j, p in enumerate(self.orders) for i in range(p))
        return sig + pac

    def split(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``sigma`` (nb, n_out) and zero-padded ``kappa`` (nb, n_out, max_order)."""
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = len(self.orders)
        sigma = params[:, :n]
        kappa = np.zeros((params.shape[0], n, self.max_order))
        col = n
        for j, p in enumerate(self.orders):
            kappa[:, j, :p] = params[:, col : col + p]
            col += p
        return sigma, kappa

    def join(self, sigma: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`split`: parameter rows (nb, n_noise)."""
        sigma = np.atleast_2d(sigma)
        kappa = np.asarray(kappa, dtype=float).reshape(sigma.shape[0], sigma.shape[1], -1)
        parts = [sigma] + [kappa[:, j, :p] for j, p in enumerate(self.orders)]
        return np.concatenate(parts, axis=1)

    def valid(self, params: np.ndarray) -> np.ndarray:
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = len(self.orders)
        sig, kap = params[:, :n], params[:, n:]
        return (np.all(np.isfinite(sig) & (sig > 0), axis=1)
                & np.all(np.isfinite(kap) & (np.abs(kap) < 1), axis=1))

    def _safe(self, params, n_out):
        params = self._params(params, n_out)
        ok = self.valid(params)
        fill = np.r_[np.ones(n_out), np.zeros(params.shape[1] - n_out)]
        return ok, np.where(ok[:, None], params, fill)

    def loglik(self, R: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Total exact log density, shape (nb,), of ``R`` (N, n_out, nb), m.

        Lanes with invalid parameters get ``-inf``.  Cost: one compiled pass computing
        ``max_order + 1`` lag sums, then ``O(p^2)`` work per lane.
        """
        R = np.ascontiguousarray(R, dtype=float)
        N, n_out, nb = R.shape
        P = self.max_order
        if N <= P:
            raise DataError(f"record of {N} samples is too short for AR order {P}")
        ok, safe = self._safe(params, n_out)
        sigma, kappa = self.split(safe)
        A, c = levinson_table(np.moveaxis(kappa, 0, 1))  # (n_out, nb, P+1, P), (n_out, nb, P+1)
        s2 = sigma.T**2
        # start: first P samples with order-k predictors
        e0, v0 = _start_terms(R[:P], A, c, s2)
        start = -0.5 * np.sum(np.log(v0) + e0**2 / v0, axis=0)
        # the rest: quadratic form a' S a
        G = _lag_sums(R, P)
        a = np.empty((P + 1, n_out, nb))
        a[0] = 1.0
        a[1:] = -np.moveaxis(A[..., P, :], -1, 0)
        ss = np.zeros((n_out, nb))
        for i in range(P + 1):
            for m in range(i, P + 1):
                d = m - i
                S = G[d].copy()
                if P - m > 0:  # head: t = 0 .. P-m-1
                    S -= np.einsum("tjb,tjb->jb", R[: P - m], R[d : d + P - m])
                if i > 0:  # tail: t = N-m .. N-1-d  (i terms)
                    S -= np.einsum("tjb,tjb->jb", R[N - m : N - d], R[N - m + d : N])
                w = 1.0 if i == m else 2.0
                ss += w * a[i] * a[m] * S
        rest = -0.5 * (N - P) * np.log(s2) - 0.5 * ss / s2
        t = start + rest - N * HALF_LOG_2PI
        with np.errstate(invalid="ignore"):
            tot = t.sum(axis=0)
        return np.where(ok & np.isfinite(tot), tot, -np.inf)

    def pointwise(self, r: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Terms ``log N(e_k; 0, v_k)``, shape (nb, N, n_out), of ``r`` (nb, N, n_out)."""
        r = np.asarray(r, dtype=float)
        nb, N, n_out = r.shape
        P = self.max_order
        if N <= P:
            raise DataError(f"record of {N} samples is too short for AR order {P}")
        ok, safe = self._safe(params, n_out)
        sigma, kappa = self.split(safe)
        A, c = levinson_table(np.moveaxis(kappa, 0, 1))
        R = np.moveaxis(r, 0, -1)  # (N, n_out, nb) view
        e = R.copy()
        for i in range(1, P + 1):
            e[P:] -= A[..., P, i - 1] * R[P - i : N - i]
        v = np.broadcast_to(sigma.T**2, R.shape).copy()
        e[:P], v[:P] = _start_terms(R[:P], A, c, sigma.T**2)
        out = -HALF_LOG_2PI - 0.5 * np.log(v) - 0.5 * e**2 / v
        out = np.ascontiguousarray(np.moveaxis(out, -1, 0))
        out[~ok] = -np.inf
        return out

    def start(self, r: np.ndarray) -> np.ndarray:
        """Burg estimates: ``sigma`` and partial autocorrelations of each output's order."""
        r = check_residual(r, len(self.orders))
        kappa, _ = burg(r, self.max_order)  # (n_out, P)
        kappa = np.clip(kappa, -0.9999, 0.9999)
        sig2 = np.array([_profile_sigma2(r[:, j], kappa[j, : p])
                         for j, p in enumerate(self.orders)])
        return self.join(np.sqrt(sig2)[None], kappa[None])[0]

    def simulate(self, params: np.ndarray, n_samples: int, rng=None) -> np.ndarray:
        """Exact stationary draws, shape (nb, n_samples, n_out), m.

        The first ``p`` samples come from the same prediction-error decomposition as the
        likelihood (``r_k = sum_i a_{k,i} r_{k-i} + sqrt(v_k) z_k``), then the AR recursion.
        """
        rng = np.random.default_rng(rng)
        params = self._params(params, len(self.orders))
        if not np.all(self.valid(params)):
            raise DataError("cannot simulate from invalid AR parameters (need sigma > 0, "
                            "|pacf| < 1)")
        sigma, kappa = self.split(params)
        A, c = levinson_table(kappa)  # (nb, n_out, P+1, P), (nb, n_out, P+1)
        nb, n_out = sigma.shape
        P = self.max_order
        z = rng.standard_normal((nb, int(n_samples), n_out))
        out = np.empty_like(z)
        for k in range(int(n_samples)):
            m = min(k, P)
            mean = np.zeros((nb, n_out))
            for i in range(1, m + 1):
                mean += A[..., m, i - 1] * out[:, k - i]
            out[:, k] = mean + np.sqrt(c[..., m]) * sigma * z[:, k]
        return out


def burg(r: np.ndarray, max_p: int) -> tuple[np.ndarray, np.ndarray]:
    """Burg estimates of the partial autocorrelations, per output.

    Parameters
    ----------
    r : ndarray, shape (N, n_out)
        Residual record, m.
    max_p : int
        Largest order.

    Returns
    -------
    kappa : ndarray, shape (n_out, max_p)
        Reflection coefficients (partial autocorrelations), ``|kappa| <= 1``; the
        estimate of order ``p`` is ``kappa[:, :p]`` (Burg's method is order-recursive).
    power : ndarray, shape (n_out, max_p + 1)
        Burg's prediction error power of each order, m^2.
    """
    r = check_residual(r)
    N, n_out = r.shape
    f = r.T.copy()  # forward errors, (n_out, N)
    b = r.T.copy()  # backward errors
    kappa = np.zeros((n_out, max_p))
    power = np.zeros((n_out, max_p + 1))
    power[:, 0] = np.mean(r**2, axis=0)
    for m in range(max_p):
        ff, bb = f[:, 1:], b[:, :-1]  # f_m(t), b_m(t - 1) for t = m+1 .. N-1
        den = np.sum(ff**2 + bb**2, axis=1)
        k = np.where(den > 0, 2 * np.sum(ff * bb, axis=1) / np.where(den > 0, den, 1), 0.0)
        kappa[:, m] = k
        f, b = ff - k[:, None] * bb, bb - k[:, None] * ff
        power[:, m + 1] = power[:, m] * (1 - k**2)
    return kappa, power


def _profile_sigma2(x: np.ndarray, kappa: np.ndarray) -> float:
    """Maximum-likelihood innovation variance of one output given its kappa (closed form)."""
    if kappa.size == 0:
        return float(np.mean(x**2))
    m = ARpNoise((kappa.size,))
    # every v_k is sigma^2 times a kappa-only factor, so sigma^2_hat = mean(e_k^2 / c_k)
    terms = m.pointwise(x[None, :, None], m.join(np.ones((1, 1)), kappa[None, None]))
    quad = -2 * (terms + HALF_LOG_2PI)  # = log c_k + e_k^2 / c_k with sigma = 1
    _, c = levinson_table(kappa)
    logc = np.r_[np.log(c[: kappa.size]), np.zeros(x.size - kappa.size)]
    return float(np.mean(quad[0, :, 0] - logc))


def _profile_loglik(x: np.ndarray, kappa: np.ndarray) -> float:
    s2 = _profile_sigma2(x, kappa)
    if kappa.size == 0:
        return float(-x.size * (HALF_LOG_2PI + 0.5 * np.log(s2) + 0.5))
    m = ARpNoise((kappa.size,))
    R = x[:, None, None]
    return float(m.loglik(R, m.join(np.sqrt([[s2]]), kappa[None, None]))[0])


@dataclass(frozen=True)
class OrderChoice:
    """AR order chosen per output.

    Attributes
    ----------
    orders : tuple of int
        Chosen order per output (0 means white noise is preferred).
    bic : ndarray, shape (n_out, max_p + 1)
        ``-2 log L + (p + 1) log N`` at the Burg estimate with sigma profiled out.
    kappa : ndarray, shape (n_out, max_p)
        Burg partial autocorrelations (order ``p`` uses the first ``p``).
    """

    orders: tuple[int, ...]
    bic: np.ndarray
    kappa: np.ndarray

    def model(self) -> ARpNoise:
        """The :class:`ARpNoise` with these orders (order 0 raised to 1; AR(1) nests white)."""
        return ARpNoise(tuple(max(p, 1) for p in self.orders))


def choose_order(r: np.ndarray, max_p: int = 8) -> OrderChoice:
    """Choose the AR order of each output of a residual record by BIC.

    Parameters
    ----------
    r : ndarray, shape (N, n_out)
        Residual record (e.g. ``y - yhat`` at a least-squares fit), m.
    max_p : int
        Largest order considered (0 .. max_p).

    Returns
    -------
    OrderChoice

    Warns
    -----
    UserWarning
        When an output chooses ``max_p`` itself: BIC would go higher.  On the rig's
        measured residuals (linear model at report Table 3) it does so up to p = 60: the
        model error is not a low-order AR process, and the cap is then a modelling choice.

    Examples
    --------
    >>> r = ARpNoise((2,)).simulate(np.array([[1.0, 0.8, -0.5]]), 2000, rng=1)[0]
    >>> choose_order(r, max_p=5).orders
    (2,)
    """
    r = check_residual(r)
    max_p = int(max_p)
    if not 0 <= max_p < r.shape[0] // 2:
        raise ConfigError(f"max_p must be in [0, N/2) = [0, {r.shape[0] // 2}), got {max_p}")
    kappa, _ = burg(r, max_p)
    kappa = np.clip(kappa, -1 + 1e-12, 1 - 1e-12)
    N, n_out = r.shape
    bic = np.empty((n_out, max_p + 1))
    for j in range(n_out):
        for p in range(max_p + 1):
            bic[j, p] = -2 * _profile_loglik(r[:, j], kappa[j, :p]) + (p + 1) * np.log(N)
    orders = tuple(int(np.argmin(bic[j])) for j in range(n_out))
    at_cap = [j + 1 for j, p in enumerate(orders) if p == max_p and max_p > 0]
    if at_cap:
        warnings.warn(
            f"choose_order: outputs {at_cap} chose the largest order max_p = {max_p}; the "
            "residual is not a low-order AR process (model error?); raise max_p or accept "
            "the cap", stacklevel=2)
    return OrderChoice(orders, bic, kappa)
