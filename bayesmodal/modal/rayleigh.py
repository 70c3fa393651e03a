"""Modes as stationary points of the Rayleigh quotient (report section 3.2).

With the first (cart 1) displacement fixed to 1, ``x = [1, a_2, ..., a_n]`` (for three carts
``a = (alpha, beta)``, report eq. 25), the Rayleigh quotient

    R(a) = N / D,   N = x^T K x,   D = x^T M x,

is stationary exactly at the mode shapes, where ``R = omega^2``.  Its analytic gradient and
Hessian with respect to ``a`` (derived from ``dN/da = 2 (K x)_a`` and ``dD/da = 2 (M x)_a``,
where ``_a`` drops the first component) are

    g = (2 / D) r_a,                    r = K x - R M x,
    H = (2 / D) [(K - R M)_aa - (M x)_a g^T - g (M x)_a^T],

so at a stationary point ``H = (2 / D) (K - omega^2 M)_aa``: positive definite at the first
mode (minimum), indefinite at the middle ones (saddles), negative definite at the last one
(maximum).  No eigen-solver is used.  The stationary points are found one after the other:

1. the first mode is the minimum of R;
2. mode ``k`` is the minimum of R restricted to the affine subspace
   ``{x : x_1 = 1, u_j^T M x = 0 for j < k}`` (the M-orthogonal complement of the modes
   already found), which is again a Rayleigh quotient in fewer coordinates;
3. each minimisation is a Newton iteration on ``g = 0`` with an exact line search (along a
   line the quotient is a ratio of quadratics, whose stationary points are the roots of a
   quadratic), falling back to steepest descent where the Hessian is not positive definite.
   A Rayleigh quotient has no spurious local minima, so this converges to the minimum;
4. each point is polished by plain Newton on the full gradient ``g(a) = 0`` and classified
   by the inertia of its Hessian (signs of LDL^T pivots).

The iteration runs vectorised over any leading batch dimensions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._errors import ModelError
from ._checks import check_pencil, n_negative
from .undamped import UndampedModes, modes_from_shapes

__all__ = ["RayleighModes", "rayleigh_modes", "rayleigh_quotient", "rayleigh_gradient"]

_KIND = np.array(["min", "saddle", "max"])


@dataclass(frozen=True)
class RayleighModes(UndampedModes):
    """Undamped modes found as stationary points of the Rayleigh quotient.

    Attributes
    ----------
    omega_rad_s, shapes, modal_mass, modal_stiffness
        As in UndampedModes.
    hessian_index : ndarray of int, shape (..., n)
        Number of negative eigenvalues of the Hessian of ``R(a)`` at each stationary point:
        0 at a minimum, ``n - 1`` at a maximum, in between at a saddle.
    """

    hessian_index: np.ndarray

    @property
    def kind(self) -> np.ndarray:
        """``"min"``, ``"saddle"`` or ``"max"`` per stationary point, shape (..., n)."""
        n = self.omega_rad_s.shape[-1]
        code = np.where(self.hessian_index == 0, 0, np.where(self.hessian_index >= n - 1, 2, 1))
        return _KIND[code]


def rayleigh_quotient(M, K, *coords) -> np.ndarray:
    """Rayleigh quotient ``R = x^T K x / x^T M x`` at ``x = [1, coords...]``.

    Parameters
    ----------
    M, K : array_like, shape (n, n)
        Mass (kg) and stiffness (N/m) matrices.
    *coords : array_like, n - 1 arrays of a common (broadcast) shape
        Displacements of carts 2..n relative to cart 1 (for three carts, alpha and beta of
        report eq. 25), e.g. grids from ``numpy.meshgrid``.

    Returns
    -------
    ndarray, broadcast shape of coords
        R in (rad/s)^2.

    Examples
    --------
    >>> import numpy as np
    >>> M, K = np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]])
    >>> float(rayleigh_quotient(M, K, -1.0))
    3.0
    """
    M = np.asarray(M, dtype=float)
    K = np.asarray(K, dtype=float)
    n = M.shape[-1]
    if len(coords) != n - 1:
        raise ModelError(f"need {n - 1} coordinates for {n} carts, got {len(coords)}")
    coords = np.broadcast_arrays(*(np.asarray(c, dtype=float) for c in coords))
    shape = coords[0].shape if coords else ()
    x = np.stack([np.ones(shape)] + list(coords), axis=-1)
    num = np.einsum("...i,ij,...j->...", x, K, x)
    den = np.einsum("...i,ij,...j->...", x, M, x)
    return num / den


def rayleigh_gradient(M, K, a) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rayleigh quotient, analytic gradient and Hessian at ``x = [1, a]``.

    Parameters
    ----------
    M, K : ndarray, shape (..., n, n)
    a : ndarray, shape (..., n - 1)

    Returns
    -------
    R : ndarray, shape (...,), (rad/s)^2
    g : ndarray, shape (..., n - 1)
    H : ndarray, shape (..., n - 1, n - 1)
    """
    x = np.concatenate([np.ones(a.shape[:-1] + (1,)), a], axis=-1)
    R, g, H, _, _ = _quotient_terms(M, K, x)
    return R, g, H


