"""How to read a lab's record: which column is which, the units, and the time base.

Files come as the lab's software writes them: MATLAB variables named ``enc1, enc2,
target_v, time`` next to a struct of run parameters, text files with header rows,
positions in encoder counts, the input in converter units, timestamps rounded to whole
milliseconds.  :class:`ReadOptions` says how to turn such a file into an
``Experiment`` (time in s, input in V, positions in m); :func:`parse_columns` and
:func:`parse_scale` read the command-line spellings (``t=time,v=target_v,x1=enc1`` and
``5/4096``).

Time base.  A uniform grid ``t_k = t0 + k dt`` is fitted to the timestamps by least
squares; :func:`regularise_time` replaces the timestamps by that grid when they only
deviate from it the way rounding or clock jitter does:

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

import re
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ._errors import ConfigError, DataError

__all__ = ["DriveSign", "MAX_GAP_STEPS", "REST_OFFSETS", "ReadOptions", "TIME_BASES", "TimeBase",
           "TimeRegularisation", "choose_time_base", "drive_sign", "parse_columns",
           "parse_scale", "regularise_time"]

#: Which rest level of each output is subtracted (``ReadOptions.rest_offset``).
REST_OFFSETS = ("none", "initial", "final")

#: How a reader may take the time column (``ReadOptions.time_base``).
TIME_BASES = ("auto", "stamps", "grid")

_ROLE = re.compile(r"^(t|v|x[1-9][0-9]*)$")


def _check_columns(columns) -> tuple[tuple[str, str], ...]:
    items = tuple(columns.items()) if isinstance(columns, Mapping) else tuple(columns)
    roles = []
    out = []
    for item in items:
        role, source = item
        role, source = str(role).strip(), str(source).strip()
        if not _ROLE.match(role):
            raise ConfigError(f"column map: unknown role {role!r}; the roles are t, v and "
                              "x1..xn (e.g. t=time,v=target_v,x1=enc1,x2=enc2)")
        if not source:
            raise ConfigError(f"column map: role {role!r} names no column")
        if role in roles:
            raise ConfigError(f"column map: role {role!r} is given twice")
        roles.append(role)
        out.append((role, source))
    missing = [r for r in ("t", "v") if r not in roles]
    xs = sorted(int(r[1:]) for r in roles if r[0] == "x")
    if not xs:
        missing.append("x1")
    if missing:
        raise ConfigError(f"column map: role(s) {missing} missing; map t, v and x1..xn "
                          "(e.g. t=time,v=target_v,x1=enc1,x2=enc2)")
    if xs != list(range(1, len(xs) + 1)):
        raise ConfigError(f"column map: outputs must be x1..xn without gaps, got "
                          f"{[f'x{i}' for i in xs]}")
    return tuple(out)


def _positive(name: str, value, *, allow_none: bool = False, signed: bool = False):
    """A finite scale factor: > 0, or (``signed``) non-zero of either sign."""
    if value is None and allow_none:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a number, got {value!r}") from None
    if signed and not (np.isfinite(x) and x != 0):
        raise ConfigError(f"{name} must be finite and non-zero (negative for a reversed "
                          f"sign), got {value!r}")
    if not signed and not (np.isfinite(x) and x > 0):
        raise ConfigError(f"{name} must be finite and > 0, got {value!r}")
    return x


def _time(name: str, value) -> float | None:
    """A finite time in s, or None."""
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a time in s, got {value!r}") from None
    if isinstance(value, bool) or not np.isfinite(x):
        raise ConfigError(f"{name} must be a finite time in s, got {value!r}")
    return x


@dataclass(frozen=True)
class ReadOptions:
    """How to read a record whose layout or units differ from the ECP defaults.

    Parameters
    ----------
    columns : mapping of str to str, optional
        Role to column: roles ``t`` (time), ``v`` (input) and ``x1..xn`` (outputs, n
        outputs); a column is a MATLAB variable (``enc1``; a struct field as
        ``run.enc1``), a header name of a text file (``Encoder 1 Pos``), or a 1-based
        column number of a text file (``"3"``).  Other variables and columns are ignored.
        Default: the file's own ``t, x1..xn, v`` layout.  Stored as a tuple of pairs.
    input_scale : float
        Volts per unit of the input column (``5 / 4096`` for a 12-bit converter over
        5 V), V; non-zero, negative for a drive wired the other way round (+V moves the
        carts to negative counts: ``-1``).
    time_scale : float
        Seconds per unit of the time column (``1e-3`` for milliseconds), s.
    m_per_count : float, optional
        Metres per unit of the output columns, m; non-zero, negative for encoders that
        count the other way.  Default: ``ECP_M_PER_COUNT`` for the ECP ``.mat``/``.txt``
        files (encoder counts), 1 for ``.csv`` (metres).
    n_outputs : int, optional
        Number of outputs expected; a record with another number is refused.
    input_kind : {"voltage", "force"}
        What the input column holds (``Rig.input``): a command voltage, V (checked
        against the rig's +-10 V), or a measured force, N (after ``input_scale``, N per
        unit).
    output_kinds : tuple of str, optional
        What each output column measures, ``"position"``, ``"velocity"`` or
        ``"acceleration"`` (``Rig.output_kinds``); default every column a position.  The
        plausibility check of displacements reads the position columns only.
    output_scales : tuple of float, optional
        SI units of each output's kind (m, m/s, m/s^2) per unit of its column, signed
        (``Sensor.si_per_unit``: 9.80665 for an accelerometer in g, -1 for a sensor facing
        -x); replaces ``m_per_count`` for every column.
    time_base : {"auto", "stamps", "grid"}
        ``"auto"``: stamps rounded or jittered within half a step are put on their
        fitted uniform grid, stamps scattered further but independently (a logger's
        jitter) are kept as recorded, anything else is refused; ``"stamps"``: keep the
        recorded stamps (only the linear fit simulates on them); ``"grid"``: put the
        stamps on their least-squares uniform grid.  See :func:`choose_time_base`.
    t_start, t_end : float, optional
        A time window, s of the record's own clock (after ``time_scale``): the samples
        with ``t_start <= t <= t_end`` are kept, with their times as recorded.  Both
        bounds must lie within the record and ``t_end > t_start``.  A window that does
        not start at rest needs its initial state estimated (``fit_lsq(...,
        initial_state="estimate")``, ``--initial-state estimate``).
    release : {None, "auto"}
        ``"auto"``: a hand-released free decay; the record (or its window) is cut at the
        release, the last sample before the held cart moves (``bayesmodal._release``),
        and its initial state must be estimated (the CLI does so).
    rest_offset : {"none", "initial", "final"}
        ``"initial"``: subtract from each output its mean over the samples before the
        first non-zero input (an encoder not zeroed with the carts at rest; at least 10
        samples, refused when they drift).  ``"final"``: subtract from each output its
        mean over the record's last 10 %, where dry friction left the carts at rest away
        from the springs' equilibrium (refused when they still move there).

    Examples
    --------
    >>> opts = ReadOptions(columns={"t": "time", "v": "target_v", "x1": "enc1"},
    ...                    input_scale=5 / 4096)
    >>> opts.column_map["x1"], opts.n_mapped_outputs
    ('enc1', 1)
    """

    columns: tuple[tuple[str, str], ...] | None = None
    input_scale: float = 1.0
    time_scale: float = 1.0
    m_per_count: float | None = None
    n_outputs: int | None = None
    input_kind: str = "voltage"
    output_kinds: tuple[str, ...] | None = None
    output_scales: tuple[float, ...] | None = None
    time_base: str = "auto"
    t_start: float | None = None
    t_end: float | None = None
    release: str | None = None
    rest_offset: str = "none"

    def __post_init__(self) -> None:
        if self.time_base not in TIME_BASES:
            raise ConfigError(f"time_base must be one of {TIME_BASES}, got {self.time_base!r}")
        if self.columns is not None:
            object.__setattr__(self, "columns", _check_columns(self.columns))
        # a sign flip of the input or the outputs is a lab convention; time runs forwards
        object.__setattr__(self, "input_scale",
                           _positive("input_scale", self.input_scale, signed=True))
        object.__setattr__(self, "time_scale", _positive("time_scale", self.time_scale))
        object.__setattr__(self, "m_per_count", _positive("m_per_count", self.m_per_count,
                                                          allow_none=True, signed=True))
        if self.input_kind not in ("voltage", "force"):
            raise ConfigError(f"input_kind must be 'voltage' or 'force', got "
                              f"{self.input_kind!r}")
        kinds = ("position", "velocity", "acceleration")
        if self.output_kinds is not None:
            ok = tuple(str(k) for k in self.output_kinds)
            bad = [k for k in ok if k not in kinds]
            if bad or not ok:
                raise ConfigError(f"output_kinds must list {kinds} values, one per output "
                                  f"column, got {self.output_kinds!r}")
            object.__setattr__(self, "output_kinds", ok)
        if self.output_scales is not None:
            sc = tuple(_positive("output_scales", x, signed=True) for x in self.output_scales)
            if not sc or (self.output_kinds is not None
                          and len(sc) != len(self.output_kinds)):
                raise ConfigError(f"output_scales needs one scale per output column (as "
                                  f"output_kinds), got {self.output_scales!r}")
            object.__setattr__(self, "output_scales", sc)
        if self.n_outputs is not None:
            n = int(self.n_outputs)
            if n != self.n_outputs or n < 1:
                raise ConfigError(f"n_outputs must be an integer >= 1, got {self.n_outputs!r}")
            m = self.n_mapped_outputs
            if m is not None and m != n:
                raise ConfigError(f"the column map names {m} outputs but n_outputs is {n}")
            object.__setattr__(self, "n_outputs", n)
        for key in ("t_start", "t_end"):
            object.__setattr__(self, key, _time(key, getattr(self, key)))
        if self.t_start is not None and self.t_end is not None and self.t_end <= self.t_start:
            raise ConfigError(f"t_end ({self.t_end:g} s) must be after t_start "
                              f"({self.t_start:g} s)")
        if self.release not in (None, "auto"):
            raise ConfigError(f"release must be 'auto' (a hand-released decay, cut at the "
                              f"release) or None, got {self.release!r}")
        if self.rest_offset not in REST_OFFSETS:
            raise ConfigError(f"rest_offset must be one of {REST_OFFSETS} (subtract the "
                              "rest level before the first input, or the final rest "
                              f"position), got {self.rest_offset!r}")

    @property
    def column_map(self) -> dict[str, str] | None:
        """The column map as a dict (role to column), or None."""
        return None if self.columns is None else dict(self.columns)

    @property
    def n_mapped_outputs(self) -> int | None:
        """Number of outputs the column map names (None without a map)."""
        if self.columns is None:
            return None
        return sum(1 for role, _ in self.columns if role[0] == "x")


def parse_scale(text: str, name: str = "scale", *, signed: bool = False) -> float:
    """A scale factor written as a number or a fraction.

    Parameters
    ----------
    text : str
        ``"5/4096"``, ``"0.001"``, ``"1e-3"``, ``"1/1000"`` (or ``"-1"``, ``"-5/4096"``
        when ``signed``).
    name : str
        Option name for the error message.
    signed : bool
        Accept a negative factor (a sign convention: a reversed drive or encoder); zero
        is refused either way.

    Returns
    -------
    float

    Raises
    ------
    ConfigError
        Not a number or fraction, not finite, zero, or negative unless ``signed``.

    Examples
    --------
    >>> parse_scale("5/4096") == 5 / 4096
    True
    >>> parse_scale("-1", "--input-scale", signed=True)
    -1.0
    """
    s = str(text).strip()
    try:
        num, sep, den = s.partition("/")
        value = float(Fraction(num.strip())) / (float(Fraction(den.strip())) if sep else 1.0)
    except (ValueError, ZeroDivisionError):
        raise ConfigError(f"{name}: {text!r} is not a number or fraction (e.g. 5/4096 or "
                          "0.001)") from None
    except OverflowError:  # beyond a float (1e400): refused as not finite below
        value = float("inf")
    if signed and not (np.isfinite(value) and value != 0):
        raise ConfigError(f"{name}: {text!r} must be finite and non-zero (negative for a "
                          "reversed sign)")
    if not signed and not (np.isfinite(value) and value > 0):
        raise ConfigError(f"{name}: {text!r} must be finite and > 0")
    return value


def parse_columns(text: str) -> dict[str, str]:
    """A column map written as ``role=column,...``.

    Parameters
    ----------
    text : str
        E.g. ``"t=time,v=target_v,x1=enc1,x2=enc2"``; columns may be MATLAB variables,
        struct fields (``run.enc1``), header names or 1-based column numbers.

    Returns
    -------
    dict
        Role to column, checked as in :class:`ReadOptions`.

    Raises
    ------
    ConfigError
        An item without ``=``, an unknown or repeated role, or missing ``t``, ``v``, ``x1``.

    Examples
    --------
    >>> parse_columns("t=time, v=target_v, x1=enc1")
    {'t': 'time', 'v': 'target_v', 'x1': 'enc1'}
    """
    pairs = []
    for item in filter(None, (s.strip() for s in str(text).split(","))):
        role, sep, source = item.partition("=")
        if not sep:
            raise ConfigError(f"column map: {item!r} is not ROLE=COLUMN (e.g. "
                              "t=time,v=target_v,x1=enc1,x2=enc2)")
        pairs.append((role.strip(), source.strip()))
    return dict(_check_columns(pairs))


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


#: Low-pass corner for the static response, Hz: below the rig's modes (1-5 Hz; the ECP
#: 210's first is at 1.3 Hz), where every cart follows the input in phase (a chain of
#: springs to ground has a static flexibility matrix ``K^-1`` with positive entries).
STATIC_BAND_HZ = 0.5

#: Student t of a low-frequency correlation beyond which its sign is taken as known.
_T_SIGNIFICANT = 4.0


@dataclass(frozen=True)
class DriveSign:
    """Which way the carts follow the input at low frequency.

    Attributes
    ----------
    correlation : ndarray, shape (n_outputs,)
        Correlation of the low-passed input with each low-passed output.
    t_stat : ndarray, shape (n_outputs,)
        Its Student t, ``r sqrt((n_eff - 2) / (1 - r^2))``.
    n_effective : float
        Independent samples of signals band-limited to ``band_hz`` over the record,
        ``2 band_hz T``.
    band_hz : float
        Low-pass corner, Hz.
    reversed : bool
        Every output moves against the input, at least one beyond ``t = -4``: the drive
        is probably wired the other way round.
    """

    correlation: np.ndarray
    t_stat: np.ndarray
    n_effective: float
    band_hz: float
    reversed: bool

    def message(self) -> str:
        """One line with the evidence and the fix (empty unless ``reversed``)."""
        if not self.reversed:
            return ""
        rs = ", ".join(f"{r:.2f}" for r in self.correlation)
        return (f"the carts move against the input: below {self.band_hz:g} Hz, where a "
                f"positive voltage pushes every cart forwards, the outputs correlate with "
                f"the input at {rs}; the drive may be reversed: if +V moves the carts to "
                "negative counts give --input-scale -1 (ReadOptions(input_scale=-1))")


def drive_sign(v_volt, y_m, dt: float, *, band_hz: float = STATIC_BAND_HZ) -> DriveSign | None:
    """Guess from a record's static response whether its drive is reversed.

    Both signals are low-passed (4th-order Butterworth, forwards and backwards, so no
    phase shift) below ``band_hz``, under the rig's modes, where the carts follow the
    input quasi-statically and in phase; there the correlation of input and position is
    positive for every cart.  A negative correlation on every output, at least one with
    a Student t below ``-4`` on the ``2 band_hz T`` independent samples a band-limited
    record holds (a chance correlation gets there with probability 0.2 % on 10 such
    samples, 0.02 % on 37), says the carts move against the input.

    Parameters
    ----------
    v_volt : ndarray, shape (N,)
        Input, V.
    y_m : ndarray, shape (N, n_outputs)
        Positions, m.
    dt : float
        Sample interval, s.
    band_hz : float
        Low-pass corner, Hz (below the first mode).

    Returns
    -------
    DriveSign or None
        None when the record cannot tell: no input, shorter than a few periods of
        ``band_hz``, or a sample rate too low for the band.

    Examples
    --------
    >>> t = np.arange(4000) * 0.005
    >>> v = 0.5 * ((t % 8) < 4)                      # a slow square wave
    >>> drive_sign(v, -0.01 * v[:, None], 0.005).reversed
    True
    """
    from scipy.signal import butter, sosfiltfilt

    v = np.asarray(v_volt, float)
    y = np.asarray(y_m, float).reshape(v.size, -1)
    n_eff = 2.0 * band_hz * v.size * dt
    nyquist = 0.5 / dt
    if n_eff < 4 or band_hz >= 0.5 * nyquist or np.ptp(v) == 0:
        return None
    sos = butter(4, band_hz, fs=1.0 / dt, output="sos")
    try:
        vl = sosfiltfilt(sos, v - v[0])
        yl = sosfiltfilt(sos, y - y[0], axis=0)
    except ValueError:  # shorter than the filter's padding
        return None
    vc = vl - vl.mean()
    yc = yl - yl.mean(axis=0)
    den = np.sqrt(np.sum(vc**2) * np.sum(yc**2, axis=0))
    if np.sum(vc**2) == 0:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(den > 0, (vc @ yc) / den, 0.0)
        t = r * np.sqrt((n_eff - 2) / np.maximum(1 - r**2, np.finfo(float).eps))
    return DriveSign(r, t, float(n_eff), float(band_hz),
                     bool(np.all(r < 0) and np.min(t) < -_T_SIGNIFICANT))
