"""Measured experiments: one type, several file formats, strict validation.

Formats
-------
- ECP course files, MATLAB v5 or v7.3 ``.mat`` with column vectors ``t, x1..xn, v``;
- ECP course files, tab/space separated ``.txt`` with columns ``t x1 .. xn v``;
- plain ``.csv`` with header ``t,v,x1,...,xn`` in SI units (s, V, m).

ECP files hold positions in encoder counts; they are converted to metres with
``m_per_count`` (default ``0.0706 / 16000`` m per count, errata 7).

Files laid out otherwise (other variable names, struct fields, header rows, the input in
converter units, time in ms) are read with a :class:`~bayesmodal.reading.ReadOptions`
(column map and scale factors).  Rounded timestamps are put on their uniform grid with a
warning; jittered ones are kept as recorded (an ``Experiment`` with ``recorded_stamps``),
which the linear model simulates step by step and every analysis that needs a uniform
grid refuses with the fix (``time_base="grid"``); the misreads that would otherwise
pass silently (a sample index as time, converter units as volts, mm or counts as
metres) are refused with the fix.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import _columns, _instruments, _window
from ._errors import DataError
from .model.system import ECP_M_PER_COUNT
from .reading import ReadOptions, drive_sign
from .timebase import choose_time_base

__all__ = [
    "Experiment",
    "ReadOptions",
    "load_experiment",
    "ECP_M_PER_COUNT",
    "MAX_FILE_BYTES",
    "data_root",
    "find_data",
    "in_data_root",
    "file_sha256",
    "save_csv",
    "check_identifiable",
    "options_for_rig",
]


#: Largest file the loaders read, bytes.  Raise with ``max_bytes=`` or BAYESMODAL_MAX_BYTES.
MAX_FILE_BYTES = 200 * 1024 * 1024

#: Relative tolerance on the sample interval for "uniform sampling".
_DT_RTOL = 1e-6

#: Largest plausible displacement of a cart on the rig, m (the rail allows a few cm).
_MAX_PLAUSIBLE_M = 0.5


@dataclass(frozen=True, eq=False)
class Experiment:
    """One measured (or simulated) experiment on the rig.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Sample times, s; strictly increasing, and uniform unless ``recorded_stamps``.
    v_volt : ndarray, shape (N,)
        Motor command voltage, V; for a rig with a force input (``Rig.input ==
        "force"``) the measured force, N.
    y_m : ndarray, shape (N, n_outputs)
        Each sensor's reading in SI units of its kind along +x: positions m (the cart
        positions of the default rig), velocities m/s, accelerations m/s^2.
    name : str
        Short name (e.g. the file stem).
    source : str
        Where the data came from (path or description).
    sha256 : str
        SHA-256 of the file read, or empty.
    recorded_stamps : bool
        ``t_s`` are a logger's stamps whose steps may differ: the input is held between
        them and the linear model is simulated on them step by step (``sim_dt``);
        :attr:`dt` then refuses a non-uniform record, so that an analysis that needs a
        uniform grid says so instead of using a wrong step.

    Raises
    ------
    DataError
        On NaN/inf, unequal lengths, fewer than 3 samples, non-increasing time, or
        non-uniform time without ``recorded_stamps``.

    Examples
    --------
    >>> t = np.arange(5) * 0.01
    >>> e = Experiment(t, np.zeros(5), np.zeros((5, 3)), name="zeros")
    >>> e.dt, e.n_outputs
    (0.01, 3)
    """

    t_s: np.ndarray
    v_volt: np.ndarray
    y_m: np.ndarray
    name: str = "experiment"
    source: str = ""
    sha256: str = field(default="", repr=False)
    recorded_stamps: bool = False

    def __post_init__(self) -> None:
        where = f"{self.name}" + (f" ({self.source})" if self.source else "")
        t = np.array(self.t_s, dtype=float)
        v = np.array(self.v_volt, dtype=float)
        y = np.array(self.y_m, dtype=float)
        if y.ndim == 1:
            y = y[:, None]
        if t.ndim != 1 or v.ndim != 1 or y.ndim != 2:
            raise DataError(
                f"{where}: t and v must be 1-D and y 2-D (samples x carts); got shapes "
                f"t {t.shape}, v {v.shape}, y {y.shape}"
            )
        if not (t.size == v.size == y.shape[0]):
            raise DataError(
                f"{where}: unequal lengths: t has {t.size}, v has {v.size}, "
                f"y has {y.shape[0]} samples"
            )
        if y.shape[1] < 1:
            raise DataError(f"{where}: no output columns")
        if t.size < 3:
            raise DataError(f"{where}: only {t.size} samples; need at least 3")
        for label, arr in (("t", t), ("v", v), ("y", y)):
            bad = ~np.isfinite(arr)
            if np.any(bad):
                idx = np.argwhere(bad)[0]
                raise DataError(
                    f"{where}: {label} has {int(bad.sum())} non-finite value(s) (NaN or inf), "
                    f"first at index {tuple(int(i) for i in idx)}"
                )
        dts = np.diff(t)
        if np.any(dts <= 0):
            k = int(np.argmax(dts <= 0))
            raise DataError(
                f"{where}: time is not strictly increasing at sample {k + 1} "
                f"(t[{k}] = {t[k]!r}, t[{k + 1}] = {t[k + 1]!r}; duplicated or decreasing); "
                "sort the rows by time and drop repeated samples"
            )
        dt = (t[-1] - t[0]) / (t.size - 1)
        dev = np.abs(dts - dt)
        uniform = bool(np.max(dev) <= _DT_RTOL * dt + 1e-12)
        if not uniform and not self.recorded_stamps:
            k = int(np.argmax(dev))
            raise DataError(
                f"{where}: time steps are not equally spaced (mean dt {dt:.6g} s, "
                f"step {k} is {dts[k]:.6g} s); keep the stamps with --time-base stamps "
                "(the linear fit simulates on them) or put them on a uniform grid with "
                "--time-base grid (ReadOptions(time_base=...))"
            )
        object.__setattr__(self, "recorded_stamps", bool(self.recorded_stamps))
        object.__setattr__(self, "_uniform", uniform)
        for a in (t, v, y):
            a.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "v_volt", v)
        object.__setattr__(self, "y_m", y)

    @property
    def is_uniform(self) -> bool:
        """The samples lie on a uniform grid (steps equal to a relative 1e-6)."""
        return self._uniform

    @property
    def mean_dt(self) -> float:
        """Mean sample interval ``(t[-1] - t[0]) / (N - 1)``, s (the step of a uniform
        record; for recorded stamps only a summary)."""
        return float((self.t_s[-1] - self.t_s[0]) / (self.t_s.size - 1))

    @property
    def dt(self) -> float:
        """Sample interval, s.

        Raises
        ------
        DataError
            For recorded stamps whose steps differ: the analysis asking needs a uniform
            grid; the message names the fix.
        """
        if not self._uniform:
            steps = np.diff(self.t_s)
            where = self.source or self.name
            raise DataError(
                f"{where}: time steps are not equally spaced (recorded stamps, steps "
                f"{steps.min():.4g} to {steps.max():.4g} s) and this analysis needs a "
                "uniform grid; read the record with --time-base grid "
                "(time_base = \"grid\" in a run configuration's [data], "
                "ReadOptions(time_base=\"grid\")), or fit the linear model with "
                "`bayesmodal lsq`, which simulates on the stamps")
        return self.mean_dt

    @property
    def sim_dt(self) -> float | np.ndarray:
        """The sample interval as the linear simulator takes it: ``dt`` (float, s) for a
        uniform record, else the recorded steps ``t[k+1] - t[k]``, shape (N - 1,), s."""
        return self.mean_dt if self._uniform else np.diff(self.t_s)

    @property
    def n_samples(self) -> int:
        return int(self.t_s.size)

    @property
    def n_outputs(self) -> int:
        return int(self.y_m.shape[1])

    def slice(self, start: int = 0, stop: int | None = None) -> Experiment:
        """Sub-record of samples ``start:stop`` with time kept as recorded."""
        return Experiment(
            self.t_s[start:stop],
            self.v_volt[start:stop],
            self.y_m[start:stop],
            name=f"{self.name}[{start}:{stop}]",
            source=self.source,
            sha256=self.sha256,
            recorded_stamps=self.recorded_stamps,
        )


# ---------------------------------------------------------------------- helpers
def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 hex digest of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def data_root() -> Path | None:
    """Folder of the shared measured data, or None if absent.

    Looks at ``$BAYESMODAL_DATA`` first, then ``../shared/data`` beside the repository root
    (the checkout that holds this package).  ``$BAYESMODAL_DATA`` may name the parent of
    the data set folders (``.../data``) or one data set folder itself
    (``.../data/ecp210-3dof``); :func:`find_data` accepts both.
    """
    env = os.environ.get("BAYESMODAL_DATA")
    if env:
        p = Path(env).expanduser()
        return p if p.is_dir() else None
    repo = Path(__file__).resolve().parents[1]
    p = repo.parent / "shared" / "data"
    return p if p.is_dir() else None


def in_data_root(name: str | os.PathLike, root: Path | None = None) -> list[Path]:
    """Where ``name`` (relative, e.g. ``"ecp210-3dof/data_steps.mat"``) may be in a root.

    ``root / name``, and, for a root that is the data set folder itself (``$BAYESMODAL_DATA
    = .../ecp210-3dof``), ``root / name`` without its first folder.  Default root:
    :func:`data_root`; no root gives an empty list.
    """
    root = data_root() if root is None else Path(root)
    rel = Path(name)
    if root is None or rel.is_absolute():
        return []
    out = [root / rel]
    if len(rel.parts) > 1 and rel.parts[0] == root.name:
        out.append(root.joinpath(*rel.parts[1:]))
    return out


def find_data(name: str) -> Path | None:
    """Path of a measured file such as ``"ecp210-3dof/data_impulses.mat"``, or None."""
    return next((p for p in in_data_root(name) if p.is_file()), None)


def _check_size(path: Path, max_bytes: int | None) -> None:
    limit = max_bytes
    if limit is None:
        limit = int(os.environ.get("BAYESMODAL_MAX_BYTES", MAX_FILE_BYTES))
    size = path.stat().st_size
    if size == 0:
        raise DataError(f"{path}: file is empty")
    if size > limit:
        raise DataError(
            f"{path}: file is {size} bytes, over the size limit of {limit} bytes; "
            "raise it with max_bytes= or the BAYESMODAL_MAX_BYTES environment variable"
        )



def _vector(path: Path, role: str, a) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim > 1 and sum(s > 1 for s in a.shape) > 1:
        raise DataError(f"{path}: column {role} has shape {a.shape}; it must be a vector")
    return np.asarray(a, dtype=float).ravel()


_FORMATS = ("mat", "txt", "csv", *_instruments.FORMATS)

#: Largest plausible motor command, V (the ECP amplifier takes +-10 V).
_MAX_PLAUSIBLE_V = 30.0

#: Longest plausible sample interval, s (the rig's modes lie at 1-5 Hz).
_MAX_PLAUSIBLE_DT = 0.5


def _assemble(path: Path, roles: dict, opts: ReadOptions, kind: str, name: str) -> Experiment:
    xs = [k for k in roles if k[0] == "x"]
    cols = {k: _vector(path, k, roles[k]) for k in ("t", "v", *xs)}
    lengths = {k: c.size for k, c in cols.items()}
    if len(set(lengths.values())) != 1:
        raise DataError(f"{path}: unequal column lengths {lengths}")
    if opts.n_outputs is not None and len(xs) != opts.n_outputs:
        raise DataError(f"{path}: {len(xs)} outputs, but {opts.n_outputs} were expected")
    scale_y = opts.m_per_count if opts.m_per_count is not None else (
        ECP_M_PER_COUNT if kind in ("mat", "txt") else 1.0)
    for what, given in (("output_kinds", opts.output_kinds),
                        ("output_scales", opts.output_scales)):
        if given is not None and len(given) != len(xs):
            raise DataError(f"{path}: {len(xs)} output columns but {what} lists "
                            f"{len(given)}; give one per column, in the rig's sensor order")
    if opts.output_scales is not None:
        scale_y = np.asarray(opts.output_scales)
    raw_y = np.column_stack([cols[k] for k in xs])
    t = cols["t"] * opts.time_scale
    v = cols["v"] * opts.input_scale
    y = raw_y * scale_y
    # rounded stamps go on their uniform grid, jittered ones are kept (timebase.py);
    # anything else is left for Experiment to refuse
    stamps = False
    if t.size >= 3 and np.all(np.isfinite(t)) and np.all(np.diff(t) > 0):
        try:
            base = choose_time_base(t, opts.time_base)
        except DataError as exc:
            raise DataError(f"{path}: {exc}") from None
        if base.message:
            warnings.warn(f"{path}: {base.message}", stacklevel=4)
        t, stamps = base.t_s, base.recorded_stamps
    exp = Experiment(t, v, y, name=name, source=str(path), recorded_stamps=stamps)
    pos = (slice(None) if opts.output_kinds is None else
           [i for i, k in enumerate(opts.output_kinds) if k == "position"])
    _check_plausible(path, exp, raw_y, opts, kind, pos)
    # the static response says which way the drive is wired (a guess: a warning; the
    # 0.5 Hz band does not see a millisecond's jitter); velocities and accelerations
    # have none
    sign = (drive_sign(exp.v_volt, exp.y_m[:, pos], exp.mean_dt)
            if opts.output_kinds is None or pos else None)
    if sign is not None and sign.reversed:
        warnings.warn(f"{path}: {sign.message()}", stacklevel=4)
    return exp


def _check_plausible(path: Path, exp: Experiment, raw_y: np.ndarray, opts: ReadOptions,
                     kind: str, pos=slice(None)) -> None:
    """Refuse the silent misreads: sample index as time, converter units, mm or counts
    (the displacement checks on the position columns ``pos``)."""
    t = exp.t_s
    t_role = (opts.column_map or {}).get("t", "t")
    if (opts.time_scale == 1.0 and np.all(t == np.round(t))
            and abs(exp.mean_dt - 1.0) < 1e-12):
        raise DataError(
            f"{path}: the time column {t_role!r} counts samples ({t[0]:g}, {t[1]:g}, "
            f"{t[2]:g}, ...), it is not a time in seconds; map the time column with "
            "--columns t=NAME (a text file's columns by number, e.g. t=2), or give "
            "--time-scale 1/1000 if it is in milliseconds")
    if exp.mean_dt > _MAX_PLAUSIBLE_DT:
        raise DataError(
            f"{path}: sample interval {exp.mean_dt:.4g} s is implausible for the rig (its modes "
            f"at 1-5 Hz need well under {_MAX_PLAUSIBLE_DT} s); if the time column is in "
            "milliseconds give --time-scale 1/1000 (ReadOptions(time_scale=1e-3))")
    vmax = float(np.max(np.abs(exp.v_volt)))
    if vmax > _MAX_PLAUSIBLE_V and opts.input_kind == "voltage":
        raise DataError(
            f"{path}: input up to {vmax:.4g} V is far beyond the rig's +-10 V command; if it "
            "is in converter units give volts per unit, e.g. --input-scale 5/4096 for 12 "
            "bits over 5 V (ReadOptions(input_scale=...))")
    if isinstance(pos, list) and not pos:
        return  # no position column: nothing to bound
    peak = float(np.max(np.abs(exp.y_m[:, pos])))
    raw_y = raw_y[:, pos]
    if peak > _MAX_PLAUSIBLE_M:
        if kind == "csv" and opts.m_per_count is None:
            unit = ("in mm? give --m-per-count 0.001" if peak < 1000 else
                    f"in encoder counts? give --m-per-count {ECP_M_PER_COUNT:.6g}")
            hint = f"are the outputs {unit} (metres per unit of the file)"
        else:
            hint = (f"is {peak / float(np.max(np.abs(raw_y))):.6g} m per count right? set "
                    "it with --m-per-count")
        raise DataError(f"{path}: displacements up to {peak:.3g} m are implausible for the "
                        f"rig (the carts move a few cm at most); {hint}")
    raw_peak = float(np.max(np.abs(raw_y)))
    scale = peak / raw_peak if raw_peak > 0 else 0.0
    # a scale of encoder counts (at most 0.1 mm per unit) with values below one count
    if 0 < scale <= 1e-4 and raw_peak < 1:
        raise DataError(
            f"{path}: outputs up to {raw_peak:.3g} are below one encoder count; if they are "
            "already in metres give --m-per-count 1 (ReadOptions(m_per_count=1))")


def load_experiment(
    path: str | os.PathLike,
    *,
    fmt: str | None = None,
    m_per_count: float | None = None,
    max_bytes: int | None = None,
    options: ReadOptions | None = None,
) -> Experiment:
    """Load one experiment from a file.

    Parameters
    ----------
    path : path-like
        ``.mat`` (MATLAB v5 or v7.3), ``.txt`` (columns separated by white space, optional
        header rows) or ``.csv`` (header row).  Without a column map: ECP ``.mat``/``.txt``
        with ``t, x1..xn, v`` in encoder counts, CSV with header ``t,v,x1..xn`` in SI units.
        ``.uff``/``.unv`` (dataset 58 time records, ``pyuff``) and ``.tdms`` (``npTDMS``):
        named channels with units (``bayesmodal._instruments``).
    fmt : {"mat", "txt", "csv", "uff", "unv", "tdms"}, optional
        Format; by default taken from the file extension.
    m_per_count : float, optional
        Metres per encoder count for the ECP ``.mat``/``.txt`` files, m (default
        ``ECP_M_PER_COUNT``); same as ``options.m_per_count`` but without effect on CSV.
    max_bytes : int, optional
        Size limit, bytes (default ``MAX_FILE_BYTES`` or ``$BAYESMODAL_MAX_BYTES``).
    options : ReadOptions, optional
        Column map and scale factors for files laid out otherwise.

    Returns
    -------
    Experiment
        With ``sha256`` of the file recorded.  Timestamps rounded to a coarser clock are
        replaced by the fitted uniform grid with a warning that says by how much they
        moved; jittered ones are kept as recorded (``recorded_stamps``) with a warning
        that gives the steps' range (``timebase.choose_time_base``; ``options.time_base``
        chooses otherwise).  A record
        whose carts move against the input at low frequency is read as it is, with a
        warning that the drive may be reversed and the fix, ``input_scale=-1``
        (``reading.drive_sign``).

    Raises
    ------
    DataError
        For a missing, empty, oversized, truncated or malformed file, missing columns,
        non-finite values, irregular time, a gap of missing samples, and for the misreads:
        a time column that counts samples, an input far beyond a few volts,
        displacements in mm or counts.

    Examples
    --------
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> e = load_experiment(p) if p else None
    >>> opts = ReadOptions(columns={"t": "time", "v": "target_v", "x1": "enc1",
    ...                             "x2": "enc2"}, input_scale=5 / 4096)
    """
    path = Path(path)
    opts = options if options is not None else ReadOptions()
    if not path.exists():
        raise DataError(f"{path}: no such file")
    if not path.is_file():
        raise DataError(f"{path}: not a regular file")
    kind = (fmt or path.suffix.lstrip(".")).lower()
    if m_per_count is not None:
        if not (np.isfinite(m_per_count) and m_per_count != 0):
            raise DataError(f"m_per_count must be finite and non-zero m (negative for "
                            f"encoders counting the other way), got {m_per_count!r}")
        if kind in ("mat", "txt") and opts.m_per_count is None:
            opts = replace(opts, m_per_count=float(m_per_count))
    if kind not in _FORMATS:
        raise DataError(
            f"{path}: unknown format {kind!r}; expected one of {_FORMATS} "
            "(ECP .mat/.txt in counts, CSV with header t,v,x1..xn in SI units, UFF "
            "dataset 58 or TDMS channels with units)"
        )
    _check_size(path, max_bytes)
    if kind == "mat":
        roles = _columns.mat_roles(path, opts)
    elif kind == "txt":
        roles = _columns.txt_roles(path, opts)
    elif kind in _instruments.FORMATS:  # instrument files: named channels with units
        roles, opts = _instruments.read_roles(path, kind, opts)
    else:
        roles = _columns.csv_roles(path, opts)
    exp = _assemble(path, roles, opts, kind, path.stem)
    t, v, y = _window.select(str(path), exp.t_s, exp.v_volt, exp.y_m, opts)  # all by default
    return Experiment(t, v, y, name=exp.name, source=exp.source,
                      sha256=file_sha256(path), recorded_stamps=exp.recorded_stamps)


def options_for_rig(options: ReadOptions, rig, path: str | os.PathLike) -> ReadOptions:
    """Reader options that read a file's output columns as the rig's sensors.

    A force input (``Rig.input``) sets ``input_kind``.  A rig whose sensors are all
    positions along +x leaves the outputs as they are (the encoder scale is
    ``m_per_count``).  Otherwise the columns get their kinds
    (``output_kinds``) and, for the ECP ``.mat``/``.txt`` files (raw units), each
    sensor's signed scale (``Sensor.si_per_unit``, unless ``m_per_count`` is given); a
    ``.csv`` holds SI units of each kind along +x already.

    Parameters
    ----------
    options : ReadOptions
    rig : Rig
    path : str or path
        The file to read (its suffix says whether it holds raw units).

    Returns
    -------
    ReadOptions

    Examples
    --------
    >>> from bayesmodal.model.system import Cart, Drive, Rig, Sensor, Spring
    >>> rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", 500.0),),
    ...           drive=(Drive("1"),), sensors=(Sensor("1", "count", 1e-5), Sensor("1", "g")))
    >>> o = options_for_rig(ReadOptions(), rig, "hammer.txt")
    >>> o.output_kinds, o.output_scales
    (('position', 'acceleration'), (1e-05, 9.80665))
    """
    sensors = rig.sensors
    changes = {} if rig.input == "voltage" else {"input_kind": rig.input}
    if all(s.kind == "position" and s.sign > 0 for s in sensors):
        return replace(options, **changes) if changes else options
    changes["output_kinds"] = tuple(s.kind for s in sensors)
    raw = Path(path).suffix.lower() in (".mat", ".txt")
    if raw and options.m_per_count is None and options.output_scales is None:
        changes["output_scales"] = tuple(s.si_per_unit for s in sensors)
    return replace(options, **changes)


def check_identifiable(experiment: Experiment) -> None:
    """Refuse a record that holds nothing to identify.

    Parameters
    ----------
    experiment : Experiment

    Raises
    ------
    DataError
        When the input voltage is all zeros (nothing excites the rig) or no output ever
        moves (every output is constant), naming the file.

    Examples
    --------
    >>> t = np.arange(5) * 0.01
    >>> check_identifiable(Experiment(t, np.ones(5), t[:, None], name="ok"))
    """
    where = experiment.source or experiment.name
    if not np.any(experiment.v_volt != 0):
        raise DataError(f"{where}: the input is all zeros; nothing is identifiable "
                        "(no excitation)")
    if np.all(np.ptp(experiment.y_m, axis=0) == 0):
        raise DataError(f"{where}: every output is constant (no cart ever moves); nothing "
                        "is identifiable")


def save_csv(experiment: Experiment, path: str | os.PathLike) -> None:
    """Write an experiment as CSV with header ``t,v,x1..xn`` (SI units), atomically."""
    path = Path(path)
    n = experiment.n_outputs
    header = ",".join(["t", "v"] + [f"x{i + 1}" for i in range(n)])
    arr = np.column_stack([experiment.t_s, experiment.v_volt, experiment.y_m])
    tmp = path.with_name(path.name + ".tmp")
    np.savetxt(tmp, arr, delimiter=",", header=header, comments="", fmt="%.17g")
    os.replace(tmp, path)
