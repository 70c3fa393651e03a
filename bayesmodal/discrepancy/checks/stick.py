"""Stick detection: carts at rest where the linear model cannot rest.

Under a linear, asymptotically stable model a cart can only stay still at the equilibrium
``x_eq = K^-1 b v`` of the held input; if it stays still for a whole period of the slowest
mode anywhere else, something holds it: static friction.  A second sign is a cart that
sits still while the fitted linear model still predicts it to oscillate.

For every window of at least one slowest period within a stretch of constant input, a
cart is *at rest* if its measured position varies by less than ``rest_tol`` (a few noise
levels and encoder counts).  It is *stuck* if, at rest, it sits more than ``offset_tol``
from ``x_eq`` or the prediction moves by more than three times ``rest_tol`` in that window.
Under the linear model neither can happen beyond noise: an oscillation whose range fits
within ``rest_tol`` has an amplitude, hence an offset from ``x_eq``, below ``rest_tol / 2``.
"""

from __future__ import annotations

import numpy as np

from ...model.effects import suggested_by
from ._result import Diagnostic
from .residuals import LinearResiduals, constant_input_segments, noise_level

__all__ = ["stick_detection"]


def stick_detection(
    res: LinearResiduals,
    *,
    window_s: float | None = None,
    rest_counts: float = 3.0,
    offset_counts: float = 6.0,
    min_episodes: int = 1,
) -> Diagnostic:
    """Find episodes of carts stuck away from the linear model's equilibrium.

    Parameters
    ----------
    res : LinearResiduals
    window_s : float, optional
        Window length, s (default 1.2 periods of the slowest mode of the model, at least
        0.5 s).
    rest_counts : float
        ``rest_tol = rest_counts * max(q, 4 sigma)``: largest range of a cart at rest (``q``
        the encoder count, ``sigma`` the noise level).
    offset_counts : float
        ``offset_tol = offset_counts * max(q, 4 sigma)``: smallest offset from ``x_eq`` that
        counts as stuck.
    min_episodes : int
        Number of stuck episodes (merged overlapping windows) of one cart that makes a
        detection.

    Returns
    -------
    Diagnostic
        ``statistic``: the largest number of stuck episodes of any cart; ``threshold``:
        ``min_episodes``.  Detail: ``episodes`` (per cart, list of (start, stop, offset_m,
        predicted_range_m)), ``rest_tol_m``, ``offset_tol_m`` (n,), ``x_eq`` per stretch,
        ``stuck_mask`` (N, n) bool.
    """
    dt = res.dt
    M, _, K, b = res.matrices()
    omega = np.sqrt(np.min(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    if window_s is None:
        window_s = max(0.5, 1.2 * 2 * np.pi / omega)
    win = max(int(round(window_s / dt)), 3)
    hop = max(win // 4, 1)
    sigma = noise_level(res.residual, res.quantum_m)
    unit = np.maximum(res.quantum_m, 4 * sigma)
    rest_tol = rest_counts * unit
    offset_tol = offset_counts * unit
    n = res.n_outputs
    stuck = np.zeros((res.y.shape[0], n), bool)
    episodes: list[list] = [[] for _ in range(n)]
    eqs = []
    for a0, b0 in constant_input_segments(res.u, win):
        x_eq = np.linalg.solve(K, b * res.u[a0])
        eqs.append((a0, b0, x_eq))
        for s0 in range(a0, b0 - win + 1, hop):
            seg = res.y[s0 : s0 + win]
            pred = res.y_pred[s0 : s0 + win]
            rng = seg.max(axis=0) - seg.min(axis=0)
            prng = pred.max(axis=0) - pred.min(axis=0)
            off = seg.mean(axis=0) - x_eq
            hit = (rng <= rest_tol) & ((np.abs(off) > offset_tol) | (prng > 3 * rest_tol))
            stuck[s0 : s0 + win][:, hit] = True
    for i in range(n):
        m = stuck[:, i]
        edges = np.flatnonzero(np.diff(np.r_[0, m.astype(int), 0]))
        for s0, s1 in zip(edges[::2], edges[1::2], strict=True):
            eq = next((e for a0, b0, e in eqs if a0 <= s0 < b0), np.zeros(n))
            episodes[i].append((int(s0), int(s1), float(res.y[s0:s1, i].mean() - eq[i]),
                                float(np.ptp(res.y_pred[s0:s1, i]))))
    counts = np.array([len(e) for e in episodes])
    j = int(np.argmax(counts))
    detected = counts[j] >= min_episodes
    q = res.quantum_m
    offs = [abs(e[2]) / q for e in episodes[j]]
    summary = (
        f"stuck episodes per cart {counts.tolist()}"
        + (f"; cart {j + 1} rests up to {max(offs):.0f} counts "
           f"({max(offs) * q * 1e3:.2f} mm) from equilibrium" if offs else "")
    )
    return Diagnostic(
        name="stick",
        statistic=float(counts[j]),
        p_value=None,
        threshold=float(min_episodes),
        detected=bool(detected),
        suggests=suggested_by("stick") if detected else (),
        location=f"cart {j + 1}" if detected else None,
        summary=summary,
        detail={"episodes": episodes, "rest_tol_m": rest_tol, "offset_tol_m": offset_tol,
                "equilibria": eqs, "stuck_mask": stuck, "window": win},
    )
