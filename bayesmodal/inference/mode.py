"""The posterior mode: where the sampler's walkers start.

``posterior_mode`` maximises the log posterior of the sampling coordinates ``z``
(``priors.PriorSet``) with L-BFGS-B and forward-difference gradients evaluated in one
batched likelihood call; the priors' bounds become box bounds.

Two things make it work for model extensions:

- **Joint constraints as box bounds.**  An extension's joint constraints (``Fs_i >= Fc_i``
  of the friction laws) are not bounds of single parameters: the posterior is ``-inf``
  beyond them, inside the box.  A line search that steps across such a wall sees an
  infinite value with no gradient, and L-BFGS-B stopped there at its first iteration with
  the start unchanged (the LuGre posterior of the four measured records, 25 Nov 2026: log
  posterior 788 033 at the least-squares start against 796 090 in the typical set; the
  "chain climbed 9 000 nats" of the Laplace starts in docs/discrepancy.md).  The search
  therefore runs in the extension's optimiser coordinates (``Extension.to_opt``, e.g. the
  static excess ``Fs_i - Fc_i >= 0``), mapped through each parameter's own sampling
  transform, where those constraints are box bounds.  It is the same function of the same
  point, so the maximiser is the same.  The coordinates are scaled by the curvature at
  the start, and a search that stops is restarted from where it stopped.
- **Starts off a degenerate face.**  Some extensions have parameters that do nothing on a
  face of the parameter space (LuGre's Stribeck speed when ``Fs_i = Fc_i``), where a
  least-squares fit may end and a local search cannot leave.
  ``Extension.mode_starts`` gives alternative starts around the fit; the search runs from
  each and keeps the highest posterior.
"""

from __future__ import annotations

import numpy as np

from .priors import PriorSet

__all__ = ["posterior_mode", "z_bounds", "MODE_TOL"]

#: A restarted search stops when a round gains less than this (nats): a hundredth of the
#: half-unit of log density that separates the mode from a draw one standard deviation
#: away in one direction.
MODE_TOL = 0.005


def z_bounds(priors: PriorSet) -> list[tuple[float | None, float | None]]:
    """Box bounds of the sampling coordinates (``None``: unbounded), one per parameter."""
    out = []
    for p, t in zip(priors.priors, priors.transforms, strict=True):
        lo, hi = p.support
        if t == "log":
            out.append((float(np.log(lo)) if lo > 0 else None,
                        float(np.log(hi)) if np.isfinite(hi) else None))
        elif t == "tanh":
            out.append((None, None))
        else:
            out.append((lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None))
    return out


