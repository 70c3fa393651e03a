"""A run folder: atomic writes, a lock against two writers, and a status file.

Every file a run writes goes through a temporary file in the same folder, flushed and
``fsync``-ed, then ``os.replace``-d onto its name; a reader (or a run killed half-way)
therefore only ever sees a complete old version or a complete new one.  Temporary names
end in ``.tmp`` (before the suffix for images: ``bode.tmp.png``) and are removed when the
folder is next opened.

``run.lock`` is created with ``O_CREAT | O_EXCL`` and holds the writer's host and process
id; a second writer is refused while that process lives.  A lock left by a process that no
longer exists (a run killed with SIGKILL) is stale and is taken over.

``status.json`` says ``running``, ``finished`` or ``failed``, with the configuration hash,
the times and, for a failure, the error.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import socket
from pathlib import Path

from .._errors import ConfigError
from .._json import to_jsonable
from ..plots._png import save_png

__all__ = [
    "RunFolder",
    "RunLockedError",
    "RunExistsError",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_json",
    "atomic_savefig",
    "STATES",
]

#: Values of ``status.json``'s ``state``.
STATES = ("running", "finished", "failed")

#: Files a run writes (besides its plots, ``*.png``); ``--force`` removes only these.
RUN_FILES = ("chain.h5", "posterior.nc", "summary.json", "timing.json", "status.json",
             "report.html", "run.log", "lsq_vs_posterior.md", "config.toml", "config.json",
             "temperature.json")


class RunLockedError(ConfigError):
    """Another live process is writing the run folder."""


class RunExistsError(ConfigError):
    """The folder already holds a run that would be overwritten."""


def now_iso() -> str:
    """Current UTC time, ISO 8601 with seconds."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def write_failed(exc: OSError, path: Path, tmp: Path | None = None) -> OSError:
    """The error to raise when writing ``path`` failed (full disk, no permission): names
    the file, says the previous version is kept, and removes the partial temporary."""
    if tmp is not None:
        with contextlib.suppress(OSError):
            tmp.unlink()
    msg = f"cannot write {path}: {exc.strerror or exc} (the previous version, if any, is kept)"
    return OSError(exc.errno, msg) if exc.errno is not None else OSError(msg)


def _fsync_replace(tmp: Path, path: Path) -> None:
    try:
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        raise write_failed(exc, path, tmp) from exc


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder.

    Parameters
    ----------
    path : str or path
        The file to write; replaced in one rename if it exists.
    data : bytes
        Its content.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        Naming ``path`` when the disk is full or the folder is not writable; ``path``
        itself is then untouched.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
    except OSError as exc:
        raise write_failed(exc, path, tmp) from exc
    _fsync_replace(tmp, path)
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically.

    Parameters
    ----------
    path : str or path
        The file to write.
    text : str
        Its content.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Write ``obj`` as indented JSON atomically (NaN and infinity become null).

    Parameters
    ----------
    path : str or path
        The JSON file to write.
    obj : object
        Plain values, NumPy scalars and arrays.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_text(path, json.dumps(to_jsonable(obj), indent=2, allow_nan=False)
                             + "\n")


