"""Plots of the classical modal analysis: Rayleigh contour, Bode diagram, mode shapes."""

from __future__ import annotations

import numpy as np

from .._errors import ModelError
from ..modal import rayleigh_modes, rayleigh_quotient

__all__ = ["plot_rayleigh_contour", "plot_bode", "plot_mode_shapes"]

_MARKERS = {"min": "v", "saddle": "X", "max": "^"}


def plot_rayleigh_contour(M, K, *, ax=None, modes=None, n_grid: int = 241,
                          margin: float = 0.35, n_levels: int = 40):
    """Contour of the Rayleigh quotient ``R(alpha, beta)`` with its stationary points.

    As the report's Figures 9-10: ``x = [1, alpha, beta]`` for a three-cart system.

    Parameters
    ----------
    M, K : array_like, shape (3, 3)
        Mass (kg) and stiffness (N/m) matrices of one system.
    ax : matplotlib Axes, optional
        Axes to draw on (new figure if omitted).
    modes : UndampedModes, optional
        Stationary points to mark (default ``rayleigh_modes(M, K)``); a RayleighModes
        result labels them min / saddle / max from its Hessian indices.
    n_grid : int
        Grid points per axis.
    margin : float
        Extra range around the stationary points, as a fraction of their spread.
    n_levels : int
        Number of contour levels.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from bayesmodal.model.system import Rig
    >>> ax = plot_rayleigh_contour(np.diag([1.565, 1.461, 1.146]), Rig().stiffness_matrix())
    >>> ax.get_xlabel()
    'alpha = x2 / x1 (m/m)'
    """
    import matplotlib.pyplot as plt


    M = np.asarray(M, dtype=float)
    K = np.asarray(K, dtype=float)
    if M.shape != (3, 3) or K.shape != (3, 3):
        raise ModelError(f"the (alpha, beta) contour needs 3 carts, got M {M.shape}, K {K.shape}")
    if modes is None:
        modes = rayleigh_modes(M, K)
    shapes = np.real(np.asarray(modes.shapes))
    omega = np.asarray(modes.omega_rad_s)
    if shapes.shape != (3, 3):
        raise ModelError(f"modes must be of one 3-cart system, got shapes {shapes.shape}")
    kinds = getattr(modes, "kind", np.array(["min", "saddle", "max"]))
    pts = shapes[1:] / shapes[:1]
    lo, hi = pts.min(axis=1), pts.max(axis=1)
    pad = margin * np.maximum(hi - lo, 1.0)
    a = np.linspace(lo[0] - pad[0], hi[0] + pad[0], n_grid)
    b = np.linspace(lo[1] - pad[1], hi[1] + pad[1], n_grid)
    A, B = np.meshgrid(a, b)
    R = rayleigh_quotient(M, K, A, B)
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 5.2), layout="constrained")
    cs = ax.contour(A, B, R, levels=n_levels, cmap="viridis", linewidths=0.8)
    cbar = ax.figure.colorbar(cs, ax=ax)
    cbar.set_label("Rayleigh quotient R ((rad/s)^2)")
    for i in range(3):
        kind = str(kinds[i])
        ax.plot(pts[0, i], pts[1, i], _MARKERS.get(kind, "o"), color="C3", ms=9,
                label=f"mode {i + 1}: {kind}, omega = {omega[i]:.4g} rad/s")
    ax.set_xlabel("alpha = x2 / x1 (m/m)")
    ax.set_ylabel("beta = x3 / x1 (m/m)")
    ax.set_title("Rayleigh quotient and its stationary points")
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_bode(omega, H, *, ax=None, bands=None, phase_bands=None, labels=None,
              db: bool = True, hz: bool = False, unit: str = "m/V"):
    """Bode diagram (magnitude and phase) of one or more frequency responses.

    Parameters
    ----------
    omega : array_like, shape (n_freq,)
        Angular frequencies, rad/s.
    H : array_like, shape (n_freq,) or (n_freq, n_out), complex
        Frequency responses, e.g. one system of ``transfer_function``; ``unit`` per volt or
        newton.
    ax : sequence of two matplotlib Axes, optional
        Magnitude and phase axes (new figure if omitted).
    bands : tuple (lo, hi) of ndarray, shape like H, optional
        Credible band of the magnitude ``|H|`` (linear, in ``unit``), shaded.
    phase_bands : tuple (lo, hi) of ndarray, shape like H, optional
        Credible band of the phase, degrees, shaded.
    labels : sequence of str, optional
        One label per output (default ``x1, x2, ...``).
    db : bool
        Magnitude in dB (``20 log10 |H|``) rather than on a log axis.
    hz : bool
        Frequency axis in Hz instead of rad/s.
    unit : str
        Unit of H, for the magnitude label.

    Returns
    -------
    ndarray of matplotlib.axes.Axes, shape (2,)

    Examples
    --------
    >>> import numpy as np
    >>> w = np.linspace(0.1, 10, 50)
    >>> axes = plot_bode(w, 1 / (1 - w**2 + 0.1j * w))
    >>> axes[1].get_ylabel()
    'phase (deg)'
    """
    import matplotlib.pyplot as plt

    w = np.asarray(omega, dtype=float)
    H = np.asarray(H)
    H = H[:, None] if H.ndim == 1 else H
    if H.ndim != 2 or H.shape[0] != w.size:
        raise ModelError(f"H must have shape (n_freq,) or (n_freq, n_out) with n_freq = "
                         f"{w.size}, got {np.shape(H)}")
    n_out = H.shape[1]
    labels = list(labels) if labels is not None else [f"x{i + 1}" for i in range(n_out)]
    if len(labels) != n_out:
        raise ModelError(f"need {n_out} labels, got {len(labels)}")
    if ax is None:
        _, ax = plt.subplots(2, 1, figsize=(7.5, 6), sharex=True, layout="constrained")
    ax = np.asarray(ax).ravel()
    f = w / (2 * np.pi) if hz else w
    mag = np.abs(H)
    phase = np.degrees(np.unwrap(np.angle(H), axis=0))

    def to_mag(x):
        x = np.asarray(x, dtype=float)
        x = x[:, None] if x.ndim == 1 else x
        return 20 * np.log10(np.maximum(x, np.finfo(float).tiny)) if db else x

    for i in range(n_out):
        color = f"C{i}"
        ax[0].plot(f, to_mag(mag[:, i])[:, 0], color=color, label=labels[i])
        ax[1].plot(f, phase[:, i], color=color, label=labels[i])
        if bands is not None:
            lo, hi = (to_mag(x) for x in bands)
            ax[0].fill_between(f, lo[:, i], hi[:, i], color=color, alpha=0.25, lw=0)
        if phase_bands is not None:
            lo, hi = (np.asarray(x, dtype=float).reshape(w.size, -1) for x in phase_bands)
            ax[1].fill_between(f, lo[:, i], hi[:, i], color=color, alpha=0.25, lw=0)
    for a in ax:
        a.set_xscale("log")
        a.grid(True, which="both", alpha=0.3)
    if db:
        ax[0].set_ylabel(f"|H| (dB re 1 {unit})")
    else:
        ax[0].set_yscale("log")
        ax[0].set_ylabel(f"|H| ({unit})")
    ax[1].set_ylabel("phase (deg)")
    ax[1].set_xlabel("frequency (Hz)" if hz else "angular frequency omega (rad/s)")
    ax[0].legend(loc="best", fontsize="small")
    return ax


