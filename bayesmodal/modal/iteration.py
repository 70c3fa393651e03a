"""Matrix iteration (power iteration with deflation) on the dynamic matrix (report 3.3).

From ``(K - omega^2 M) u = 0`` (report eq. 34 with errata 4: the sign is minus) follows

    D u = lambda u,   D = K^-1 M,   lambda = 1 / omega^2,

so power iteration ``x <- D x`` (eq. 30), normalised on cart 1 (eq. 31), converges to the
mode of *lowest* frequency, at the rate ``lambda_2 / lambda_1 = (omega_1 / omega_2)^2`` per
step.  D is self-adjoint in the M inner product (``M D = M K^-1 M`` is symmetric), so the
quotient

    lambda = x^T M D x / x^T M x

is second-order accurate in the error of x; the report's eq. 32 uses the plain quotient
``x^T D x / x^T x``, which has the same limit but converges only at first order.

Deflation.  Once ``(lambda_i, u_i)`` is known, the next dominant mode is obtained from

    D_{i+1} = D_i - lambda_i u_i u_i^T M / (u_i^T M u_i),

which maps ``u_i`` to 0 and leaves every other mode unchanged (they are M-orthogonal to
``u_i``).  The report's eq. 33 omits the factor ``lambda_i``: then ``u_i`` is mapped to
``(lambda_i - 1) u_i``, whose eigenvalue ``lambda_i - 1`` (about -1 for the rig) dominates
and the next iteration converges to ``u_i`` again.

Stopping rule.  With the change ``delta_k = max|x_k - x_{k-1}|`` and the observed rate
``rho = delta_k / delta_{k-1}``, the remaining error of a geometric sequence is about
``delta_k rho / (1 - rho)``; iteration stops when that is below ``tol`` (or when the change
reaches the rounding floor).  Because a near-stall of a slowly converging sequence can
mimic convergence, every mode is finally checked by the a-posteriori bound

    sin angle_M(x, u_i) <= ||K x - omega^2 M x||_{M^-1} / (||x||_M  gap_i),

with ``gap_i`` the distance, in omega^2, to the nearest other computed frequency.  A mode
whose bound exceeds ``accuracy`` raises ConvergenceError (nearly repeated frequencies make
power iteration arbitrarily slow).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import check_pencil
from .undamped import UndampedModes, modes_from_shapes

__all__ = ["IterationModes", "matrix_iteration", "ConvergenceError"]

_EPS = np.finfo(float).eps


class ConvergenceError(RuntimeError):
    """An iterative modal method did not reach the requested accuracy."""


@dataclass(frozen=True)
class IterationModes(UndampedModes):
    """Undamped modes found by matrix iteration.

    Attributes
    ----------
    omega_rad_s, shapes, modal_mass, modal_stiffness
        As in UndampedModes (NaN for systems that failed with ``on_fail="nan"``).
    n_iterations : ndarray of int, shape (..., n)
        Power iterations spent on each mode (after sorting by frequency).
    error_bound : ndarray, shape (..., n)
        A-posteriori bound on the sine of the M-angle between each shape and the exact
        mode; dimensionless.
    """

    n_iterations: np.ndarray
    error_bound: np.ndarray


def _mv(A, x):
    return np.einsum("...ij,...j->...i", A, x)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _power(D, x, *, tol, max_iter):
    """Power iteration on D for a stack; returns x (normalised), counts, converged.

    Works on the flattened batch and, each step, only on the systems still iterating, so
    that a few slow systems do not make a large batch slow.
    """
    batch, n = x.shape[:-1], x.shape[-1]
    Df = D.reshape((-1, n, n))
    x = (x / _pick(x)[..., None]).reshape((-1, n)).copy()
    count = np.zeros(len(x), dtype=int)
    conv = np.zeros(len(x), dtype=bool)
    idx = np.arange(len(x))
    delta_prev = np.full(len(x), np.inf)
    for _ in range(max_iter):
        if idx.size == 0:
            break
        y = _mv(Df[idx], x[idx])
        y = y / _pick(y)[..., None]
        delta = np.max(np.abs(y - x[idx]), axis=-1)
        prev = delta_prev[idx]
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.clip(np.where(np.isfinite(prev), delta / prev, 1.0), 0.0, 1.0 - 1e-12)
        stop = (delta * rho / (1.0 - rho) <= tol) | (delta <= 16 * _EPS)
        x[idx] = y
        count[idx] += 1
        delta_prev[idx] = delta
        conv[idx[stop]] = True
        idx = idx[~stop]
    return x.reshape(batch + (n,)), count.reshape(batch), conv.reshape(batch)


def _pick(x):
    """Normalising component: cart 1 (report eq. 31) unless it is tiny, else the largest."""
    big = np.take_along_axis(x, np.argmax(np.abs(x), axis=-1)[..., None], axis=-1)[..., 0]
    first = x[..., 0]
    return np.where(np.abs(first) > 1e-3 * np.abs(big), first, big)


def matrix_iteration(M, K, *, tol: float = 1e-13, max_iter: int = 10000,
                     accuracy: float = 1e-8, on_fail: str = "raise") -> IterationModes:
    """Undamped modes by power iteration on ``D = K^-1 M`` with deflation.

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Mass matrix, kg; symmetric positive definite.
    K : array_like, shape (..., n, n)
        Stiffness matrix, N/m; symmetric positive definite.
    tol : float
        Estimated remaining error of each normalised shape at which iteration stops.
    max_iter : int
        Iterations allowed per mode.
    accuracy : float
        Largest accepted a-posteriori error bound (sine of the M-angle to the exact mode).
    on_fail : {"raise", "nan"}
        What to do with systems that hit ``max_iter`` or fail the accuracy check: raise
        ConvergenceError, or return NaN for those systems only (useful for large batches).

    Returns
    -------
    IterationModes
        Frequencies ascending, shapes normalised on cart 1, iteration counts and bounds.

    Raises
    ------
    ModelError
        If M or K is invalid.
    ConvergenceError
        With ``on_fail="raise"``, if a mode does not converge (e.g. nearly repeated
        frequencies, where the convergence rate ``(omega_i / omega_j)^2`` approaches 1).

    Examples
    --------
    >>> import numpy as np
    >>> modes = matrix_iteration(np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]]))
    >>> modes.omega_rad_s.round(6)
    array([1.      , 1.732051])
    """
    if on_fail not in ("raise", "nan"):
        raise ValueError(f"on_fail must be 'raise' or 'nan', got {on_fail!r}")
    M, K = check_pencil(M, K)
    batch, n = M.shape[:-2], M.shape[-1]
    D = np.linalg.solve(K, M)
    found, counts = [], []
    ok = np.ones(batch, dtype=bool)
    # Start from the static deflection under a fixed, irregular force pattern: it has a
    # component along every mode unless the force is M-orthogonal to one, which a
    # structured pattern such as (1, ..., 1) can be for symmetric systems.
    force = 1.0 + 0.5 * np.sin(1.0 + 2.7 * np.arange(n))
    x0 = np.linalg.solve(K, np.broadcast_to(force[:, None], batch + (n, 1)))[..., 0]
    for _ in range(n):
        x, count, conv = _power(D, x0, tol=tol, max_iter=max_iter)
        ok &= conv
        Mx = _mv(M, x)
        xMx = _dot(x, Mx)
        lam = _dot(Mx, _mv(D, x)) / xMx
        D = D - lam[..., None, None] * x[..., :, None] * Mx[..., None, :] / xMx[..., None, None]
        found.append(x)
        counts.append(count)
    U = np.stack(found, axis=-1)
    counts = np.stack(counts, axis=-1)
    bound = _error_bound(M, K, U)
    ok &= np.all(bound <= accuracy, axis=-1)
    if not np.all(ok):
        if on_fail == "raise":
            w2 = np.einsum("...im,...im->...m", U, K @ U) / np.einsum("...im,...im->...m",
                                                                       U, M @ U)
            raise ConvergenceError(_failure_message(ok, counts, bound, max_iter, accuracy,
                                                    w2))
        U = np.where(ok[..., None, None], U, np.nan)
        # keep NaN systems from tripping the normalisation and sorting
        U = np.where(np.isnan(U), 1.0, U)
    res = modes_from_shapes(M, K, U, cls=IterationModes, n_iterations=counts,
                            error_bound=bound)
    if np.all(ok):
        return res
    nan = ~ok
    fields = {f: np.where(nan[..., None], np.nan, getattr(res, f)) for f in
              ("omega_rad_s", "modal_mass", "modal_stiffness", "error_bound")}
    return IterationModes(shapes=np.where(nan[..., None, None], np.nan, res.shapes),
                          n_iterations=res.n_iterations, **fields)


def _error_bound(M, K, U):
    """A-posteriori bound on sin(angle_M) between each column of U and the exact mode."""
    MU = M @ U
    KU = K @ U
    uMu = np.einsum("...im,...im->...m", U, MU)
    w2 = np.einsum("...im,...im->...m", U, KU) / uMu
    R = KU - w2[..., None, :] * MU
    r_Minv_r = np.einsum("...im,...im->...m", R, np.linalg.solve(M, R))
    dist = np.abs(w2[..., :, None] - w2[..., None, :])
    n = w2.shape[-1]
    dist = np.where(np.eye(n, dtype=bool), np.inf, dist)
    gap = np.min(dist, axis=-1) if n > 1 else np.full(w2.shape, np.inf)
    return np.sqrt(np.maximum(r_Minv_r, 0.0) / uMu) / gap


def _failure_message(ok, counts, bound, max_iter, accuracy, w2=None):
    bad = np.argwhere(~np.atleast_1d(ok))[0]
    idx = tuple(int(i) for i in bad)
    c = counts[idx] if ok.ndim else counts
    b = bound[idx] if ok.ndim else bound
    where = f" (batch index {idx})" if ok.ndim else ""
    cause = ("nearly repeated frequencies make power iteration arbitrarily slow, use "
             "undamped_modes instead")
    if w2 is not None and np.all(np.asarray(c) < max_iter):
        # every mode met the stopping rule, yet the bound fails: not slow convergence but
        # rounding, as when omega^2 spans many decades (very stiff next to very soft
        # springs): deflating lambda = 1/omega^2 of the lowest mode leaves rounding
        # errors of order eps * lambda_max in the D seen by the highest modes
        w = np.sort(np.asarray(w2[idx] if ok.ndim else w2, float))
        gaps = np.diff(w) / w[1:] if w.size > 1 else np.array([1.0])
        if np.all(np.isfinite(w)) and w[0] > 0 and gaps.min() > 0.01:
            cause = (f"omega^2 spans a factor {w[-1] / w[0]:.2g} (very stiff or very soft "
                     "springs, or very unequal masses): deflation loses accuracy for the "
                     "highest modes, use undamped_modes instead")
    return (
        f"matrix iteration did not converge{where}: iterations per mode {c.tolist()} "
        f"(max {max_iter}), error bounds {np.array2string(b, precision=2)} "
        f"(accepted {accuracy:g}); {cause}"
    )
