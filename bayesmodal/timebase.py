"""The time base of a record: its stamps as recorded, or a uniform grid fitted to them.

A uniform grid ``t_k = t0 + k dt`` is fitted to the timestamps by least squares;
:func:`regularise_time` replaces the timestamps by that grid when they only deviate from
it the way rounding or clock jitter does:

- rounding to a quantum ``q`` (the steps take exactly two values ``q`` apart, e.g. 4 and
  5 ms for ``dt = 4.42 ms`` rounded to 1 ms): every timestamp lies within ``q / 2`` of the
  grid (plus the grid's own least-squares error, ``~ q / sqrt(N)``);
- jitter: independent deviations, so that the residuals are uncorrelated from one
  sample to the next (lag-1 autocorrelation below 1/2; a missing sample or a drifting
  clock makes a step or a ramp in the residuals, whose autocorrelation is near 1) and
  smaller than half a step.

Stamps that scatter beyond half a step but independently from one sample to the next
(a microcontroller logger whose loop runs at about a millisecond with jitter, its stamps
rounded to whole ms) cannot be a uniform clock: they are the sample instants themselves.
:func:`choose_time_base` keeps them as recorded (``ReadOptions(time_base="auto")``, the
default); the linear model is then simulated exactly on them, each step with its own
zero-order hold.  ``time_base="grid"`` puts any monotone record on its fitted uniform
grid instead, ``time_base="stamps"`` keeps the recorded stamps whatever they look like.
Anything else (a missing sample, a change of rate, a drifting clock) is left alone in
``auto``, and ``Experiment`` refuses it as not equally spaced with both fixes; stamps
that stall for more than ``MAX_GAP_STEPS`` median steps are refused in every mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import ConfigError, DataError

__all__ = ["MAX_GAP_STEPS", "TIME_BASES", "TimeBase", "TimeRegularisation",
           "choose_time_base", "regularise_time"]

#: How a reader may take the time column (``ReadOptions.time_base``).
TIME_BASES = ("auto", "stamps", "grid")


@dataclass(frozen=True)
class TimeRegularisation:
    """How timestamps were put on a uniform grid.

    Attributes
    ----------
    t_s : ndarray, shape (N,)
        The uniform grid ``t0 + k dt``, s.
    dt : float
        Its step, s.
    kind : str
        ``"uniform"`` (nothing changed), ``"rounded"``, ``"jitter"`` or ``"irregular"``
        (left unchanged: not a rounded or jittered uniform grid).
    max_shift_s : float
        Largest distance of a timestamp from the grid, s.
    quantum_s : float
        Rounding quantum (``kind == "rounded"``), else NaN, s.
    """

    t_s: np.ndarray
    dt: float
    kind: str
    max_shift_s: float
    quantum_s: float = float("nan")

    def message(self) -> str:
        """One line saying what was done (empty for ``uniform`` and ``irregular``)."""
        pct = 100 * self.max_shift_s / self.dt
        if self.kind == "rounded":
            return (f"timestamps are rounded to {self.quantum_s:.3g} s; regularised to a "
                    f"uniform step of {self.dt:.6g} s, moving samples by at most "
                    f"{self.max_shift_s:.3g} s ({pct:.0f} % of a step)")
        if self.kind == "jitter":
            return (f"timestamps jitter around a uniform step of {self.dt:.6g} s by up to "
                    f"{self.max_shift_s:.3g} s ({pct:.0f} % of a step); regularised to the "
                    "uniform grid")
        return ""


#: Relative tolerance on the steps of a uniform grid (as in ``Experiment``).
_DT_RTOL = 1e-6

#: Fewest samples for telling jitter from a gap by the residuals' autocorrelation: the
#: lag-1 autocorrelation of independent residuals has a standard error 1/sqrt(N), so
#: N >= 64 keeps the 1/2 threshold beyond 4 standard errors.
_MIN_JITTER_SAMPLES = 64


def regularise_time(t_s) -> TimeRegularisation:
    """Fit a uniform grid to timestamps and say whether they are a rounded/jittered copy.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Finite, strictly increasing timestamps, s (``N >= 3``).

    Returns
    -------
    TimeRegularisation
        ``t_s`` is the fitted grid for ``"rounded"`` and ``"jitter"``, the input otherwise.

    Examples
    --------
    >>> t = np.round(np.arange(200) * 0.00442, 3)      # rounded to whole milliseconds
    >>> r = regularise_time(t)
    >>> r.kind, round(r.dt, 5)
    ('rounded', 0.00442)
    """
    t = np.asarray(t_s, dtype=float)
    n = t.size
    steps = np.diff(t)
    mean_dt = (t[-1] - t[0]) / (n - 1)
    if np.max(np.abs(steps - mean_dt)) <= _DT_RTOL * mean_dt + 1e-12:
        return TimeRegularisation(t, float(mean_dt), "uniform", 0.0)
    k = np.arange(n, dtype=float)
    dt, t0 = np.polyfit(k, t, 1)
    grid = t0 + k * dt
    r = t - grid
    shift = float(np.max(np.abs(r)))
    if not (dt > 0 and shift < 0.5 * dt):
        return TimeRegularisation(t, float(mean_dt), "irregular", shift)
    # rounding: exactly two step values, q apart, and every stamp within q/2 of the grid
    tol = _DT_RTOL * dt + 1e-12
    lo, hi = float(steps.min()), float(steps.max())
    two_values = np.all((np.abs(steps - lo) <= tol) | (np.abs(steps - hi) <= tol))
    q = hi - lo
    if two_values and q <= dt / 3 and (shift <= 0.5 * q + tol
                                       or _minimax_line(k, r / q) <= 0.5 + 1e-6):
        return TimeRegularisation(grid, float(dt), "rounded", shift, float(q))
    if n >= _MIN_JITTER_SAMPLES:
        rc = r - r.mean()
        rho1 = float(np.dot(rc[1:], rc[:-1]) / np.dot(rc, rc))
        if rho1 < 0.5:
            return TimeRegularisation(grid, float(dt), "jitter", shift)
    return TimeRegularisation(t, float(mean_dt), "irregular", shift)


#: Longest step a record may hold, in median steps: beyond it the logger stalled (samples
#: are missing and the input held over the gap is not known), not jittered.
MAX_GAP_STEPS = 5.0


@dataclass(frozen=True)
class TimeBase:
    """The time base a record is read with (:func:`choose_time_base`).

    Attributes
    ----------
    t_s : ndarray, shape (N,)
        The times to use, s: the recorded stamps, or a uniform grid.
    kind : str
        ``"uniform"`` (recorded on a uniform grid), ``"rounded"``, ``"jitter"``
        (regularised to the fitted grid), ``"grid"`` (put on the fitted grid on request),
        ``"stamps"`` (non-uniform stamps kept as recorded) or ``"irregular"`` (left
        unchanged for ``Experiment`` to refuse).
    recorded_stamps : bool
        ``t_s`` are non-uniform stamps to be simulated step by step.
    step_min_s, step_median_s, step_max_s : float
        Smallest, median and largest recorded step, s.
    grid_dt_s : float
        Step of the least-squares uniform grid, s.
    shift_min_s, shift_max_s : float
        Smallest and largest distance of a stamp from that grid (stamp minus grid), s.
    message : str
        The one-line warning to give (empty when there is nothing to say).
    """

    t_s: np.ndarray
    kind: str
    recorded_stamps: bool
    step_min_s: float
    step_median_s: float
    step_max_s: float
    grid_dt_s: float
    shift_min_s: float
    shift_max_s: float
    message: str = ""


def choose_time_base(t_s, mode: str = "auto") -> TimeBase:
    """Decide how a record's timestamps are used: as recorded, or on a uniform grid.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Finite, strictly increasing timestamps, s (``N >= 3``).
    mode : {"auto", "stamps", "grid"}
        See ``ReadOptions.time_base``.

    Returns
    -------
    TimeBase

    Raises
    ------
    DataError
        A step longer than ``MAX_GAP_STEPS`` median steps (samples missing), with the
        fix.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> k = np.arange(500)
    >>> t = np.round(k * 1.127 + rng.uniform(0, 0.12, 500)) / 1000  # a logger's stamps, ms
    >>> tb = choose_time_base(t)
    >>> tb.kind, tb.recorded_stamps, round(tb.step_min_s, 6), round(tb.step_max_s, 6)
    ('stamps', True, 0.001, 0.002)
    """
    if mode not in TIME_BASES:
        raise ConfigError(f"time_base must be one of {TIME_BASES}, got {mode!r}")
    t = np.asarray(t_s, dtype=float)
    steps = np.diff(t)
    n = t.size
    k = np.arange(n, dtype=float)
    dt, t0 = np.polyfit(k, t, 1)
    grid = t0 + k * dt
    r = t - grid
    median = float(np.median(steps))
    stats = dict(step_min_s=float(steps.min()), step_median_s=median,
                 step_max_s=float(steps.max()), grid_dt_s=float(dt),
                 shift_min_s=float(r.min()), shift_max_s=float(r.max()))
    reg = regularise_time(t)
    if reg.kind == "uniform":
        return TimeBase(t, "uniform", False, **stats)
    worst = int(np.argmax(steps))
    if steps[worst] > MAX_GAP_STEPS * median:
        raise DataError(
            f"time jumps by {steps[worst]:.4g} s after t = {t[worst]:.6g} s, "
            f"{steps[worst] / median:.0f} times the median step of {median:.4g} s: samples "
            "are missing; cut the record at the gap and read the parts as separate records")
    jitter = (f"steps {stats['step_min_s']:.4g} to {stats['step_max_s']:.4g} s (median "
              f"{median:.4g} s), stamps {stats['shift_min_s']:+.3g} to "
              f"{stats['shift_max_s']:+.3g} s from a uniform step of {dt:.6g} s")
    if mode == "grid":
        if reg.kind in ("rounded", "jitter"):
            return TimeBase(reg.t_s, reg.kind, False, **stats, message=reg.message())
        return TimeBase(grid, "grid", False, **stats,
                        message=f"timestamps put on a uniform grid: {jitter}; samples "
                        f"moved by up to {max(-r.min(), r.max()):.3g} s")
    kept = (f"timestamps are not uniform: {jitter}; kept as recorded: the linear model "
            "is simulated on them step by step (--time-base grid puts them on the "
            "uniform grid)")
    if mode == "stamps":
        return TimeBase(t, "stamps", True, **stats, message=kept)
    if reg.kind == "rounded":  # a uniform clock printed coarsely: the grid is the truth
        return TimeBase(reg.t_s, reg.kind, False, **stats, message=reg.message())
    if reg.kind == "jitter" or (n >= _MIN_JITTER_SAMPLES and _lag1(r) < 0.5):
        # independent scatter: the stamps are the sample instants, not a clock's noise
        return TimeBase(t, "stamps", True, **stats, message=kept)
    return TimeBase(t, "irregular", False, **stats)


def _lag1(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of grid residuals (independent jitter: about 0, standard
    error ``1 / sqrt(N)``; a gap, drift or change of rate: near 1)."""
    rc = r - r.mean()
    den = float(np.dot(rc, rc))
    return float(np.dot(rc[1:], rc[:-1]) / den) if den > 0 else 0.0


def _minimax_line(k: np.ndarray, r: np.ndarray) -> float:
    """Smallest ``h`` with ``|r_k - a - b k| <= h`` for all k (Chebyshev line fit).

    Timestamps rounded to ``q`` lie within ``q / 2`` of the true grid, so some line comes
    within ``1 / 2`` of ``r / q`` (the least-squares residuals in quanta); the
    least-squares line itself may not (exact ties put half the samples at ``q / 2``).
    """
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull, QhullError

    x = k / k[-1]  # a well-scaled abscissa
    # the largest deviation from a line is reached at a vertex of the points' convex hull
    try:
        v = ConvexHull(np.column_stack([x, r])).vertices
    except QhullError:  # all points on one line
        return 0.0
    x, r = x[v], r[v]
    n = x.size
    ones = np.ones(n)
    # variables (a, b, h): minimise h subject to +-(r - a - b x) <= h
    a_ub = np.block([[-ones[:, None], -x[:, None], -ones[:, None]],
                     [ones[:, None], x[:, None], -ones[:, None]]])
    b_ub = np.r_[-r, r]
    res = linprog([0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * 3,
                  method="highs")
    return float(res.x[2]) if res.success else float("inf")
