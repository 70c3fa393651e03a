"""Posterior samples of the modal quantities and their credible intervals.

Every retained posterior draw of the mechanical parameters goes through the classical
modal analysis of :mod:`bayesmodal.modal` (all functions are batched over draws):

- the undamped eigenproblem ``(K - omega^2 M) u = 0`` (frequencies and shapes),
- matrix iteration with deflation and the Rayleigh-quotient stationary points (the same
  frequencies by two other routes; they must agree draw by draw),
- the complex eigenvalues of the state matrix (damping ratio, damped frequency; exact for
  free as well as proportional damping),
- the MAC between each draw's mode shapes and reference (least-squares) shapes.

The result holds arrays with the draws' leading dimensions, so intervals are plain
quantiles over them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import modal as md
from .._errors import ModelError
from ..model.system import LinearModel

__all__ = [
    "ModalSamples",
    "Interval",
    "propagate_modes",
    "credible_interval",
    "hdi",
    "modal_intervals",
]


@dataclass(frozen=True)
class ModalSamples:
    """Modal quantities of a stack of parameter draws.

    Attributes
    ----------
    omega_rad_s : ndarray, shape (..., n)
        Undamped natural frequencies from the eigenproblem, rad/s, ascending.
    omega_iteration_rad_s : ndarray, shape (..., n) or None
        The same by matrix iteration with deflation.
    omega_rayleigh_rad_s : ndarray, shape (..., n) or None
        The same as stationary values of the Rayleigh quotient.
    shapes : ndarray, shape (..., n, n)
        Undamped mode shapes as columns, cart 1 = 1.
    shapes_iteration : ndarray, shape (..., n, n) or None
    zeta : ndarray, shape (..., n)
        Damping ratios from the state-matrix eigenvalues (NaN for an overdamped mode).
    damped_rad_s : ndarray, shape (..., n)
        Damped natural frequencies ``Im(lambda)``, rad/s.
    mac_reference : ndarray, shape (..., n) or None
        ``MAC(shape_i of the draw, shape_i of the reference)``.
    """

    omega_rad_s: np.ndarray
    omega_iteration_rad_s: np.ndarray | None
    omega_rayleigh_rad_s: np.ndarray | None
    shapes: np.ndarray
    shapes_iteration: np.ndarray | None
    zeta: np.ndarray
    damped_rad_s: np.ndarray
    mac_reference: np.ndarray | None

    @property
    def n_modes(self) -> int:
        return int(self.omega_rad_s.shape[-1])

    def max_method_difference(self) -> float:
        """Largest relative difference of the iteration / Rayleigh frequencies from the
        eigenproblem over all draws and modes (0 if those methods were not run)."""
        worst = 0.0
        for other in (self.omega_iteration_rad_s, self.omega_rayleigh_rad_s):
            if other is not None:
                worst = max(worst, float(np.max(np.abs(other / self.omega_rad_s - 1.0))))
        return worst


def propagate_modes(
    model: LinearModel,
    theta: np.ndarray,
    *,
    reference: np.ndarray | None = None,
    methods: tuple[str, ...] = ("eig", "iteration", "rayleigh"),
) -> ModalSamples:
    """Modal quantities of every parameter draw.

    Parameters
    ----------
    model : LinearModel
    theta : ndarray, shape (..., n_params) or (..., P)
        Draws of the mechanical parameters (extra trailing noise parameters are ignored).
    reference : ndarray, shape (n_params,), optional
        Parameters whose undamped shapes are the MAC reference (e.g. the LSQ estimate).
    methods : tuple of {"eig", "iteration", "rayleigh"}
        Undamped methods to run; "eig" is always run.

    Returns
    -------
    ModalSamples

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> draws = np.array([[6.2, 1.56, 1.46, 1.14, 1.6, 1e-4]] * 4)
    >>> ms = propagate_modes(model, draws)
    >>> ms.omega_rad_s.shape, ms.max_method_difference() < 1e-9
    ((4, 3), True)
    """

    theta = np.asarray(theta, dtype=float)[..., : model.n_params]
    bad = ~model.valid(theta)
    if np.any(bad):
        raise ModelError(f"{int(bad.sum())} draw(s) with impossible parameters")
    unknown = set(methods) - {"eig", "iteration", "rayleigh"}
    if unknown:
        raise ModelError(f"unknown modal methods {sorted(unknown)}")
    M, _, K, _ = model.matrices(theta)
    eig = md.undamped_modes(M, K)
    it = md.matrix_iteration(M, K) if "iteration" in methods else None
    ray = md.rayleigh_modes(M, K) if "rayleigh" in methods else None
    cm = md.state_space_modes(model, theta)
    mac_ref = None
    if reference is not None:
        ref = md.undamped_modes(*(model.matrices(np.asarray(reference, float)[: model.n_params])
                                  [i] for i in (0, 2)))
        full = md.mac(eig.shapes, np.broadcast_to(ref.shapes, eig.shapes.shape))
        mac_ref = np.diagonal(full, axis1=-2, axis2=-1)
    return ModalSamples(
        omega_rad_s=eig.omega_rad_s,
        omega_iteration_rad_s=None if it is None else it.omega_rad_s,
        omega_rayleigh_rad_s=None if ray is None else ray.omega_rad_s,
        shapes=eig.shapes,
        shapes_iteration=None if it is None else it.shapes,
        zeta=cm.zeta,
        damped_rad_s=cm.damped_rad_s,
        mac_reference=mac_ref,
    )


@dataclass(frozen=True)
class Interval:
    """Posterior summary of one (array) quantity.

    Attributes
    ----------
    median, lo, hi : ndarray, shape (...)
        Median and equal-tailed interval bounds (quantiles ``(1-prob)/2`` and
        ``(1+prob)/2``).
    hdi_lo, hdi_hi : ndarray, shape (...)
        Highest-density interval (shortest interval holding ``prob`` of the draws).
    prob : float
    """

    median: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    hdi_lo: np.ndarray
    hdi_hi: np.ndarray
    prob: float

    def contains(self, value) -> np.ndarray:
        """Whether ``value`` lies in the equal-tailed interval (elementwise)."""
        value = np.asarray(value, dtype=float)
        return (value >= self.lo) & (value <= self.hi)

    def as_dict(self) -> dict:
        """``{"median", "lo", "hi", "hdi_lo", "hdi_hi"}`` as plain lists/floats."""
        def conv(a):
            a = np.asarray(a)
            return a.tolist() if a.ndim else float(a)

        return {"median": conv(self.median), "lo": conv(self.lo), "hi": conv(self.hi),
                "hdi_lo": conv(self.hdi_lo), "hdi_hi": conv(self.hdi_hi)}


def hdi(samples: np.ndarray, prob: float = 0.9, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Shortest interval containing ``prob`` of the draws along ``axis`` (unimodal HDI).

    Returns
    -------
    lo, hi : ndarray
        Shape of ``samples`` without ``axis``.
    """
    x = np.sort(np.moveaxis(np.asarray(samples, dtype=float), axis, 0), axis=0)
    n = x.shape[0]
    k = int(np.floor(prob * n))
    if k < 1 or k >= n:
        raise ValueError(f"need prob in (1/n, 1 - 1/n) for {n} draws, got {prob}")
    widths = x[k:] - x[: n - k]
    i = np.argmin(np.where(np.isnan(widths), np.inf, widths), axis=0)
    lo = np.take_along_axis(x, i[None], axis=0)[0]
    hi = np.take_along_axis(x, (i + k)[None], axis=0)[0]
    return lo, hi


