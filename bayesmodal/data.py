"""Measured experiments: one type, several file formats, strict validation.

Formats
-------
- ECP course files, MATLAB v5 ``.mat`` with column vectors ``t, x1..xn, v``;
- ECP course files, tab/space separated ``.txt`` with columns ``t x1 .. xn v``, no header;
- plain ``.csv`` with header ``t,v,x1,...,xn`` in SI units (s, V, m).

ECP files hold positions in encoder counts; they are converted to metres with
``m_per_count`` (default ``0.0706 / 16000`` m per count, errata 7).
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._errors import DataError

__all__ = [
    "Experiment",
    "load_experiment",
    "ECP_M_PER_COUNT",
    "MAX_FILE_BYTES",
    "data_root",
    "find_data",
    "in_data_root",
    "file_sha256",
    "save_csv",
    "check_identifiable",
]

#: Metres per encoder count of the ECP 210 rig (0.0706 m per 16000 counts).
ECP_M_PER_COUNT = 0.0706 / 16000

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
        Sample times, s; uniform and strictly increasing.
    v_volt : ndarray, shape (N,)
        Motor command voltage, V.
    y_m : ndarray, shape (N, n_carts)
        Cart positions, m.
    name : str
        Short name (e.g. the file stem).
    source : str
        Where the data came from (path or description).

    Raises
    ------
    DataError
        On NaN/inf, unequal lengths, fewer than 3 samples, non-increasing or non-uniform
        time.

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
                f"(t[{k}] = {t[k]!r}, t[{k + 1}] = {t[k + 1]!r}; duplicated or decreasing)"
            )
        dt = (t[-1] - t[0]) / (t.size - 1)
        dev = np.abs(dts - dt)
        if np.max(dev) > _DT_RTOL * dt + 1e-12:
            k = int(np.argmax(dev))
            raise DataError(
                f"{where}: time steps are not equally spaced (mean dt {dt:.6g} s, "
                f"step {k} is {dts[k]:.6g} s); resample to a uniform grid first"
            )
        for a in (t, v, y):
            a.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "v_volt", v)
        object.__setattr__(self, "y_m", y)

    @property
    def dt(self) -> float:
        """Sample interval, s."""
        return float((self.t_s[-1] - self.t_s[0]) / (self.t_s.size - 1))

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


def _ecp_columns(path: Path, cols: dict[str, np.ndarray], m_per_count: float, name: str):
    xs = sorted((k for k in cols if k[:1] == "x" and k[1:].isdigit()), key=lambda k: int(k[1:]))
    missing = [k for k in ("t", "v") if k not in cols]
    if not xs:
        missing.append("x1")
    if missing:
        raise DataError(
            f"{path}: missing column(s) {missing}; an ECP file needs t, x1..xn, v "
            f"(found {sorted(cols)})"
        )
    expected = [f"x{i + 1}" for i in range(len(xs))]
    if xs != expected:
        raise DataError(f"{path}: output columns must be x1..xn without gaps, found {xs}")
    lengths = {k: np.asarray(cols[k]).size for k in ["t", "v", *xs]}
    if len(set(lengths.values())) != 1:
        raise DataError(f"{path}: unequal column lengths {lengths}")
    y = np.column_stack([np.asarray(cols[k], dtype=float).ravel() for k in xs]) * m_per_count
    return Experiment(
        np.asarray(cols["t"], dtype=float).ravel(),
        np.asarray(cols["v"], dtype=float).ravel(),
        y,
        name=name,
        source=str(path),
    )


def _load_mat(path: Path, m_per_count: float, name: str) -> Experiment:
    import scipy.io

    with open(path, "rb") as fh:
        head = fh.read(128)
    if len(head) < 128:
        raise DataError(f"{path}: truncated .mat file ({len(head)} bytes of header)")
    if head[:6] == b"\x89HDF\r\n" or b"MATLAB 7.3" in head[:116]:
        return _load_mat73(path, m_per_count, name)
    try:
        raw = scipy.io.loadmat(path, squeeze_me=False)
    except Exception as exc:  # scipy raises several types for corrupt files
        raise DataError(f"{path}: not a readable MATLAB v5 file (truncated or corrupt: "
                        f"{exc})") from exc
    cols = {k: v for k, v in raw.items() if not k.startswith("__")}
    _check_variables(path, {k: _kind(v) for k, v in cols.items()})
    return _ecp_columns(path, cols, m_per_count, name)


def _kind(v) -> str:
    """``"numeric"`` for a real numeric array, else a short description of the variable."""
    if isinstance(v, np.ndarray) and v.dtype.kind in "fiu":
        return "numeric"
    if isinstance(v, np.ndarray) and v.dtype.names:
        return "struct"
    if isinstance(v, np.ndarray) and v.dtype.kind == "O":
        return "cell"
    if isinstance(v, np.ndarray) and v.dtype.kind in "US":
        return "text"
    if isinstance(v, np.ndarray) and v.dtype.kind == "c":
        return "complex"
    return type(v).__name__


def _check_variables(path: Path, kinds: dict[str, str]) -> None:
    """Refuse a MATLAB file whose variables are not exactly numeric t, x1..xn, v."""

    def expected(k: str) -> bool:
        return k in ("t", "v") or (k[:1] == "x" and k[1:].isdigit())

    found = ", ".join(f"{k} ({kind})" for k, kind in kinds.items()) or "no variables"
    wrong = [k for k, kind in kinds.items() if expected(k) and kind != "numeric"]
    if wrong:
        raise DataError(f"{path}: variable(s) {wrong} must be real numeric vectors; found "
                        f"{found}")
    has_x = any(k[:1] == "x" for k in kinds if expected(k))
    missing = [k for k in ("t", "v") if k not in kinds] + ([] if has_x else ["x1"])
    if missing:
        raise DataError(f"{path}: missing column(s) {missing}; an ECP .mat file holds "
                        f"t, x1..xn, v (found {found})")
    unexpected = [k for k in kinds if not expected(k)]
    if unexpected:
        raise DataError(f"{path}: unexpected variable(s) {unexpected}; an ECP .mat file "
                        "holds only t, x1..xn, v (save the record without the others)")


def _load_mat73(path: Path, m_per_count: float, name: str) -> Experiment:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            kinds, cols = {}, {}
            for k in f.keys():
                if k.startswith("#"):  # MATLAB's #refs# and #subsystem# bookkeeping
                    continue
                obj = f[k]
                if isinstance(obj, h5py.Dataset):
                    cls = obj.attrs.get("MATLAB_class", b"double")
                    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                    numeric = obj.dtype.kind in "fiu" and cls not in ("char", "logical")
                    kinds[k] = "numeric" if numeric else cls
                    if numeric:
                        cols[k] = np.array(obj)
                else:
                    kinds[k] = "struct"
    except OSError as exc:
        raise DataError(f"{path}: not a readable MATLAB v7.3 (HDF5) file (truncated or "
                        f"corrupt: {exc})") from exc
    _check_variables(path, kinds)
    return _ecp_columns(path, cols, m_per_count, name)


def _read_text_table(path: Path, delimiter: str | None, skip_header: bool) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text file (binary content: {exc.reason})") from exc
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if skip_header:
        lines = lines[1:]
    if not lines:
        raise DataError(f"{path}: no data rows")
    rows = []
    width = None
    for i, ln in enumerate(lines, start=2 if skip_header else 1):
        parts = ln.split(delimiter) if delimiter else ln.split()
        if width is None:
            width = len(parts)
        elif len(parts) != width:
            raise DataError(
                f"{path}: line {i} has {len(parts)} columns, expected {width} "
                "(truncated or ragged file)"
            )
        try:
            rows.append([float(p) for p in parts])
        except ValueError as exc:
            raise DataError(f"{path}: line {i}: non-numeric value ({exc})") from exc
    return np.array(rows, dtype=float)


def _load_txt(path: Path, m_per_count: float, name: str) -> Experiment:
    arr = _read_text_table(path, None, skip_header=False)
    if arr.shape[1] < 3:
        raise DataError(
            f"{path}: {arr.shape[1]} column(s); an ECP .txt file needs t x1 .. xn v"
        )
    n = arr.shape[1] - 2
    cols = {"t": arr[:, 0], "v": arr[:, -1]}
    cols.update({f"x{i + 1}": arr[:, 1 + i] for i in range(n)})
    return _ecp_columns(path, cols, m_per_count, name)


def _load_csv(path: Path, name: str) -> Experiment:
    try:
        with open(path, encoding="utf-8") as fh:
            header = fh.readline()
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text file (binary content)") from exc
    names = [h.strip() for h in header.strip().split(",")]
    xs = [h for h in names if h.startswith("x") and h[1:].isdigit()]
    missing = [c for c in ("t", "v") if c not in names]
    if not xs:
        missing.append("x1")
    if missing:
        raise DataError(
            f"{path}: missing column(s) {missing} in header {names}; "
            "a CSV needs the header t,v,x1,...,xn (SI units: s, V, m)"
        )
    extra = [h for h in names if h not in ("t", "v") and h not in xs]
    if extra:
        raise DataError(f"{path}: unknown column(s) {extra}; expected t,v,x1,...,xn")
    if len(set(names)) != len(names):
        raise DataError(f"{path}: duplicated column names in header {names}")
    expected = [f"x{i + 1}" for i in range(len(xs))]
    if sorted(xs, key=lambda k: int(k[1:])) != expected:
        raise DataError(f"{path}: output columns must be x1..xn without gaps, found {xs}")
    arr = _read_text_table(path, ",", skip_header=True)
    if arr.shape[1] != len(names):
        raise DataError(f"{path}: rows have {arr.shape[1]} columns, header has {len(names)}")
    col = {h: arr[:, i] for i, h in enumerate(names)}
    y = np.column_stack([col[f"x{i + 1}"] for i in range(len(xs))])
    return Experiment(col["t"], col["v"], y, name=name, source=str(path))


_FORMATS = ("mat", "txt", "csv")


def load_experiment(
    path: str | os.PathLike,
    *,
    fmt: str | None = None,
    m_per_count: float = ECP_M_PER_COUNT,
    max_bytes: int | None = None,
) -> Experiment:
    """Load one experiment from a file.

    Parameters
    ----------
    path : path-like
        ``.mat`` (ECP, counts), ``.txt`` (ECP, counts) or ``.csv`` (header
        ``t,v,x1..xn``, SI units).
    fmt : {"mat", "txt", "csv"}, optional
        Format; by default taken from the file extension.
    m_per_count : float, optional
        Metres per encoder count for ECP files, m.
    max_bytes : int, optional
        Size limit, bytes (default ``MAX_FILE_BYTES`` or ``$BAYESMODAL_MAX_BYTES``).

    Returns
    -------
    Experiment
        With ``sha256`` of the file recorded.

    Raises
    ------
    DataError
        For a missing, empty, oversized, truncated or malformed file, missing columns,
        non-finite values, or non-uniform time.

    Examples
    --------
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> e = load_experiment(p) if p else None
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such file")
    if not path.is_file():
        raise DataError(f"{path}: not a regular file")
    if not (np.isfinite(m_per_count) and m_per_count > 0):
        raise DataError(f"m_per_count must be finite and > 0 m, got {m_per_count!r}")
    kind = (fmt or path.suffix.lstrip(".")).lower()
    if kind not in _FORMATS:
        raise DataError(
            f"{path}: unknown format {kind!r}; expected one of {_FORMATS} "
            "(ECP .mat/.txt in counts, or CSV with header t,v,x1..xn in SI units)"
        )
    _check_size(path, max_bytes)
    name = path.stem
    if kind == "mat":
        exp = _load_mat(path, m_per_count, name)
    elif kind == "txt":
        exp = _load_txt(path, m_per_count, name)
    else:
        exp = _load_csv(path, name)
    peak = float(np.max(np.abs(exp.y_m)))
    if peak > _MAX_PLAUSIBLE_M:
        hint = ("are the outputs in mm or encoder counts instead of metres? (mm: divide "
                f"by 1000; counts: multiply by {ECP_M_PER_COUNT:.6g} m per count)"
                if kind == "csv" else f"is m_per_count = {m_per_count:.6g} m per count right?")
        warnings.warn(
            f"{path}: displacements up to {peak:.3g} m are implausible for the rig (the "
            f"carts move a few cm at most); {hint}",
            stacklevel=2,
        )
    return Experiment(exp.t_s, exp.v_volt, exp.y_m, name=exp.name, source=exp.source,
                      sha256=file_sha256(path))


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
