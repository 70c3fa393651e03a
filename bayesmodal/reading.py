"""How to read a lab's record: which column is which, the units, and the time base.

Files come as the lab's software writes them: MATLAB variables named ``enc1, enc2,
target_v, time`` next to a struct of run parameters, text files with header rows,
positions in encoder counts, the input in converter units, timestamps rounded to whole
milliseconds.  :class:`ReadOptions` says how to turn such a file into an
``Experiment`` (time in s, input in V, positions in m); :func:`parse_columns` and
:func:`parse_scale` read the command-line spellings (``t=time,v=target_v,x1=enc1`` and
``5/4096``).

Time base (:mod:`bayesmodal.timebase`).  :func:`choose_time_base` keeps timestamps as
recorded or puts them on their fitted uniform grid (``ReadOptions(time_base=...)``);
its names are importable from here too.  :func:`drive_sign` guesses from a record's
static response whether its drive is wired the other way round.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ._errors import ConfigError
from .timebase import (
    MAX_GAP_STEPS,
    TIME_BASES,
    TimeBase,
    TimeRegularisation,
    choose_time_base,
    regularise_time,
)

__all__ = ["DriveSign", "MAX_GAP_STEPS", "REST_OFFSETS", "ReadOptions", "TIME_BASES", "TimeBase",
           "TimeRegularisation", "choose_time_base", "drive_sign", "parse_columns",
           "parse_scale", "regularise_time"]

#: Which rest level of each output is subtracted (``ReadOptions.rest_offset``).
REST_OFFSETS = ("none", "initial", "final")

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
