"""The excitation a record holds: a pulse train, steps or hammer hits, and the segments
between them.

The impulse records hold a train of short pulses on a zero background, each followed by a
free decay; :func:`pulse_segments` cuts them pulse to pulse (the averages of
``pulse_frf``) and :func:`free_decay_segments` keeps the decays (the records of LSCE).  A
step record becomes an impulse train through its increments (:func:`step_increments`).
:func:`is_pulse_train`, :func:`is_step_input` and :func:`is_impact_train` tell the kinds
apart; the last looks at a measured force, whose sensor noise never leaves it at zero
between the hits.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["IMPACT_THRESHOLD", "free_decay_segments", "is_impact_train", "is_pulse_train",
           "is_step_input", "pulse_segments", "step_increments"]

#: Force above which a sample belongs to a hammer hit, relative to the largest force.
IMPACT_THRESHOLD = 0.05


def pulse_segments(u, *, min_gap: int = 20, drop_truncated: bool = True) -> np.ndarray:
    """Split a pulse train into pulse-to-pulse segments.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Input with isolated pulses on a zero background.
    min_gap : int
        Runs of at least this many zero samples separate two pulses.
    drop_truncated : bool
        Drop the last segment when the end of the record cuts its free decay short (it
        is shorter than a quarter of the median of the others, or than 8 samples): a
        transient cut off early leaks into every frequency.  Ignored with one pulse.

    Returns
    -------
    ndarray of int, shape (n_pulses, 3)
        Rows ``(start, pulse_end, stop)``: the pulse occupies ``start:pulse_end`` and the
        free decay ``pulse_end:stop``; ``stop`` is the next pulse's start (or N).

    Raises
    ------
    DataError
        If the input has no pulse.

    Examples
    --------
    >>> u = np.zeros(100); u[5:8] = 1.0; u[55:58] = 1.0
    >>> pulse_segments(u).tolist()
    [[5, 8, 55], [55, 58, 100]]
    >>> u[98] = 1.0                     # a pulse two samples before the end of the record
    >>> pulse_segments(u).tolist()
    [[5, 8, 55], [55, 58, 98]]
    """
    u = np.asarray(u, dtype=float)
    nz = np.flatnonzero(u != 0)
    if nz.size == 0:
        raise DataError("the input is all zeros; it holds no pulse")
    breaks = np.flatnonzero(np.diff(nz) > min_gap)
    starts = np.r_[nz[0], nz[breaks + 1]]
    ends = np.r_[nz[breaks], nz[-1]] + 1
    stops = np.r_[starts[1:], u.size]
    seg = np.column_stack([starts, ends, stops]).astype(int)
    if drop_truncated and len(seg) > 1:
        span = seg[:, 2] - seg[:, 0]
        if span[-1] < max(8.0, 0.25 * float(np.median(span[:-1]))):
            seg = seg[:-1]
    return seg


def is_pulse_train(u, *, max_duty: float = 0.1) -> bool:
    """True if the input is zero on all but a fraction ``max_duty`` of the samples."""
    u = np.asarray(u, dtype=float)
    return bool(np.any(u != 0) and np.mean(u != 0) <= max_duty)


def is_impact_train(force, *, threshold: float = IMPACT_THRESHOLD,
                    max_duty: float = 0.1) -> bool:
    """True for a hammer test: isolated hits, each followed by a long quiet stretch.

    The samples where ``|force|`` exceeds ``threshold`` times its largest value are the
    hits; the sensor's noise between them stays below (a load cell's noise is a small
    fraction of a hit's peak).  Those samples, the rest set to zero, must form a pulse
    train (:func:`is_pulse_train` with ``max_duty``), and each hit must take at most the
    fraction ``max_duty`` of its segment from its start to the next hit's (or the record's
    end, :func:`pulse_segments`), i.e. be followed by at least nine times its own length
    of quiet.  A shaker's sweep or random force exceeds the threshold on most samples; a
    hit at the end of the record, with no time to ring down, fails the second test.

    Parameters
    ----------
    force : ndarray, shape (N,)
        Measured force, N.
    threshold : float
        A sample belongs to a hit when ``|force|`` exceeds this fraction of the largest
        (as in :func:`~bayesmodal.ema.impact.find_impacts`).
    max_duty : float
        Largest fraction of the record, and of each hit's segment, the hits may take.

    Returns
    -------
    bool

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> f = rng.normal(0.0, 0.02, 3000); f[100:103] += 60.0; f[1600:1603] += 55.0
    >>> is_impact_train(f), is_impact_train(rng.normal(0.0, 1.0, 3000))
    (True, False)
    """
    f = np.abs(np.asarray(force, dtype=float))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or not np.any(f > 0):
        return False
    hits = np.where(f > threshold * f.max(), f, 0.0)
    if not is_pulse_train(hits, max_duty=max_duty):
        return False
    seg = pulse_segments(hits, drop_truncated=False)
    return bool(np.all(seg[:, 1] - seg[:, 0] <= max_duty * (seg[:, 2] - seg[:, 0])))


def is_step_input(u, *, max_changes: float = 0.01) -> bool:
    """True for steps: a piecewise-constant input that changes on at most a fraction
    ``max_changes`` of the samples and is not a pulse train."""
    u = np.asarray(u, dtype=float)
    changes = np.count_nonzero(np.diff(u))
    return bool(changes >= 1 and changes <= max_changes * u.size and not is_pulse_train(u))


def step_increments(u, y) -> tuple[np.ndarray, np.ndarray]:
    """Sample-to-sample increments of input and outputs, zero at the first sample.

    A step input becomes an impulse train, and its response a free decay after each
    impulse (the increments of a decay to a new rest position).  The system relating
    the increments is the same discrete system as the one relating ``u`` and ``y``
    (differencing commutes with it), so their FRF is the FRF of the record, without
    the leakage of a step that never returns to zero.

    Parameters
    ----------
    u : ndarray, shape (N,)
    y : ndarray, shape (N,) or (N, n_outputs)

    Returns
    -------
    du : ndarray, shape (N,)
    dy : ndarray, shape (N, n_outputs)

    Examples
    --------
    >>> du, dy = step_increments(np.r_[0.0, 0.0, 1.0, 1.0], np.zeros(4))
    >>> du.tolist()
    [0.0, 0.0, 1.0, 0.0]
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    return np.diff(u, prepend=u[:1]), np.diff(y, axis=0, prepend=y[:1])


def free_decay_segments(
    u,
    dt: float,
    *,
    skip_s: float = 0.0,
    duration_s: float | None = None,
    min_gap: int = 20,
) -> np.ndarray:
    """Index ranges of the free decays that follow each pulse.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Pulse-train input.
    dt : float
        Sample interval, s.
    skip_s : float
        Time skipped after the end of each pulse, s.
    duration_s : float, optional
        Length kept, s (default: until the next pulse).
    min_gap : int
        See ``pulse_segments``.

    Returns
    -------
    ndarray of int, shape (n_segments, 2)
        Rows ``(start, stop)`` with zero input on ``start:stop``.
    """
    seg = pulse_segments(u, min_gap=min_gap)
    start = seg[:, 1] + int(round(skip_s / dt))
    stop = seg[:, 2].copy()
    if duration_s is not None:
        stop = np.minimum(stop, start + int(round(duration_s / dt)))
    ok = stop - start >= 8
    if not np.any(ok):
        raise DataError("no free decay of at least 8 samples after the pulses")
    return np.column_stack([start[ok], stop[ok]])
