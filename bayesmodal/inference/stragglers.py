"""Walkers stranded in modes of negligible mass: move them onto the others during burn-in.

An ensemble sampler climbs into a posterior along many paths.  On a multimodal target
(the LuGre friction model on the four measured records has local modes 50 to 300 nats
below the best) a few walkers end the climb in a poor local mode and stay there: the
ordinary differential-evolution step only proposes points between walkers, and the mode
jump (``de-jump``) needs a partner in the stranded walker's own mode.  Such a walker never
contributes a draw of the posterior, yet it inflates R-hat with walkers as chains.

At stationarity the log posterior of a walker lies below the mode by ``chi2_d / 2`` for a
posterior of ``d`` parameters near a Gaussian, and the ensemble's median by about
``median(chi2_d) / 2``, so a walker more than ``(chi2_d(1 - p) - median(chi2_d)) / 2``
below the ensemble's median (``p = 1e-6``: 22.7 nats for 26 parameters) is not in the
typical set.  :func:`prune_stragglers` moves each such walker
onto a randomly chosen other walker plus a small differential-evolution jitter,
``z_a + 0.01 (z_b - z_c)``, so that the walkers stay distinct.  Used once, during burn-in
(``sample_posterior(..., prune=step)``): the retained draws come after it and the
sampler's invariance is untouched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

__all__ = ["Pruning", "prune_stragglers", "STRAGGLER_P"]

#: Tail probability of the chi-square cut: a walker in the typical set falls below it with
#: about this probability.
STRAGGLER_P = 1e-6
#: Size of the jitter, as a fraction of a difference of two good walkers.
JITTER = 0.01


@dataclass(frozen=True)
class Pruning:
    """Outcome of :func:`prune_stragglers`.

    Attributes
    ----------
    z : ndarray, shape (n_walkers, P)
        Walker positions after the move (sampling coordinates).
    moved : ndarray of int
        Indices of the walkers that were moved.
    cut : float
        Nats below the median log posterior beyond which a walker was moved.
    log_prob : ndarray, shape (n_moved,)
        Log posterior of the moved walkers before the move.
    """

    z: np.ndarray
    moved: np.ndarray
    cut: float
    log_prob: np.ndarray


def prune_stragglers(z: np.ndarray, log_prob: np.ndarray, rng=None,
                     p: float = STRAGGLER_P) -> Pruning:
    """Move walkers far below the ensemble's median log posterior onto the others.

    Parameters
    ----------
    z : array_like, shape (n_walkers, P)
        Walker positions in sampling coordinates.
    log_prob : array_like, shape (n_walkers,)
        Their log posterior densities (nats).
    rng : numpy.random.Generator or int, optional
    p : float
        Tail probability of the cut, ``(chi2_P(1 - p) - median(chi2_P)) / 2`` nats below
        the median.

    Returns
    -------
    Pruning

    Examples
    --------
    >>> z = np.random.default_rng(0).standard_normal((8, 2))
    >>> lp = -0.5 * (z**2).sum(axis=1)
    >>> lp[3] -= 500.0                      # one walker stranded far below
    >>> prune_stragglers(z, lp, rng=1).moved.tolist()
    [3]
    """
    z = np.array(z, dtype=float)
    lp = np.asarray(log_prob, dtype=float)
    if z.ndim != 2 or lp.shape != (z.shape[0],):
        raise ValueError(f"z must be (n_walkers, P) and log_prob (n_walkers,), got "
                         f"{z.shape} and {lp.shape}")
    if not 0 < p < 1:
        raise ValueError(f"p must be in (0, 1), got {p}")
    gen = np.random.default_rng(rng)
    # nats below the median: the chi-square tail beyond the median's own distance from the
    # mode (isf: no rounding of 1 - p)
    cut = float((chi2.isf(p, z.shape[1]) - chi2.median(z.shape[1])) / 2.0)
    finite = np.isfinite(lp)
    bad = ~finite | (lp < np.median(lp[finite]) - cut) if finite.any() else ~finite
    good = np.flatnonzero(~bad)
    if bad.any() and good.size < 3:
        raise ValueError("fewer than 3 walkers in the typical set: nothing to move the "
                         "stragglers onto; run a longer burn-in first")
    for i in np.flatnonzero(bad):
        a, b, c = gen.choice(good, 3, replace=False)
        z[i] = z[a] + JITTER * (z[b] - z[c])
    return Pruning(z, np.flatnonzero(bad), cut, lp[bad])