def credible_interval(samples: np.ndarray, prob: float = 0.9, axis: int = 0) -> Interval:
    """Median, equal-tailed and highest-density intervals along ``axis``.

    Parameters
    ----------
    samples : ndarray
        Draws along ``axis``; any other dimensions are kept.
    prob : float
        Probability content, in (0, 1).

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(size=100_000)
    >>> iv = credible_interval(x, 0.9)
    >>> round(float(iv.hi), 1)
    1.6
    """
    if not 0 < prob < 1:
        raise ValueError(f"prob must be in (0, 1), got {prob}")
    s = np.asarray(samples, dtype=float)
    q = np.nanquantile(s, [0.5, (1 - prob) / 2, (1 + prob) / 2], axis=axis)
    lo_h, hi_h = hdi(s, prob, axis)
    return Interval(median=q[0], lo=q[1], hi=q[2], hdi_lo=lo_h, hdi_hi=hi_h, prob=float(prob))


def _flatten(a: np.ndarray, tail: int) -> np.ndarray:
    return a.reshape((-1,) + a.shape[a.ndim - tail:])


def modal_intervals(ms: ModalSamples, prob: float = 0.9) -> dict[str, Interval]:
    """Credible intervals of every modal quantity over all draws.

    Returns
    -------
    dict
        ``omega_rad_s``, ``zeta``, ``damped_rad_s`` (each shape (n,)), ``mode_shapes``
        (shape (n, n), columns are modes) and ``mac_reference`` (n,) if available.
    """
    out = {
        "omega_rad_s": credible_interval(_flatten(ms.omega_rad_s, 1), prob),
        "zeta": credible_interval(_flatten(ms.zeta, 1), prob),
        "damped_rad_s": credible_interval(_flatten(ms.damped_rad_s, 1), prob),
        "mode_shapes": credible_interval(_flatten(ms.shapes, 2), prob),
    }
    if ms.mac_reference is not None:
        out["mac_reference"] = credible_interval(_flatten(ms.mac_reference, 1), prob)
    return out
