"""What the reader sees in a lab file, before any fit (``bayesmodal inspect FILE``).

:func:`inspect_file` reads a record as every command would (``load_experiment`` with the
same :class:`~bayesmodal.reading.ReadOptions`) and says what it found: which column
plays which role and in which units, the time base (steps, jitter, what the reader did
with it), the input's events, which way the drive seems wired (``reading.drive_sign``),
where each cart rests before the first event and after the last, and the command line
that fits the record.  A file the reader refuses raises the reader's own one-line error.
"""

from __future__ import annotations

import shlex
import warnings
from dataclasses import asdict, dataclass, replace
from fractions import Fraction
from pathlib import Path

import numpy as np

from ._window import offset_at_rest
from .data import ECP_M_PER_COUNT, load_experiment
from .reading import ReadOptions, drive_sign
from .timebase import choose_time_base

__all__ = ["InputEvent", "Inspection", "inspect_file", "input_events"]

#: An input change is an event beyond this many robust standard deviations of the
#: sample-to-sample changes (a normal difference gets there with probability 6e-7).
EVENT_SIGMAS = 5.0

#: ... and beyond this fraction of the input's range (a converter's one-unit flicker on
#: a held input is not an event).
EVENT_MIN_FRACTION = 0.01


@dataclass(frozen=True)
class InputEvent:
    """A change of the input beyond its noise.

    Attributes
    ----------
    t_s : float
        Time of the first sample after the change, s.
    from_v, to_v : float
        Input before and after, V.
    """

    t_s: float
    from_v: float
    to_v: float


@dataclass(frozen=True)
class Inspection:
    """What the reader sees in one file.

    Attributes
    ----------
    path : str
    format : str
        ``"mat"``, ``"txt"`` or ``"csv"``.
    columns : tuple of (str, str)
        Role (``t``, ``v``, ``x1..xn``) to the file's column.
    input_v_per_unit, time_s_per_unit, output_m_per_unit : float
        Scale factors applied: V, s and m per unit of the file.
    n_samples : int
    duration_s : float
        ``t[-1] - t[0]``, s.
    step_min_s, step_median_s, step_max_s : float
        Recorded steps, s.
    grid_dt_s : float
        Step of the least-squares uniform grid, s.
    shift_min_s, shift_max_s : float
        Stamps minus that grid, s.
    time_base : str
        What the reader did: ``"uniform"``, ``"rounded"``, ``"jitter"`` (put on the
        grid), ``"grid"`` (put on the grid on request) or ``"stamps"`` (kept as recorded).
    events : tuple of InputEvent
        Input changes beyond its noise, in time order.
    drive_correlation : tuple of float, or None
        Low-frequency correlation of the input with each output (``reading.drive_sign``);
        None when the record cannot tell.
    drive_reversed : bool
        The carts move against the input: read with ``--input-scale -1``.
    rest_before_m : tuple of float
        Mean of each output before the first event, m (NaN without events).
    rest_after_m : tuple of float
        Mean of each output over the last quarter of the time after the last event, m.
    warnings : tuple of str
        The reader's warnings.
    fit_command : str
        ``bayesmodal lsq FILE`` with the reader options this file needs.
    """

    path: str
    format: str
    columns: tuple
    input_v_per_unit: float
    time_s_per_unit: float
    output_m_per_unit: float
    n_samples: int
    duration_s: float
    step_min_s: float
    step_median_s: float
    step_max_s: float
    grid_dt_s: float
    shift_min_s: float
    shift_max_s: float
    time_base: str
    events: tuple
    drive_correlation: tuple | None
    drive_reversed: bool
    rest_before_m: tuple
    rest_after_m: tuple
    warnings: tuple
    fit_command: str

    def as_dict(self) -> dict:
        """JSON-ready fields (events as dicts)."""
        return asdict(self)