def _quotient_terms(M, K, x):
    Kx = np.einsum("...ij,...j->...i", K, x)
    Mx = np.einsum("...ij,...j->...i", M, x)
    N = np.einsum("...i,...i->...", x, Kx)
    D = np.einsum("...i,...i->...", x, Mx)
    R = N / D
    r = Kx - R[..., None] * Mx
    g = 2.0 * r[..., 1:] / D[..., None]
    Mxa = Mx[..., 1:]
    H = (K - R[..., None, None] * M)[..., 1:, 1:]
    H = H - Mxa[..., :, None] * g[..., None, :] - g[..., :, None] * Mxa[..., None, :]
    H = (2.0 / D)[..., None, None] * H
    # backward error of the eigen-equation (floors near machine precision): the convergence
    # measure
    scale = np.linalg.norm(K, axis=(-2, -1)) + np.abs(R) * np.linalg.norm(M, axis=(-2, -1))
    res = np.linalg.norm(r, axis=-1) / (scale * np.linalg.norm(x, axis=-1))
    return R, g, H, res, r


def _solve(H, g):
    """``H^-1 g`` over a stack, NaN where H is singular."""
    try:
        return np.linalg.solve(H, g[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full_like(g, np.nan)
        flat_h = H.reshape((-1,) + H.shape[-2:])
        flat_g = g.reshape((-1, g.shape[-1]))
        flat_o = out.reshape(flat_g.shape)
        for i in range(len(flat_h)):
            try:
                flat_o[i] = np.linalg.solve(flat_h[i], flat_g[i])
            except np.linalg.LinAlgError:
                pass
        return out


def _line_min(K, M, x, d):
    """Step t minimising R(x + t d) for each batch entry (exact line search).

    Along the line ``N(t) = n0 + 2 n1 t + n2 t^2`` and ``D(t) = d0 + 2 d1 t + d2 t^2``;
    ``R'(t) = 0`` reduces to ``(n2 d1 - n1 d2) t^2 + (n2 d0 - n0 d2) t + (n1 d0 - n0 d1) = 0``.
    Its discriminant is non-negative because M is positive definite.
    """
    Kx = np.einsum("...ij,...j->...i", K, x)
    Mx = np.einsum("...ij,...j->...i", M, x)
    Kd = np.einsum("...ij,...j->...i", K, d)
    Md = np.einsum("...ij,...j->...i", M, d)
    n0, n1, n2 = (np.einsum("...i,...i->...", *p) for p in ((x, Kx), (d, Kx), (d, Kd)))
    d0, d1, d2 = (np.einsum("...i,...i->...", *p) for p in ((x, Mx), (d, Mx), (d, Md)))
    qa = n2 * d1 - n1 * d2
    qb = n2 * d0 - n0 * d2
    qc = n1 * d0 - n0 * d1
    disc = np.sqrt(np.maximum(qb * qb - 4.0 * qa * qc, 0.0))
    q = -0.5 * (qb + np.where(qb >= 0, disc, -disc))
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(qa != 0, q / qa, np.inf)
        t2 = np.where(q != 0, qc / q, 0.0)

        def rq(t):
            t = np.where(np.isfinite(t), t, 0.0)
            return (n0 + 2 * n1 * t + n2 * t * t) / (d0 + 2 * d1 * t + d2 * t * t), t

        r1, t1 = rq(t1)
        r2, t2 = rq(t2)
    return np.where(r1 <= r2, t1, t2)


def _minimise(K, M, *, tol, max_iter):
    """Minimise R over x = [1, z] for a stack of pencils (K, M) of size m.

    Returns x, shape (..., m), and a convergence mask.
    """
    batch, m = K.shape[:-2], K.shape[-1]
    x = np.zeros(batch + (m,))
    x[..., 0] = 1.0
    if m == 1:
        return x, np.ones(batch, dtype=bool)
    done = np.zeros(batch, dtype=bool)
    for _ in range(max_iter):
        R, g, H, res, r = _quotient_terms(M, K, x)
        done |= res <= tol
        if np.all(done):
            break
        # Newton where the chart Hessian is positive definite (near the minimum) ...
        newton = -_solve(H, g)
        use_newton = (n_negative(H) == 0) & np.all(np.isfinite(newton), axis=-1)
        newton = np.concatenate([np.zeros(batch + (1,)), newton], axis=-1)
        # ... elsewhere the K-preconditioned residual v = K^-1 r, whose span with x contains
        # the inverse-iteration vector K^-1 M x; span{x, v} meets the chart x_1 = 1 along
        # the line x + t (v - v_1 x).
        v = np.linalg.solve(K, r[..., None])[..., 0]
        pre = v - v[..., :1] * x
        d = np.where(use_newton[..., None], np.nan_to_num(newton), pre)
        t = _line_min(K, M, x, d)
        t = np.where(done, 0.0, t)
        dx = t[..., None] * d
        x = x + dx
        # Newton steps that no longer move x have reached the rounding floor
        moved = np.max(np.abs(dx), axis=-1) / np.max(np.abs(x), axis=-1)
        stalled = use_newton & (moved <= 1e-12)
        done |= stalled & (res <= 1e3 * tol)
        if np.all(done):
            break
    return x, done


def rayleigh_modes(M, K, *, tol: float = 1e-14, max_iter: int = 200) -> RayleighModes:
    """Undamped modes as the stationary points of the Rayleigh quotient (no eigen-solver).

    Parameters
    ----------
    M : array_like, shape (..., n, n)
        Mass matrix, kg; symmetric positive definite.
    K : array_like, shape (..., n, n)
        Stiffness matrix, N/m; symmetric positive definite.
    tol : float
        Target backward error ``||K x - R M x|| / ((||K|| + R ||M||) ||x||)`` of each
        stationary point (Frobenius norms).  Iterations also stop when Newton steps no
        longer change x by more than 1e-12 relative (rounding floor) and the backward
        error is below ``1000 tol``.
    max_iter : int
        Newton iterations allowed per mode.

    Returns
    -------
    RayleighModes
        Frequencies ``sqrt(R)`` ascending, shapes ``[1, a]``, Hessian indices.

    Raises
    ------
    ModelError
        If M, K are invalid, or if a mode has a node at cart 1 (the chart ``x_1 = 1``
        cannot represent it) or the search does not converge.

    Examples
    --------
    >>> import numpy as np
    >>> modes = rayleigh_modes(np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]]))
    >>> modes.omega_rad_s.round(6), modes.kind.tolist()
    (array([1.      , 1.732051]), ['min', 'max'])
    """
    M, K = check_pencil(M, K)
    batch, n = M.shape[:-2], M.shape[-1]
    found = np.zeros(batch + (n, 0))
    e1 = np.zeros(n)
    e1[0] = 1.0
    for k in range(n):
        # Affine subspace {x : x_1 = 1, found^T M x = 0} = p + span(N), from the complete QR
        # of the constraint normals [e1, M u_1, ..., M u_k].
        normals = np.concatenate(
            [np.broadcast_to(e1[:, None], batch + (n, 1)), M @ found], axis=-1
        )
        Q, Rq = np.linalg.qr(normals, mode="complete")
        rhs = np.zeros(batch + (k + 1,))
        rhs[..., 0] = 1.0
        # normals^T p = rhs with p = Q_1 w:  R_1^T w = rhs
        R1 = Rq[..., : k + 1, :]
        w = np.linalg.solve(np.swapaxes(R1, -1, -2), rhs[..., None])[..., 0]
        p = np.einsum("...ij,...j->...i", Q[..., :, : k + 1], w)
        T = np.concatenate([p[..., :, None], Q[..., :, k + 1 :]], axis=-1)
        Tt = np.swapaxes(T, -1, -2)
        z, ok = _minimise(Tt @ K @ T, Tt @ M @ T, tol=tol, max_iter=max_iter)
        x = np.einsum("...ij,...j->...i", T, z)
        _check_chart(x, ok, k)
        found = np.concatenate([found, (x / x[..., :1])[..., None]], axis=-1)
    a = np.swapaxes(found, -1, -2)[..., 1:]  # (..., n modes, n - 1)
    a = _polish(M[..., None, :, :], K[..., None, :, :], a, tol=tol)
    _, _, H = rayleigh_gradient(M[..., None, :, :], K[..., None, :, :], a)
    index = n_negative(H)
    shapes = np.concatenate([np.ones(batch + (1, n)), np.swapaxes(a, -1, -2)], axis=-2)
    return modes_from_shapes(M, K, shapes, cls=RayleighModes, hessian_index=index)


def _check_chart(x, ok, k):
    if not np.all(ok):
        raise ModelError(
            f"Rayleigh quotient search for mode {k + 1} did not converge "
            f"({int(np.sum(~ok))} of {ok.size} systems)"
        )
    scale = np.max(np.abs(x), axis=-1)
    if np.any(np.abs(x[..., 0]) < 1e-8 * scale):
        raise ModelError(
            f"mode {k + 1} has a node at cart 1, which the chart x = [1, a] cannot represent"
        )


def _polish(M, K, a, *, tol, n_steps=3):
    """A few plain Newton steps on grad R(a) = 0, kept only where they lower the residual."""
    x = np.concatenate([np.ones(a.shape[:-1] + (1,)), a], axis=-1)
    _, g, H, res, _ = _quotient_terms(M, K, x)
    for _ in range(n_steps):
        if np.all(res <= 0.1 * tol) or a.shape[-1] == 0:
            break
        step = _solve(H, g)
        cand = a - np.where(np.isfinite(step), step, 0.0)
        xc = np.concatenate([np.ones(a.shape[:-1] + (1,)), cand], axis=-1)
        _, gc, Hc, resc, _ = _quotient_terms(M, K, xc)
        better = resc < res
        a = np.where(better[..., None], cand, a)
        g = np.where(better[..., None], gc, g)
        H = np.where(better[..., None, None], Hc, H)
        res = np.where(better, resc, res)
    return a
