"""The part of a record to fit: a time window, and whether it starts at rest.

A window keeps the samples ``t_start <= t <= t_end`` with their times as recorded, so that
plots and messages name the instants of the file.  The linear model's default initial
state is rest (every cart at 0, the input 0 before the first sample); a window cut where
the carts move or sit displaced breaks that, and is fitted with its initial state
estimated.  :func:`motion_at_start` says whether a record starts at rest.
"""

from __future__ import annotations

import numpy as np

from . import _release
from ._errors import DataError

#: Noise standard deviations within which a position counts as zero.
_K_NOISE = 5.0

#: Fraction of the record's largest displacement within which a position counts as zero
#: (a floor for records without visible noise, such as whole encoder counts).
_REST_FRACTION = 1e-3


def select(where: str, t_s: np.ndarray, v_volt: np.ndarray, y_m: np.ndarray, opts):
    """The part of a record to fit, and its outputs less their final rest if asked.

    The time window first (:func:`cut`), then, with ``opts.release == "auto"``, the cut
    at the release of a hand-released decay (``_release.find_release``), then, with
    ``opts.rest_offset == "final"``, each output less its final rest position
    (``_release.final_rest``), or with ``"initial"`` less its rest level before the first
    input (``_release.initial_rest``).

    Parameters
    ----------
    where : str
        The file, for messages.
    t_s : ndarray, shape (N,)
        Times, s.
    v_volt : ndarray, shape (N,)
        Input, V.
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.
    opts : ReadOptions

    Returns
    -------
    t_s, v_volt, y_m : ndarray
        The kept samples, shapes (M,), (M,), (M, n_outputs).
    """

    part = cut(where, t_s, opts.t_start, opts.t_end)
    t, v, y = t_s[part], v_volt[part], y_m[part]
    if opts.release == "auto":
        if np.any(v != 0):
            raise DataError(f"{where}: the input is not zero (up to "
                            f"{np.max(np.abs(v)):.3g} V); --release auto is for a cart "
                            "released by hand with no input")
        k0 = _release.find_release(where, y)
        t, v, y = t[k0:], v[k0:], y[k0:]
    if opts.rest_offset == "final":
        y = y - _release.final_rest(where, y)
    elif opts.rest_offset == "initial":
        y = y - _release.initial_rest(where, v, y)
    return t, v, y


def cut(where: str, t_s: np.ndarray, t_start: float | None, t_end: float | None) -> slice:
    """The samples of a time window.

    Parameters
    ----------
    where : str
        The file, for messages.
    t_s : ndarray, shape (N,)
        The record's times, s (uniform).
    t_start, t_end : float or None
        The window, s of the record's clock; None: from the first or to the last sample.

    Returns
    -------
    slice
        Of at least 3 samples.

    Raises
    ------
    DataError
        A bound outside the record (beyond half a step), or fewer than 3 samples inside;
        the message names the record's span.
    """
    t0, t1 = float(t_s[0]), float(t_s[-1])
    dt = (t1 - t0) / (t_s.size - 1)
    span = f"the record spans {t0:g} to {t1:g} s (step {dt:.6g} s)"
    lo = t0 if t_start is None else t_start
    hi = t1 if t_end is None else t_end
    for name, t in (("t_start", t_start), ("t_end", t_end)):
        if t is not None and not (t0 - dt / 2 <= t <= t1 + dt / 2):
            raise DataError(f"{where}: {name} = {t:g} s is outside the record; {span}")
    if hi <= lo:
        raise DataError(f"{where}: the window {lo:g} to {hi:g} s is empty (t_end must be "
                        f"after t_start); {span}")
    # a bound equal to a sample's time up to rounding keeps that sample
    tol = 1e-9 * dt
    start = int(np.searchsorted(t_s, lo - tol, side="left"))
    stop = int(np.searchsorted(t_s, hi + tol, side="right"))
    if stop - start < 3:
        raise DataError(f"{where}: the window {lo:g} to {hi:g} s holds {stop - start} "
                        f"sample(s), fewer than 3; {span}")
    return slice(start, stop)