def input_events(t_s, v_volt) -> tuple[InputEvent, ...]:
    """Where the input changes beyond its noise.

    A change between consecutive samples is an event when it exceeds ``EVENT_SIGMAS``
    robust standard deviations (1.4826 times the median absolute deviation) of all
    sample-to-sample changes and ``EVENT_MIN_FRACTION`` of the input's range;
    consecutive such changes (a ramp over a few samples) make one event.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Times, s.
    v_volt : ndarray, shape (N,)
        Input, V.

    Returns
    -------
    tuple of InputEvent

    Examples
    --------
    >>> t = np.arange(100) * 0.01
    >>> [(e.t_s, e.to_v) for e in input_events(t, 0.5 * ((t > 0.2) & (t < 0.6)))]
    [(0.21, 0.5), (0.6, 0.0)]
    """
    t = np.asarray(t_s, float)
    v = np.asarray(v_volt, float)
    d = np.diff(v)
    span = float(np.ptp(v))
    if span == 0:
        return ()
    sigma = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    big = np.abs(d) > max(EVENT_SIGMAS * sigma, EVENT_MIN_FRACTION * span)
    out = []
    k = 0
    while k < d.size:
        if not big[k]:
            k += 1
            continue
        j = k
        while j + 1 < d.size and big[j + 1] and np.sign(d[j + 1]) == np.sign(d[k]):
            j += 1
        out.append(InputEvent(float(t[k + 1]), float(v[k]), float(v[j + 1])))
        k = j + 1
    return tuple(out)


def _default_columns(kind: str, n_outputs: int) -> tuple:
    return (("t", "t"), ("v", "v"), *((f"x{i}", f"x{i}") for i in range(1, n_outputs + 1)))


def _number(x: float) -> str:
    """A scale as the options take it: a short fraction when it is one exactly
    (``5/4096``, ``1/1000``), else its shortest repr."""
    frac = Fraction(x).limit_denominator(1 << 20)
    if float(frac) == x and frac.denominator != 1:
        return f"{frac.numerator}/{frac.denominator}"
    return repr(float(x)) if frac.denominator != 1 else str(frac.numerator)


def _fit_command(path: Path, opts: ReadOptions, reversed_drive: bool,
                 offset: bool = False) -> str:
    args = ["bayesmodal", "lsq", str(path)]
    if opts.columns is not None:
        args += ["--columns", ",".join(f"{r}={c}" for r, c in opts.columns)]
    scale = opts.input_scale * (-1 if reversed_drive else 1)
    if scale != 1.0:
        args += ["--input-scale", _number(scale)]
    if opts.time_scale != 1.0:
        args += ["--time-scale", _number(opts.time_scale)]
    if opts.m_per_count is not None:
        args += ["--m-per-count", _number(opts.m_per_count)]
    if opts.time_base != "auto":
        args += ["--time-base", opts.time_base]
    for flag, value in (("--t-start", opts.t_start), ("--t-end", opts.t_end)):
        if value is not None:
            args += [flag, repr(float(value))]
    if opts.release is not None:
        args += ["--release", opts.release]
    rest = "initial" if offset else opts.rest_offset
    if rest != "none":
        args += ["--rest-offset", rest]
    return " ".join(shlex.quote(a) for a in args)