class _OptCoordinates:
    """``z <-> u``: the extension's block in its optimiser coordinates, each element
    through its parameter's sampling transform; every other parameter as in ``z``.

    The identity when the likelihood has no extension, or when the extension's parameters
    are not all shared by name (per-record copies): then nothing is reparameterised.
    """

    def __init__(self, likelihood, priors: PriorSet) -> None:
        self.priors = priors
        ext = getattr(likelihood, "extension", None)
        self.ext, self.idx = None, None
        if ext is None:
            return
        rig = likelihood.model.rig
        names = ext.extension_names(rig)
        if all(n in priors.names for n in names):
            self.ext, self.rig = ext, rig
            self.idx = np.array([priors.names.index(n) for n in names])

    def to_u(self, z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(np.asarray(z, dtype=float))
        if self.ext is None:
            return z.copy()
        theta = self.priors.to_physical(z)
        theta[:, self.idx] = self.ext.to_opt(self.rig, theta[:, self.idx])
        u = z.copy()
        u[:, self.idx] = self.priors.to_sampling(theta)[:, self.idx]
        return u

    def to_z(self, u: np.ndarray) -> np.ndarray:
        u = np.atleast_2d(np.asarray(u, dtype=float))
        if self.ext is None:
            return u.copy()
        w = self.priors.to_physical(u)
        w[:, self.idx] = self.ext.from_opt(self.rig, w[:, self.idx])
        z = u.copy()
        z[:, self.idx] = self.priors.to_sampling(w)[:, self.idx]
        return z


def _curvature_scale(f, u0: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Per-coordinate scale ``1 / sqrt(d2f / du_i2)`` at ``u0`` (central differences, one
    batched call of ``2 P + 1`` points); a coordinate without positive finite curvature
    there gets a hundred times its difference step."""
    P = u0.size
    h = 1e-4 * np.maximum(1.0, np.abs(u0))
    h = np.where(u0 + h > upper, -h, h)
    us = np.repeat(u0[None], 2 * P + 1, axis=0)
    us[:P] += np.diag(h)
    us[P : 2 * P] -= np.diag(h)
    v = f(us)
    with np.errstate(invalid="ignore"):
        d2 = (v[:P] - 2 * v[2 * P] + v[P : 2 * P]) / h**2
    good = np.isfinite(d2) & (d2 > 0)
    return np.where(good, 1.0 / np.sqrt(np.where(good, d2, 1.0)), 100 * np.abs(h))


def _lbfgsb(log_post, coords: _OptCoordinates, z0: np.ndarray, bounds,
            max_iter: int) -> tuple[np.ndarray, float]:
    """One L-BFGS-B search from ``z0`` in the optimiser coordinates: (z at the end, log
    posterior).

    The coordinates are scaled by the curvature at the start (``_curvature_scale``), so
    that the first step, of unit length, is about one posterior standard deviation:
    unscaled, it was 100 units on a synthetic LuGre record (gradients from 1 to 2e7),
    landed beyond the priors, and L-BFGS-B stopped at its start.
    """
    from scipy.optimize import minimize

    lower = np.array([-np.inf if b[0] is None else b[0] for b in bounds])
    upper = np.array([np.inf if b[1] is None else b[1] for b in bounds])
    u0 = coords.to_u(z0)[0]
    f0 = -float(log_post(z0[None])[0, 0])
    if not np.isfinite(f0):
        return z0, -np.inf

    def f(us):  # relative to the start: L-BFGS-B's stopping rule compares the reduction
        # with |f|, which for a log-likelihood of 1e5-1e6 nats stops it far from the mode
        return -log_post(coords.to_z(us))[:, 0] - f0

    s = _curvature_scale(f, u0, upper)

    def fun(x):
        u = u0 + s * x
        h = 1e-6 * np.maximum(1.0, np.abs(u))
        h = np.where(u + h > upper, -h, h)  # step inwards at an upper bound
        us = np.repeat(u[None], u.size + 1, axis=0)
        us[1:] += np.diag(h)
        v = f(us)
        if not np.isfinite(v[0]):
            return 1e300, np.zeros_like(u)
        g = np.where(np.isfinite(v[1:]), (v[1:] - v[0]) / h, 0.0)
        return v[0], g * s

    box = [(None if not np.isfinite(lo) else (lo - c) / k,
            None if not np.isfinite(hi) else (hi - c) / k)
           for lo, hi, c, k in zip(lower, upper, u0, s, strict=True)]
    res = minimize(fun, np.zeros_like(u0), jac=True, method="L-BFGS-B", bounds=box,
                   options={"maxiter": max_iter})
    if not (np.isfinite(res.fun) and res.fun < 0.0):
        return z0, -f0
    return coords.to_z(u0 + s * res.x)[0], -(float(res.fun) + f0)


def _local_mode(log_post, coords: _OptCoordinates, z0: np.ndarray, bounds,
                max_iter: int, rounds: int = 5) -> tuple[np.ndarray, float]:
    """L-BFGS-B searches from ``z0``, each restarted where the last stopped with the
    curvature measured there, until a round gains less than ``MODE_TOL`` nats."""
    z, lp = z0, -np.inf
    for _ in range(rounds):
        z_new, lp_new = _lbfgsb(log_post, coords, z, bounds, max_iter)
        if not lp_new > lp + MODE_TOL:
            return (z_new, lp_new) if lp_new > lp else (z, lp)
        z, lp = z_new, lp_new
    return z, lp


def posterior_mode(log_post, theta0: np.ndarray, *, max_iter: int = 2000,
                   starts: bool = True) -> np.ndarray:
    """Maximum of the posterior density of the sampling coordinates, from ``theta0``.

    Parameters
    ----------
    log_post : LogPosterior
    theta0 : ndarray, shape (P,)
        Physical starting point with finite posterior density.
    max_iter : int
        L-BFGS-B iterations per start.
    starts : bool
        Also search from the extension's ``mode_starts`` around ``theta0`` and keep the
        highest posterior (module docstring).

    Returns
    -------
    theta : ndarray, shape (P,)
        Physical parameters at the mode (``theta0`` if no search improves it).
    """
    priors = log_post.priors
    coords = _OptCoordinates(log_post.likelihood, priors)
    bounds = z_bounds(priors)
    theta0 = np.asarray(theta0, dtype=float)
    candidates = [theta0]
    if starts and coords.ext is not None:
        for row in coords.ext.mode_starts(coords.rig, theta0[coords.idx]):
            th = theta0.copy()
            th[coords.idx] = row
            candidates.append(th)
    best_z, best_lp = None, -np.inf
    for th in candidates:
        z0 = priors.to_sampling(th[None])[0]
        z, lp = _local_mode(log_post, coords, z0, bounds, max_iter)
        if lp > best_lp:
            best_z, best_lp = z, lp
    if best_z is None:  # no start with a finite posterior
        return theta0
    return priors.to_physical(best_z[None])[0]
