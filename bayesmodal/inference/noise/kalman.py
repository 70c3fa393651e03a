r"""Process-noise likelihood: a random force on each cart, steady-state Kalman filter.

Model.  The output-error likelihoods (white, AR(p)) put all of the model error on the
output.  Here part of it enters as a random force ``f_i(t)`` on each cart, white with
spectral density ``q_i`` (N^2 s, ``E[f_i(t) f_i(s)] = q_i delta(t - s)``), so that the
model's own dynamics shape the error:

    x' = A x + B v + G f,          G = [0; M^-1]      (state: positions, velocities)
    x_{k+1} = Ad x_k + Bd v_k + w_k,   w_k ~ N(0, Qd)
    y_k = C x_k + e_k,                 e_k ~ N(0, diag(sigma_j^2)),  C = [I 0]

with ``Ad, Bd`` the exact ZOH discretisation (as in :mod:`bayesmodal.model.simulate`) and
``Qd = int_0^dt e^{A s} G diag(q) G' e^{A' s} ds`` by Van Loan's method: with
``F = [[-A, G Q G'], [0, A']] dt`` and ``E = expm(F)``, ``Qd = E_22' E_12``.

Likelihood.  The Kalman filter turns ``y`` into innovations ``eps_k = y_k - C xhat_k``
(``xhat_k`` the prediction from ``y_0..y_{k-1}``), independent ``N(0, S_k)``, so
``log p(y) = sum_k log N(eps_k; 0, S_k)`` (prediction-error decomposition).  With the
predicted covariance at its steady state ``P`` (the stabilising solution of the filter
DARE ``P = Ad P Ad' - Ad P C' S^-1 C P Ad' + Qd``, ``S = C P C' + R``) the gain and
``S`` are constant, and one pass costs ``s^2 + 2 s n_out`` multiply-adds a step, batched
across walkers in a compiled kernel (lane index innermost).

Initial state.  ``xhat_0 = 0`` (the rig starts at rest; the simulation starts from rest)
with covariance ``P_{0|-1} = P``: then the time-varying filter keeps ``P_k = P`` for every
``k`` and the steady-state filter *is* the exact likelihood of that model
(``initial="steady"``, the default).  It assumes an initial state ``x_0 ~ N(0, P)``
rather than exactly at rest; the two likelihoods differ only while the time-varying
covariance converges to ``P`` (a few closed-loop time constants), by an amount that does
not grow with the record length (tested).  ``initial="rest"`` gives the exact likelihood
with ``x_0 = 0`` (the time-varying filter from ``P_{0|-1} = 0``) without a time-varying
filter: writing the record as ``y = m + O x_0 + eta``, the steady-state covariance is
``Sigma_ss = Sigma_rest + O P O'``, and with ``M = O' Sigma_ss^-1 O`` and
``b = O' Sigma_ss^-1 (y - m)`` (Woodbury, Sylvester)

    log p_rest(y) = log p_ss(y) - 1/2 log det(I - P M) - 1/2 b' P (I - M P)^-1 b.

The filter supplies both: ``Sigma_ss^-1/2 O`` has rows ``L^-1 C Phi^k`` with
``Phi = Ad - Ad K C`` the filter's error dynamics, so ``M`` is a Stein sum (summed by
doubling) and ``b = sum_k Phi'^k C' L^-T u_k`` an adjoint pass over the standardised
innovations, truncated where ``Phi^k`` has decayed below 1e-18.

DARE solver: a batched doubling algorithm (:mod:`.steady_filter`).

Pointwise terms.  ``S = L L'`` (Cholesky) and ``u_k = L^-1 eps_k``; the terms
``log N(u_kj; 0, 1) - log L_jj`` (one per sample and output: output ``j`` conditioned on
outputs ``< j`` of the same sample) sum exactly to the total.

Where this is not sound.  The filter's prediction step is the linear model's: it holds
for the linear model (both damping models) and would hold for linear extensions once
their extra states are added to ``x`` (``motor_lag`` adds the motor force as a state;
``input_delay`` only shifts ``v``, so it is handled by passing the delayed input).  For
the nonlinear extensions (``coulomb_friction``, ``backlash``, ``cubic_stiffness``,
``input_saturation``) the linear prediction of the state and of its covariance is wrong:
a random force changes when carts stick or cross the backlash gap, the posterior of the
state is not Gaussian, and the innovations are neither independent nor Gaussian.  An
extended or unscented Kalman filter (or a particle filter for stick-slip) would be
needed; use the output-error noise models (white, AR(1), AR(p)) with those extensions.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..._errors import ConfigError, DataError, ModelError
from ...model._kernels import _compile, padded_width
from ..priors import LogUniform, PriorSet
from .base import HALF_LOG_2PI, SIGMA_PRIOR
from .steady_filter import (
    ProcessNoiseSystem,
    SteadyStateFilter,
    discretize_process_noise,
    solve_filter_dare,
    steady_state_filter,
)

__all__ = [
    "ProcessNoise",
    "ProcessNoiseSystem",
    "SteadyStateFilter",
    "discretize_process_noise",
    "steady_state_filter",
    "solve_filter_dare",
    "kalman_loglik",
    "kalman_pointwise",
    "simulate_process_noise",
]

#: Prior of the force spectral densities ``q_i``, N^2 s.  A residual of 0.1 mm on a
#: 1.5 kg cart near 20 rad/s with 5 % damping needs q of about 4e-5 N^2 s.
Q_PRIOR = LogUniform(1e-14, 1e-2)

#: Initial-state assumptions of the filter (see the module docstring).
INITIAL_STATES = ("steady", "rest")


@dataclass(frozen=True)
class ProcessNoise:
    """Parameter layout of the process-noise model: ``q_1..n`` (N^2 s), ``sigma_1..n`` (m).

    Examples
    --------
    >>> ProcessNoise().names(2)
    ('q_1', 'q_2', 'sigma_1', 'sigma_2')
    """

    name: str = "process"

    def for_record(self, experiment) -> ProcessNoise:
        """The model for one record: the same for every record (see ``NoiseModel``)."""
        return self

    def names(self, n_carts: int) -> tuple[str, ...]:
        return (tuple(f"q_{i + 1}" for i in range(n_carts))
                + tuple(f"sigma_{j + 1}" for j in range(n_carts)))

    def valid(self, params: np.ndarray) -> np.ndarray:
        """Mask (nb,): ``q >= 0`` and ``sigma > 0``, finite; params (nb, 2 n_carts)."""
        params = np.atleast_2d(np.asarray(params, dtype=float))
        n = params.shape[1] // 2
        q, s = params[:, :n], params[:, n:]
        return (np.all(np.isfinite(q) & (q >= 0), axis=1)
                & np.all(np.isfinite(s) & (s > 0), axis=1))

    def priors(self, n_carts: int) -> PriorSet:
        """``q_i ~ LogUniform(1e-14, 1e-2)`` N^2 s and ``sigma_j`` as everywhere (log)."""
        names = self.names(n_carts)
        pri = tuple(Q_PRIOR if nm.startswith("q") else SIGMA_PRIOR for nm in names)
        return PriorSet(names, pri, ("log",) * len(names))


@functools.lru_cache(maxsize=32)
def _kalman_kernel(n_states: int, n_out: int, width: int, store: bool):
    """Compiled ``kernel(P, v, y, X, SS, U)``: the steady-state filter for ``width`` lanes.

    Generated like the simulator's kernels (``bayesmodal.model._kernels``): the state loop is
    unrolled and the lane width and row strides are constants, so that the compiler
    vectorises across lanes.  Flat float64 arrays, lane index innermost: ``P`` rows
    ``Ad[i, m]`` (``i*s + m``), ``Bd[i]`` (``s*s + i``), ``(Ad K)[i, j]``
    (``s*s + s + i*n_out + j``), ``L^-1[j, m]`` (``s*s + s + s*n_out + j*n_out + m``),
    ``Bd[i] v0`` (``s*s + s + s*n_out + n_out^2 + i``: the lane's input offset);
    ``v`` (N,); ``y`` (N * n_out,); ``X`` (s, width) predicted state, updated in place;
    ``SS`` (width,) accumulates ``sum |u_k|^2``; ``U`` (N, n_out, width) gets ``u_k`` if
    ``store``.
    """
    s, n, w = n_states, n_out, width
    o_b, o_k = s * s, s * s + s
    o_l = o_k + s * n
    o_c = o_l + n * n
    lines = [
        "def kernel(P, v, y, X, SS, U):",
        "    for k in range(v.shape[0]):",
        "        vk = v[k]",
        f"        yo = k * {n}",
        f"        uo = k * {n * w}",
        f"        for b in range({w}):",
    ]
    lines += [f"            x{i} = X[{i * w} + b]" for i in range(s)]
    lines += [f"            e{j} = y[yo + {j}] - x{j}" for j in range(n)]
    for j in range(n):
        terms = " + ".join(f"P[{(o_l + j * n + m) * w} + b] * e{m}" for m in range(j + 1))
        lines.append(f"            u{j} = {terms}")
        if store:
            lines.append(f"            U[uo + {j * w} + b] = u{j}")
    lines.append("            SS[b] += " + " + ".join(f"u{j} * u{j}" for j in range(n)))
    for i in range(s):
        terms = " + ".join([f"P[{(i * s + m) * w} + b] * x{m}" for m in range(s)]
                           + [f"P[{(o_k + i * n + j) * w} + b] * e{j}" for j in range(n)])
        lines.append(f"            X[{i * w} + b] = P[{(o_b + i) * w} + b] * vk + "
                     f"P[{(o_c + i) * w} + b] + {terms}")
    return _compile(lines, f"kalman s={s} o={n} w={w} store={store}")


def _filter(Ad, Bd, AK, Linv, v, y, n_store, v0=None):
    """Run the generated kernels over chunks of lanes (``v0`` (nb,): each lane's input
    offset, V, added to ``v``; None: none).

    Returns ``SS`` (nb,) and the standardised innovations ``U`` (n_store, n, nb) of the
    first ``n_store`` samples (the kernel that stores them runs only that far; the state
    carries over to the kernel that does not).
    """
    nb, s, _ = Ad.shape
    n = Linv.shape[1]
    N = v.size
    n_store = int(min(max(n_store, 0), N))
    width = padded_width(nb)
    n_chunks = -(-nb // width)
    c = np.zeros_like(Bd) if v0 is None else Bd * np.asarray(v0, float)[:, None]
    rows = np.concatenate([Ad.reshape(nb, s * s), Bd, AK.reshape(nb, s * n),
                           Linv.reshape(nb, n * n), c], axis=1)
    yf = np.ascontiguousarray(y).ravel()
    ss = np.empty(n_chunks * width)
    U = np.empty((n_chunks, n_store, n, width))
    dummy = np.empty(1)
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        real = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        P = np.ascontiguousarray(rows[real].T).ravel()
        X = np.zeros(s * width)
        acc = np.zeros(width)
        if n_store:
            _kalman_kernel(s, n, width, True)(P, v[:n_store], yf[: n_store * n], X, acc,
                                              U[c].reshape(-1))
        if n_store < N:
            _kalman_kernel(s, n, width, False)(P, v[n_store:], yf[n_store * n :], X, acc,
                                               dummy)
        ss[c * width : (c + 1) * width] = acc
    U = np.moveaxis(U, 0, 2).reshape(n_store, n, n_chunks * width)[:, :, :nb]
    return ss[:nb], U


@functools.lru_cache(maxsize=16)
def _adjoint_kernel(n_states: int, n_out: int, width: int):
    """Compiled ``kernel(Q, U, G)``: ``g = sum_k Phi'^k C' L^-T u_k`` by Horner, backwards.

    Generated like :func:`_kalman_kernel`.  Flat float64 arrays, lane index innermost:
    ``Q`` rows ``Phi'[i, m]`` (``i*s + m``) and ``L^-T[i, j]`` (``s*s + i*n_out + j``);
    ``U`` (K, n_out, width) standardised innovations; ``G`` (s, width), zero on entry.
    """
    s, n, w = n_states, n_out, width
    lines = [
        "def kernel(Q, U, G):",
        f"    for k in range(U.shape[0] // {n * w} - 1, -1, -1):",
        f"        uo = k * {n * w}",
        f"        for b in range({w}):",
    ]
    lines += [f"            g{i} = G[{i * w} + b]" for i in range(s)]
    lines += [f"            u{j} = U[uo + {j * w} + b]" for j in range(n)]
    for i in range(s):
        terms = [f"Q[{(i * s + m) * w} + b] * g{m}" for m in range(s)]
        if i < n:
            terms += [f"Q[{(s * s + i * n + j) * w} + b] * u{j}" for j in range(n)]
        lines.append(f"            G[{i * w} + b] = " + " + ".join(terms))
    return _compile(lines, f"kalman adjoint s={s} o={n} w={w}")


def _adjoint_sum(Phi, Linv, U):
    """``b = sum_k Phi'^k C' L^-T u_k`` for each lane, shape (nb, s); U (K, n, nb)."""
    nb, s, _ = Phi.shape
    n = Linv.shape[1]
    width = padded_width(nb)
    rows = np.concatenate([np.swapaxes(Phi, 1, 2).reshape(nb, s * s),
                           np.swapaxes(Linv, 1, 2).reshape(nb, n * n)], axis=1)
    kernel = _adjoint_kernel(s, n, width)
    out = np.empty((nb, s))
    for c in range(-(-nb // width)):
        lanes = np.arange(c * width, (c + 1) * width)
        real = np.where(lanes < nb, lanes, nb - 1)
        G = np.zeros(s * width)
        kernel(np.ascontiguousarray(rows[real].T).ravel(),
               np.ascontiguousarray(U[:, :, real]).ravel(), G)
        keep = lanes < nb
        out[lanes[keep]] = G.reshape(s, width).T[keep]
    return out


def _rest_correction(Ad, AK, Linv, P, N):
    """Pieces of the correction from x_0 ~ N(0, P) to x_0 = 0 (rest).

    With ``Phi = Ad - Ad K C`` (the filter's error dynamics) the whitened innovations of
    the free response from ``x_0`` are ``Z x_0`` with rows ``L^-1 C Phi^k``, so
    ``M = Z' Z = sum_{k<N} Phi'^k C' S^-1 C Phi^k``, summed by doubling
    (``sum_{k < 2^(j+1)} = X_j + A_j' X_j A_j``, ``A_j = Phi^(2^j)``) and combined over the
    binary digits of N.  Returns ``M`` (nb, s, s), ``Phi`` and ``K``, the number of
    samples after which ``Phi^K`` is below 1e-18 (later innovations do not move ``b``).
    """
    nb, s, _ = Ad.shape
    n = Linv.shape[1]
    Phi = Ad.copy()
    Phi[:, :, :n] -= AK
    X = np.zeros((nb, s, s))
    X[:, :n, :n] = np.swapaxes(Linv, 1, 2) @ Linv  # C' S^-1 C
    A = Phi.copy()
    total = np.zeros((nb, s, s))
    power = np.broadcast_to(np.eye(s), (nb, s, s)).copy()
    j, K = 0, N
    while (1 << j) <= N:
        if N >> j & 1:  # digit j of N: add the block of 2^j terms at the current offset
            total += np.swapaxes(power, 1, 2) @ X @ power
            power = A @ power
        if np.max(np.abs(A)) < 1e-18:
            K = min(N, 1 << j)
            # the rest of the sum is below rounding: every further block is ~ A' X A
            break
        X = X + np.swapaxes(A, 1, 2) @ X @ A
        A = A @ A
        j += 1
    return total, Phi, K


def _check(model, theta_mech, q, sigma, v, y, dt, v0=None):
    theta_mech = np.atleast_2d(np.asarray(theta_mech, dtype=float))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    sigma = np.atleast_2d(np.asarray(sigma, dtype=float))
    n = model.n_carts
    nb = theta_mech.shape[0]
    if theta_mech.shape != (nb, model.n_params):
        raise ModelError(f"theta_mech must have shape (nb, {model.n_params}) {model.names}, "
                         f"got {theta_mech.shape}")
    if q.shape != (nb, n) or sigma.shape != (nb, n):
        raise DataError(f"q and sigma must have shape ({nb}, {n}) (one per cart), got "
                        f"{q.shape} and {sigma.shape}")
    v = np.ascontiguousarray(v, dtype=float)
    if v.ndim != 1 or v.size < 1 or not np.all(np.isfinite(v)):
        raise DataError(f"input v must be a finite 1-D array, got shape {v.shape}")
    if y is not None:
        y = np.ascontiguousarray(y, dtype=float)
        if y.shape != (v.size, n) or not np.all(np.isfinite(y)):
            raise DataError(f"y must be finite with shape ({v.size}, {n}) to match v, got "
                            f"{y.shape}")
    if not (np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    ok = model.valid(theta_mech) & ProcessNoise().valid(np.c_[q, sigma])
    if v0 is not None:
        v0 = np.asarray(v0, dtype=float)
        if v0.shape not in ((), (nb,)):
            raise DataError(f"input offset v0 must be a number or have shape ({nb},) (one "
                            f"per row), got {v0.shape}")
        v0 = np.broadcast_to(v0, (nb,))
        ok = ok & np.isfinite(v0)
    return theta_mech, q, sigma, v, y, ok, v0


def _run(model, theta_mech, q, sigma, v, y, dt, store, initial="steady", v0=None):
    if initial not in INITIAL_STATES:
        raise ConfigError(f"initial must be one of {INITIAL_STATES}, got {initial!r}")
    theta_mech, q, sigma, v, y, ok, v0 = _check(model, theta_mech, q, sigma, v, y, dt, v0)
    nb, n = q.shape
    ss = np.full(nb, np.nan)
    logdet = np.full(nb, np.nan)
    U = None
    logL = np.full((nb, n), np.nan)
    corr = np.zeros(nb)
    if np.any(ok):
        sysd = discretize_process_noise(model, theta_mech[ok], q[ok], dt)
        filt = steady_state_filter(sysd, sigma[ok])
        with np.errstate(all="ignore"):
            try:
                L = np.linalg.cholesky(filt.S)
            except np.linalg.LinAlgError:
                L = np.full_like(filt.S, np.nan)
            Linv = np.linalg.inv(np.where(np.isfinite(L), L, 1.0))
        AK = sysd.Ad @ filt.gain
        n_store = v.size
        if initial == "rest":
            M, Phi, n_store = _rest_correction(sysd.Ad, AK, Linv, filt.P, v.size)
        ss_ok, U = _filter(sysd.Ad, sysd.Bd, AK, Linv, v, y, v.size if store else n_store,
                           None if v0 is None else v0[ok])
        d = np.log(np.diagonal(L, axis1=1, axis2=2))
        if initial == "rest":
            # Woodbury and Sylvester: Sigma_rest = Sigma_ss - O P O', b = O' Sigma_ss^-1 r
            b = _adjoint_sum(Phi, Linv, U[:n_store])
            eye = np.eye(M.shape[1])
            with np.errstate(all="ignore"):
                sign, ld = np.linalg.slogdet(eye - filt.P @ M)
                z = np.linalg.solve(eye - M @ filt.P, b[:, :, None])[:, :, 0]
                quad = np.einsum("bi,bij,bj->b", b, filt.P, z)
            corr[ok] = -0.5 * np.where(sign > 0, ld, np.nan) - 0.5 * quad
        ss[ok] = ss_ok
        logL[ok] = d
        logdet[ok] = d.sum(axis=1)
    return ok, ss, logdet, logL, U, corr


def kalman_loglik(model, theta_mech: np.ndarray, q: np.ndarray, sigma: np.ndarray,
                  v: np.ndarray, y: np.ndarray, dt: float, *,
                  initial: str = "steady", v0: np.ndarray | None = None) -> np.ndarray:
    """Log-likelihood of one record under the process-noise model, for a batch.

    Parameters
    ----------
    model : LinearModel
    theta_mech : ndarray, shape (nb, n_params)
        Mechanical parameters in ``model.names`` order.
    q : ndarray, shape (nb, n_carts)
        Spectral density of the random force on each cart, N^2 s (``>= 0``).
    sigma : ndarray, shape (nb, n_carts)
        Measurement noise standard deviation of each position, m (``> 0``).
    v : ndarray, shape (N,)
        Motor voltage, V, held over each sample.
    y : ndarray, shape (N, n_carts)
        Measured positions, m.
    dt : float
        Sample interval, s.
    initial : {"steady", "rest"}
        Initial state ``N(0, P)`` (steady-state covariance; the steady-state filter is
        then exact) or exactly at rest (``x_0 = 0``, the exact time-varying filter from
        ``P_0 = 0``), computed as the steady-state value plus a rank-``2n`` correction
        (module docstring); "rest" costs about one more pass over the filter's transient.
    v0 : ndarray, shape (nb,) or float, optional
        Input offset of each row, V: the drive sees ``v + v0`` (an amplifier offset,
        ``RecordLayout``'s ``v0``).  None: no offset.

    Returns
    -------
    ndarray, shape (nb,)
        ``-inf`` for impossible rows (they are never filtered).

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> th = np.array([[6.2, 1.5, 1.4, 1.1, 1.5, 1e-4]])
    >>> v = np.r_[np.full(10, 3.0), np.zeros(190)]
    >>> y = simulate_process_noise(model, th, [[1e-5] * 3], [[1e-5] * 3], v, 0.005, rng=0)
    >>> kalman_loglik(model, th, [[1e-5] * 3], [[1e-5] * 3], v, y[0], 0.005).shape
    (1,)
    """
    ok, ss, logdet, _, _, corr = _run(model, theta_mech, q, sigma, v, y, dt, store=False,
                                      initial=initial, v0=v0)
    N, n = np.shape(y)
    with np.errstate(invalid="ignore"):
        total = -N * (n * HALF_LOG_2PI + logdet) - 0.5 * ss + corr
    return np.where(ok & np.isfinite(total), total, -np.inf)


def kalman_pointwise(model, theta_mech: np.ndarray, q: np.ndarray, sigma: np.ndarray,
                     v: np.ndarray, y: np.ndarray, dt: float, *,
                     v0: np.ndarray | None = None) -> np.ndarray:
    """Pointwise terms, shape (nb, N, n_carts), summing to :func:`kalman_loglik`.

    Term ``(k, j)`` is ``log p(y_kj | y_k,<j, y_<k)``: the standardised innovation
    ``u = L^-1 eps_k`` with ``S = L L'``.  Same parameters as :func:`kalman_loglik`; the
    terms are those of the steady-state start (``initial="steady"``; the exact start from
    rest changes only a transient, as a correction that is not split per sample).
    """
    ok, _, _, logL, U, _ = _run(model, theta_mech, q, sigma, v, y, dt, store=True, v0=v0)
    nb = ok.size
    N, n = np.shape(y)
    out = np.full((nb, N, n), -np.inf)
    if np.any(ok):
        t = -HALF_LOG_2PI - logL[ok][:, None, :] - 0.5 * np.moveaxis(U, -1, 0) ** 2
        out[ok] = np.where(np.isfinite(t), t, -np.inf)
    return out


def simulate_process_noise(model, theta_mech: np.ndarray, q: np.ndarray, sigma: np.ndarray,
                           v: np.ndarray, dt: float, rng=None, *,
                           v0: np.ndarray | None = None) -> np.ndarray:
    """Measured positions drawn from the process-noise model (posterior predictive).

    The initial state is drawn from ``N(0, P)`` with ``P`` the steady-state predicted
    covariance, the model the likelihood assumes.

    Parameters
    ----------
    model, theta_mech, q, sigma, v, dt, v0
        As in :func:`kalman_loglik` (every row must be admissible).
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    ndarray, shape (nb, N, n_carts), m
    """
    rng = np.random.default_rng(rng)
    theta_mech, q, sigma, v, _, ok, v0 = _check(model, theta_mech, q, sigma, v, None, dt, v0)
    if not np.all(ok):
        raise ModelError("cannot simulate from impossible parameters (need an admissible "
                         "model, q >= 0, sigma > 0, a finite v0)")
    sysd = discretize_process_noise(model, theta_mech, q, dt)
    P = steady_state_filter(sysd, sigma).P
    nb, n = q.shape
    s = 2 * n
    Lq, Lp = _psd_root(sysd.Qd), _psd_root(P)
    x = np.einsum("bij,bj->bi", Lp, rng.standard_normal((nb, s)))
    w = np.einsum("bij,bkj->bki", Lq, rng.standard_normal((nb, v.size, s)))
    y = np.empty((nb, v.size, n))
    if v0 is not None:  # the offset's constant drive, once
        w = w + (sysd.Bd * v0[:, None])[:, None, :]
    for k in range(v.size):
        y[:, k] = x[:, :n]
        x = np.einsum("bij,bj->bi", sysd.Ad, x) + sysd.Bd * v[k] + w[:, k]
    return y + sigma[:, None, :] * rng.standard_normal(y.shape)


def _psd_root(M: np.ndarray) -> np.ndarray:
    """A square root ``R`` with ``R R' = M`` of symmetric PSD matrices (clips rounding)."""
    lam, V = np.linalg.eigh(M)
    return V * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]