def atomic_savefig(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically (``name.tmp.png`` then rename) and close it;
    a PNG gets a 256-colour palette (``bayesmodal.plots._png.save_png``).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or path
        The image file; its suffix chooses the format.
    dpi : int
        Resolution, dots per inch.

    Returns
    -------
    Path
        ``path``.
    """
    import matplotlib.pyplot as plt


    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    try:
        if path.suffix.lower() == ".png":
            save_png(fig, tmp, dpi=dpi)
        else:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight")
    except OSError as exc:
        raise write_failed(exc, path, tmp) from exc
    finally:
        plt.close(fig)
    _fsync_replace(tmp, path)
    return path


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class RunFolder:
    """The output folder of one run.

    Parameters
    ----------
    path : str or path
        Folder (created on :meth:`lock`).

    Examples
    --------
    >>> import tempfile
    >>> folder = RunFolder(tempfile.mkdtemp())
    >>> with folder.lock():
    ...     _ = folder.write_status("running", config_hash="abc")
    >>> folder.status()["state"]
    'running'
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"RunFolder({str(self.path)!r})"

    @property
    def lock_path(self) -> Path:
        return self.path / "run.lock"

    @property
    def checkpoint_path(self) -> Path:
        return self.path / "chain.h5"

    # ------------------------------------------------------------------ status
    def status(self) -> dict | None:
        """The parsed ``status.json``, or None when the folder holds no run."""
        p = self.path / "status.json"
        if not p.is_file():
            return None
        try:
            st = json.loads(p.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{p}: unreadable run status ({exc})") from exc
        if not isinstance(st, dict) or st.get("state") not in STATES:
            raise ConfigError(f"{p}: not a run status file")
        return st

    def write_status(self, state: str, **fields) -> dict:
        """Write ``status.json`` with ``state`` and ``fields`` (kept from the old status
        unless given again); returns the new status."""
        if state not in STATES:
            raise ValueError(f"state must be one of {STATES}, got {state!r}")
        old = self.status() or {}
        st = {**old, **fields, "state": state, "updated": now_iso(), "pid": os.getpid(),
              "host": socket.gethostname()}
        if state != "failed":
            st.pop("error", None)
            st.pop("failed", None)
        atomic_write_json(self.path / "status.json", st)
        return st

    # ------------------------------------------------------------------ files
    def write_text(self, name: str, text: str) -> Path:
        return atomic_write_text(self.path / name, text)

    def write_bytes(self, name: str, data: bytes) -> Path:
        return atomic_write_bytes(self.path / name, data)

    def write_json(self, name: str, obj) -> Path:
        return atomic_write_json(self.path / name, obj)

    def remove_temporaries(self) -> list[Path]:
        """Delete ``*.tmp`` and ``*.tmp.*`` files left by an interrupted writer."""
        gone = []
        if self.path.is_dir():
            for p in self.path.iterdir():
                if p.is_file() and (p.name.endswith(".tmp") or ".tmp." in p.name):
                    p.unlink()
                    gone.append(p)
        return gone

    def clear(self) -> None:
        """Delete the run's own files (``RUN_FILES`` and ``*.png``), nothing else."""
        self.remove_temporaries()
        for name in RUN_FILES:
            (self.path / name).unlink(missing_ok=True)
        for p in self.path.glob("*.png"):
            p.unlink()

    # ------------------------------------------------------------------ lock
    def _holder(self) -> dict | None:
        try:
            return json.loads(self.lock_path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            return None

    def _stale(self) -> bool:
        h = self._holder()
        if h is None:  # unreadable: the writer died between creating and filling it
            return True
        if h.get("host") != socket.gethostname():
            return False  # cannot tell from here
        return not _pid_alive(int(h.get("pid", -1)))

    @contextlib.contextmanager
    def lock(self):
        """Hold ``run.lock`` for the duration of the block.

        Raises
        ------
        RunLockedError
            When a live process holds the lock.
        """
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OSError(exc.errno, f"cannot create the run folder {self.path}: "
                          f"{exc.strerror or exc}") from exc
        content = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                              "since": now_iso()}).encode()
        for _ in range(2):
            try:
                fd = os.open(self.lock_path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self._stale():
                    self.lock_path.unlink(missing_ok=True)
                    continue
                h = self._holder() or {}
                raise RunLockedError(
                    f"{self.path} is being written by process {h.get('pid')} on "
                    f"{h.get('host')} (since {h.get('since')}); wait for it or stop it"
                ) from None
            try:
                os.write(fd, content)
            finally:
                os.close(fd)
            break
        else:  # pragma: no cover - a third process took the stale lock in between
            raise RunLockedError(f"{self.path}: could not take the lock")
        try:
            yield self
        finally:
            self.lock_path.unlink(missing_ok=True)
