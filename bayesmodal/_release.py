"""A hand-released free decay: where the release is, and the rest position it ends at.

A cart pushed aside by hand, held, and let go: the record holds the push, the hold (the
position constant within its noise), then the free decay.  The model's free response
starts at the release, so the record is cut there and fitted with its initial state
estimated.

Finding the release.  A cart released from rest at ``t_r`` leaves its held position
``h`` as ``h + a tau^2 / 2 + b tau^3 / 6 + ...`` with ``tau = t - t_r``: its velocity is
continuous (zero), its acceleration jumps from 0 to ``a``.  So the held level and the
onset are fitted together: for each candidate last held sample ``k0``, least squares of
the output that moves most on ``1``, ``[k > k0] tau^2`` and ``[k > k0] tau^3`` over the
samples up to where the motion first reaches 10 % of its range (where the two terms
still describe it: a cosine ``1 - cos(theta)`` reaches 10 % at ``theta = 0.45``, where
its next term is 1.7 % of the motion); ``k0`` is the candidate of least residual sum of
squares, the maximum-likelihood change point under Gaussian noise.  The hold must last
``MIN_HELD + 2`` samples at least; a push before it is allowed.

The rest before the input.  An encoder not zeroed with the carts at rest reads an
offset the model, which starts from rest at 0, cannot produce; with
``rest_offset="initial"`` each output's mean over the samples before the first non-zero
input is subtracted (refused, as below, when they drift there).

The final rest.  Dry friction stops the carts away from the springs' equilibrium, at
an offset the linear model cannot produce.  With ``rest_offset="final"`` each output's
last 10 % is taken as its rest: if the line fitted there drifts by more than 5 of its
standard errors (``sigma sqrt(12 / n)`` for the change across ``n`` samples, ``sigma``
from the median absolute first difference) the carts are still moving and the record is
refused; otherwise the mean of that stretch is subtracted from the whole output.
"""

from __future__ import annotations

import numpy as np

from ._errors import DataError

#: Fewest held samples before the first candidate release.
MIN_HELD = 10

#: Fraction of the motion's range that ends the stretch fitted for the release.
_ONSET_FRACTION = 0.1

#: Noise standard deviations from the held level where the push ends and the hold begins.
_K_HELD = 5.0

#: Fraction of the record taken as its final rest.
REST_FRACTION = 0.1

#: Standard errors of drift beyond which the final stretch is not at rest.
_K_DRIFT = 5.0


def find_release(where: str, y_m: np.ndarray) -> int:
    """Index of the last sample before a hand-released free decay starts.

    The output that moves most (largest distance between its held level and its final
    value) is used.  The held level is where it is farthest from its final value (the
    median of the record's last 10 %); the hold is the stretch around that sample within
    10 % of the range of it, less the end of the push (samples before that one farther
    than 5 noise standard deviations, from the median absolute first difference, from
    the stretch's median); the release is the change point fitted over the hold and the
    start of the decay (module docstring).

    Parameters
    ----------
    where : str
        The file, for messages.
    y_m : ndarray, shape (N, n_outputs)
        Positions, m: (the push,) the hold (constant within noise, at least
        ``MIN_HELD`` samples), then the free decay.

    Returns
    -------
    int
        ``k0``: the last held sample; the decay starts after it.

    Raises
    ------
    DataError
        No output moves, or no hold of ``MIN_HELD`` samples before the decay.
    """
    y = np.asarray(y_m, float).reshape(len(y_m), -1)
    final = np.median(y[-max(1, int(REST_FRACTION * len(y))):], axis=0)
    far = np.abs(y - final)
    i = int(np.argmax(far.max(axis=0)))
    k_held = int(np.argmax(far[:, i]))
    if far[k_held, i] == 0:
        raise DataError(f"{where}: no output moves; there is no release to find")
    dev = np.abs(y[:, i] - y[k_held, i])
    away = dev > _ONSET_FRACTION * far[k_held, i]
    after = np.flatnonzero(away[k_held:])
    before = np.flatnonzero(away[:k_held])
    onset = k_held + int(after[0]) if after.size else len(y) - 1
    first = int(before[-1]) + 1 if before.size else 0
    # the hold proper: from where the push ends within 5 noise standard deviations of
    # the held level (the push's approach to it is no part of the change-point model)
    band = y[first: onset + 1, i]
    d1 = np.diff(band)
    sigma = np.median(np.abs(d1 - np.median(d1))) / 0.6745 / np.sqrt(2)
    pushed = np.flatnonzero(np.abs(y[first:k_held, i] - np.median(band)) > _K_HELD * sigma)
    first += int(pushed[-1]) + 1 if pushed.size else 0
    if onset - first < MIN_HELD + 2:
        raise DataError(f"{where}: output {i + 1} is held for {onset - first} samples before "
                        f"it moves; --release auto needs a hold of at least {MIN_HELD + 2} "
                        "samples (the cart at rest in the hand) before the release")
    seg = y[first: onset + 1, i]
    k = np.arange(seg.size, dtype=float)
    n = seg.size - 1
    best, k_best = np.inf, 0
    for k0 in range(MIN_HELD - 1, n - 1):
        tau = np.clip(k - k0, 0.0, None) / (n - k0)  # scaled: a well-conditioned fit
        a = np.column_stack([np.ones_like(tau), tau**2, tau**3])
        coef, *_ = np.linalg.lstsq(a, seg, rcond=None)
        sse = float(np.sum((seg - a @ coef) ** 2))
        if sse < best:
            best, k_best = sse, k0
    return first + k_best