def inspect_file(path, options: ReadOptions | None = None) -> Inspection:
    """Read a record and say what the reader sees.

    Parameters
    ----------
    path : path-like
        A file ``load_experiment`` reads.
    options : ReadOptions, optional
        Column map and scale factors, as for ``load_experiment``.

    Returns
    -------
    Inspection

    Raises
    ------
    DataError, ConfigError
        The reader's own errors for a file it refuses.

    Examples
    --------
    >>> import tempfile, os
    >>> t = np.arange(400) * 0.005
    >>> rows = ["t,v,x1"] + [f"{a},{0.5 * (a > 0.5)},{1e-3 * (a > 0.5)}" for a in t]
    >>> p = os.path.join(tempfile.mkdtemp(), "step.csv")
    >>> with open(p, "w") as f:
    ...     _ = f.write("\\n".join(rows) + "\\n")
    >>> r = inspect_file(p)
    >>> r.n_samples, r.time_base, [e.t_s for e in r.events], r.fit_command.split()[:2]
    (400, 'uniform', [0.505], ['bayesmodal', 'lsq'])
    """
    path = Path(path)
    opts = options if options is not None else ReadOptions()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        exp = load_experiment(path, options=opts)
    said = tuple(str(w.message) for w in caught)
    # the recorded stamps, as the file holds them (ECP exports: the recovered time)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = load_experiment(path, options=replace(opts, time_base="stamps"))
    base = choose_time_base(raw.t_s, opts.time_base)
    kind = path.suffix.lstrip(".").lower()
    scale_y = opts.m_per_count if opts.m_per_count is not None else (
        ECP_M_PER_COUNT if kind in ("mat", "txt") else 1.0)
    events = input_events(exp.t_s, exp.v_volt)
    sign = drive_sign(exp.v_volt, exp.y_m, exp.mean_dt)
    y, t = exp.y_m, exp.t_s
    if events:
        before = y[t < events[0].t_s]
        after_t0 = events[-1].t_s
        tail = y[t >= after_t0 + 0.75 * (t[-1] - after_t0)]
    else:
        before, tail = y[:0], y[t >= t[0] + 0.75 * (t[-1] - t[0])]
    nan = np.full(exp.n_outputs, np.nan)
    rest_before = before.mean(axis=0) if before.size else nan
    rest_after = tail.mean(axis=0) if tail.size else nan
    reversed_drive = bool(sign is not None and sign.reversed)
    return Inspection(
        path=str(path),
        format=kind,
        columns=opts.columns if opts.columns is not None else _default_columns(
            kind, exp.n_outputs),
        input_v_per_unit=float(opts.input_scale),
        time_s_per_unit=float(opts.time_scale),
        output_m_per_unit=float(scale_y),
        n_samples=exp.n_samples,
        duration_s=float(t[-1] - t[0]),
        step_min_s=base.step_min_s,
        step_median_s=base.step_median_s,
        step_max_s=base.step_max_s,
        grid_dt_s=base.grid_dt_s,
        shift_min_s=base.shift_min_s,
        shift_max_s=base.shift_max_s,
        time_base=base.kind,
        events=events,
        drive_correlation=None if sign is None else tuple(float(r) for r in sign.correlation),
        drive_reversed=reversed_drive,
        rest_before_m=tuple(float(a) for a in rest_before),
        rest_after_m=tuple(float(a) for a in rest_after),
        warnings=said,
        # outputs resting away from 0 before the input: lsq refuses them without the fix
        fit_command=_fit_command(path, opts, reversed_drive, offset=opts.rest_offset == "none"
                                 and bool(offset_at_rest(exp.y_m, exp.v_volt))),
    )


def format_inspection(r: Inspection, max_events: int = 12) -> str:
    """The text ``bayesmodal inspect`` prints."""
    cols = ", ".join(f"{role}={src}" for role, src in r.columns)
    lines = [
        f"file: {r.path} ({r.format})",
        f"columns: {cols}",
        f"scales: input {r.input_v_per_unit:.6g} V/unit, time {r.time_s_per_unit:.6g} s/unit, "
        f"outputs {r.output_m_per_unit:.6g} m/unit",
        f"samples: {r.n_samples} over {r.duration_s:.4g} s",
        f"steps: min {1e3 * r.step_min_s:.4g} ms, median {1e3 * r.step_median_s:.4g} ms, max "
        f"{1e3 * r.step_max_s:.4g} ms; stamps {1e3 * r.shift_min_s:+.3g} to "
        f"{1e3 * r.shift_max_s:+.3g} ms from a uniform step of {1e3 * r.grid_dt_s:.6g} ms",
        f"time base: {r.time_base}",
        f"input events: {len(r.events)}",
    ]
    for e in r.events[:max_events]:
        lines.append(f"  t = {e.t_s:.4f} s: {e.from_v:+.4g} -> {e.to_v:+.4g} V")
    if len(r.events) > max_events:
        lines.append(f"  ... {len(r.events) - max_events} more")
    if r.drive_correlation is None:
        lines.append("drive polarity: the record cannot tell")
    else:
        rs = ", ".join(f"{c:+.2f}" for c in r.drive_correlation)
        lines.append(f"drive polarity: {'REVERSED' if r.drive_reversed else 'as wired'} "
                     f"(low-frequency correlation of input and outputs {rs})")
    mm = lambda a: ", ".join(f"{1e3 * x:+.4g}" for x in a)  # noqa: E731
    lines.append(f"rest before the first event: {mm(r.rest_before_m)} mm")
    lines.append(f"rest after the last event: {mm(r.rest_after_m)} mm")
    for w in r.warnings:
        lines.append(f"reader warning: {w.splitlines()[0]}")
    lines.append(f"fit it with: {r.fit_command}")
    return "\n".join(lines)