def plot_mode_shapes(modes, *, ax=None):
    """Mode shapes against cart number, one line per mode.

    Parameters
    ----------
    modes : UndampedModes or ComplexModes
        Modes of one system: ``shapes`` of shape (n, n) normalised on cart 1 and
        ``omega_rad_s`` of shape (n,).  Complex shapes are drawn by their real part.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from bayesmodal.modal import undamped_modes
    >>> ax = plot_mode_shapes(undamped_modes(np.eye(2), np.array([[2.0, -1.0], [-1.0, 2.0]])))
    >>> ax.get_xlabel()
    'cart'
    """
    import matplotlib.pyplot as plt

    shapes = np.asarray(modes.shapes)
    omega = np.asarray(modes.omega_rad_s)
    if shapes.ndim != 2:
        raise ModelError(f"plot_mode_shapes takes the modes of one system, got {shapes.shape}")
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4), layout="constrained")
    carts = np.arange(1, shapes.shape[0] + 1)
    for i in range(shapes.shape[1]):
        ax.plot(carts, np.real(shapes[:, i]), "o-",
                label=f"mode {i + 1}: {omega[i]:.4g} rad/s")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xticks(carts)
    ax.set_xlabel("cart")
    ax.set_ylabel("displacement / displacement of cart 1 (m/m)")
    ax.legend(loc="best", fontsize="small")
    return ax