def motion_at_start(y_m: np.ndarray, v_volt: np.ndarray, dt: float) -> str:
    """Why a record does not start at rest, or ``""`` when it does.

    At rest: the input is 0 at the first sample and every position within
    ``max(5 sigma, 1e-3 peak)`` of 0 over the first three samples, where ``sigma`` is the
    noise standard deviation estimated from the median absolute second difference
    (``MAD / 0.6745 / sqrt(6)``: a second difference of white noise has variance
    ``6 sigma^2``; the motion's own curvature makes it an overestimate, so the test
    leans towards rest) and ``peak`` the largest displacement of the record.

    Parameters
    ----------
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.
    v_volt : ndarray, shape (N,)
        Input, V.
    dt : float
        Sample interval, s.

    Returns
    -------
    str
        E.g. ``"cart 2 at 3.1 mm"``, or ``"the input at 0.5 V"``.
    """
    y = np.asarray(y_m, float).reshape(len(v_volt), -1)
    if v_volt[0] != 0:
        return f"the input at {v_volt[0]:.3g} V"
    d2 = np.diff(y, n=2, axis=0)
    sigma = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) / 0.6745 / np.sqrt(6)
    tol = np.maximum(_K_NOISE * sigma, _REST_FRACTION * np.max(np.abs(y), axis=0))
    head = np.abs(y[:3])
    bad = np.flatnonzero(np.any(head > tol, axis=0))
    if bad.size == 0:
        return ""
    i = int(bad[0])
    return f"output {i + 1} at {1e3 * y[0, i]:.3g} mm"


#: Fewest samples before the first input for its rest level to be judged.
_MIN_REST = 10

def offset_at_rest(y_m: np.ndarray, v_volt: np.ndarray) -> str:
    """Where a driven record's outputs rest away from 0 before the first input, or ``""``.

    The model starts from rest at 0; an encoder not zeroed with the carts at rest reads
    a constant offset there, which a fit from rest absorbs in its parameters (on a
    simulated record an offset of 37 counts moved ``g_v`` by 1 000 standard errors, the
    fit still above 99 %).  An output's rest level is the mean of its samples before the
    first non-zero input (at least ``_MIN_REST`` of them); it is an offset when it lies
    beyond both 5 noise standard deviations (from the median absolute first difference
    there) and 0.1 % of the output's range over the record (a floor for whole encoder
    counts at rest, whose differences are all 0), from the first sample on, and the
    output is still there (a line fitted over the stretch drifts by no more than 5 of
    its standard errors, plus the floor): carts that move before the input, pushed by a
    bias of the drive, are no offset of the sensor.

    Parameters
    ----------
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.
    v_volt : ndarray, shape (N,)
        Input, V.

    Returns
    -------
    str
        E.g. ``"output 1 at 0.163 mm"``; ``""`` when every output rests at 0, or the
        record has no rest of ``_MIN_REST`` samples before its input.
    """
    v = np.asarray(v_volt, float)
    y = np.asarray(y_m, float).reshape(v.size, -1)
    driven = np.flatnonzero(v != 0)
    if driven.size == 0 or driven[0] < _MIN_REST:
        return ""
    rest = y[: driven[0]]
    n = len(rest)
    level = rest.mean(axis=0)
    d1 = np.diff(rest, axis=0)
    sigma = np.median(np.abs(d1 - np.median(d1, axis=0)), axis=0) / 0.6745 / np.sqrt(2)
    tol = np.maximum(_K_NOISE * sigma, _REST_FRACTION * np.ptp(y, axis=0))
    # at rest: a line fitted there drifts by at most 5 of its standard errors (carts
    # pushed before the input, e.g. by a bias of the drive, move from 0: not an offset)
    k = np.arange(n, dtype=float) - (n - 1) / 2
    drift = np.abs(k @ (rest - level) / (k @ k)) * (n - 1)
    still = drift <= _K_NOISE * sigma * np.sqrt(12.0 / n) + _REST_FRACTION * np.ptp(y, axis=0)
    bad = np.flatnonzero((np.abs(level) > tol) & still & (np.abs(y[0]) > tol))
    if bad.size == 0:
        return ""
    i = int(bad[0])
    return f"output {i + 1} at {1e3 * level[i]:.3g} mm"