def final_rest(where: str, y_m: np.ndarray) -> np.ndarray:
    """Each output's rest position over the last ``REST_FRACTION`` of a record.

    Parameters
    ----------
    where : str
        The file, for messages.
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.

    Returns
    -------
    ndarray, shape (n_outputs,)
        The mean of each output over the final stretch, m.

    Raises
    ------
    DataError
        An output still drifts over the final stretch (not at rest), or the stretch holds
        fewer than 10 samples.
    """
    y = np.asarray(y_m, float).reshape(len(y_m), -1)
    n = int(round(REST_FRACTION * len(y)))
    if n < MIN_REST_SAMPLES:
        raise DataError(f"{where}: the record's final {REST_FRACTION:.0%} holds {n} samples, "
                        "too few to take the rest offset from")
    return _rest_level(where, y[-n:], f"over the last {REST_FRACTION:.0%} of the record",
                       "there is no final rest to take the offset from; record until the "
                       "carts stop, or drop --rest-offset final")


def initial_rest(where: str, v_volt: np.ndarray, y_m: np.ndarray) -> np.ndarray:
    """Each output's rest level before the first input: the offset of a sensor that was
    not zeroed with the carts at rest.

    Parameters
    ----------
    where : str
        The file, for messages.
    v_volt : ndarray, shape (N,)
        Input, V; the rest is the samples before its first non-zero value.
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.

    Returns
    -------
    ndarray, shape (n_outputs,)
        The mean of each output over the samples before the first input, m.

    Raises
    ------
    DataError
        No input, fewer than ``MIN_REST_SAMPLES`` samples before it, or an output that
        drifts there (the carts move before the input).
    """
    v = np.asarray(v_volt, float)
    y = np.asarray(y_m, float).reshape(v.size, -1)
    driven = np.flatnonzero(v != 0)
    if driven.size == 0:
        raise DataError(f"{where}: the input is all zeros, so there is no rest before the "
                        "first input; --rest-offset initial is for a driven record (a "
                        "free decay takes --rest-offset final)")
    n = int(driven[0])
    if n < MIN_REST_SAMPLES:
        raise DataError(f"{where}: the input starts at sample {n + 1}; --rest-offset initial "
                        f"needs at least {MIN_REST_SAMPLES} samples at rest before it "
                        "(start the record, or the window, earlier)")
    return _rest_level(where, y[:n], "before the first input",
                       "there is no rest to take the offset from; start the record with "
                       "the carts at rest, or drop --rest-offset initial")


#: Fewest samples a rest level is taken from.
MIN_REST_SAMPLES = 10


def _rest_level(where: str, stretch: np.ndarray, when: str, fix: str) -> np.ndarray:
    """The mean of each output over ``stretch`` (shape (n, n_outputs), m), refused when
    a line fitted to it drifts by more than ``_K_DRIFT`` of its standard errors
    (``sigma sqrt(12 / n)``, ``sigma`` from the median absolute first difference)."""
    n = len(stretch)
    k = np.arange(n, dtype=float)
    kc = k - k.mean()
    slope = kc @ (stretch - stretch.mean(axis=0)) / (kc @ kc)
    drift = np.abs(slope) * (n - 1)
    d1 = np.diff(stretch, axis=0)
    sigma = np.median(np.abs(d1 - np.median(d1, axis=0)), axis=0) / 0.6745 / np.sqrt(2)
    limit = _K_DRIFT * sigma * np.sqrt(12.0 / n) + 1e-12
    moving = np.flatnonzero(drift > limit)
    if moving.size:
        j = int(moving[0])
        raise DataError(
            f"{where}: output {j + 1} still moves {when} (it drifts by "
            f"{1e3 * drift[j]:.3g} mm, noise {1e3 * sigma[j]:.2g} mm), so {fix}")
    return stretch.mean(axis=0)
