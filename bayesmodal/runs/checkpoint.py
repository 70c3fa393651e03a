"""An emcee backend whose checkpoint file is always complete.

emcee's ``HDFBackend`` writes every step into the file in place; a process killed while
the file is open can leave it unreadable.  :class:`AtomicCheckpoint` keeps the chain in
memory (it is emcee's in-memory ``Backend``) and every ``every_s`` seconds, and at the last
step of each ``run_mcmc`` call, writes the whole state to a temporary file that replaces
the checkpoint atomically.  The file has the layout of ``emcee.backends.HDFBackend``
(group ``mcmc`` with ``chain``, ``log_prob``, ``blobs``, ``accepted`` and the generator
state ``random_state_0..4`` after the last stored step), so emcee can read it too.

The periodic checkpoints are written uncompressed (a write must be quick: it holds up the
sampler); the write at the end of a ``run_mcmc`` call, which is the file a finished run
keeps, compresses the datasets losslessly (HDF5 gzip level 1: about a third of the size
for a DE-move chain, whose rejected proposals repeat the previous row; shuffling the bytes
first made it larger).  The values stay float64, so a resumed run is bit-exact either way.

Because the generator state is stored with the step it follows, a run resumed from the
file continues exactly as the uninterrupted run did: same proposals, same chain.
**Compaction.**  A finished run needs neither the float64 chain nor every step: its
posterior draws (float64) are in ``posterior.nc`` and its diagnostics in ``summary.json``.
:func:`compact_checkpoint` rewrites the file of a finished run with every ``k``-th step
in float32 (the trace; ``k`` divides burn-in and thinning, so the trace holds every
retained draw) and the final walker state in float64 with the generator state
(:func:`last_state`): emcee continued from that state takes exactly the steps the longer
uninterrupted run would have taken.  A compacted file cannot be resumed as a checkpoint.

Attributes named ``_bayesmodal_<key>`` (how ``bayesmodal.inference.sample_posterior``
tags a non-HDF backend with its configuration hash) are stored as ``bayesmodal_<key>``,
the attribute name it uses in HDF files.
"""

from __future__ import annotations

import errno
import math
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import emcee
import numpy as np

from .._errors import ConfigError
from .folder import _fsync_replace, write_failed

__all__ = ["AtomicCheckpoint", "checkpoint_iteration", "compact_checkpoint", "last_state",
           "read_trace", "trace_stride", "Trace", "COMPACT_TRACE_STEPS"]

_TAG = "_bayesmodal_"


class AtomicCheckpoint(emcee.backends.Backend):
    """In-memory emcee backend with atomic HDF5 checkpoints.

    Parameters
    ----------
    path : str or path
        Checkpoint file; loaded if it exists.
    every_s : float
        Minimum wall time between two checkpoint writes, s.
    name : str
        HDF group name (emcee's default ``"mcmc"``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "chain.h5"
    >>> be = AtomicCheckpoint(p)
    >>> s = emcee.EnsembleSampler(4, 1, lambda x: -0.5 * float(x[0] ** 2), backend=be)
    >>> _ = s.run_mcmc(np.random.default_rng(1).normal(size=(4, 1)), 3)
    >>> AtomicCheckpoint(p).iteration
    3
    """

    def __init__(self, path: str | os.PathLike, *, every_s: float = 5.0,
                 name: str = "mcmc") -> None:
        super().__init__()
        self.path = Path(path)
        self.every_s = float(every_s)
        self.name = name
        self.n_writes = 0
        self._last_write = time.monotonic()
        if self.path.is_file():
            self._load()

    def _load(self) -> None:
        import h5py

        with h5py.File(self.path, "r") as f:
            if self.name not in f:
                return
            g = f[self.name]
            if g.attrs.get("compact", False):
                raise ConfigError(
                    f"{self.path} holds the compacted chain of a finished run (every "
                    f"{int(g.attrs['trace_stride'])}th step, float32) and cannot be resumed; "
                    "sample into a new checkpoint, or continue with emcee from "
                    "bayesmodal.runs.last_state(path)")
            it = int(g.attrs["iteration"])
            self.reset(int(g.attrs["nwalkers"]), int(g.attrs["ndim"]))
            self.iteration = it
            self.chain = np.array(g["chain"][:it], dtype=self.dtype)
            self.log_prob = np.array(g["log_prob"][:it], dtype=self.dtype)
            self.accepted = np.array(g["accepted"][:], dtype=self.dtype)
            if g.attrs["has_blobs"]:
                self.blobs = np.array(g["blobs"][:it])
            rs = _read_random_state(g.attrs)
            if rs is not None:
                self.random_state = rs
            for k, v in g.attrs.items():
                if k.startswith("bayesmodal_"):
                    setattr(self, "_" + k, v.decode() if isinstance(v, bytes) else v)

    def reset(self, nwalkers, ndim):
        """Clear the chain (emcee's ``Backend.reset``) and the configuration tags."""
        super().reset(nwalkers, ndim)
        for k in [k for k in vars(self) if k.startswith(_TAG)]:
            delattr(self, k)

    def save_step(self, state, accepted):
        """Store one step (emcee's ``Backend.save_step``), then checkpoint if it is the last
        step of the ``run_mcmc`` call (compressed) or ``every_s`` has passed."""
        super().save_step(state, accepted)
        last = self.iteration == len(self.chain)
        if last:
            self.flush(compress=True)
        elif time.monotonic() - self._last_write >= self.every_s:
            self.flush()

    def flush(self, *, compress: bool = False) -> Path:
        """Write the checkpoint now (temporary file, fsync, rename).

        Parameters
        ----------
        compress : bool
            Compress the datasets (lossless gzip, level 1): slower to write, about a third
            of the size.
        """
        import h5py

        tmp = self.path.with_name(self.path.name + ".tmp")
        # HDF5 does not fail cleanly when the disk fills up during a write (errors from
        # destructors, even a segmentation fault): check the free space first
        need = self._estimated_bytes()
        free = shutil.disk_usage(self.path.parent).free
        if free < need:
            raise write_failed(OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)}: the "
                                       f"checkpoint needs about {need} bytes, {free} are free"),
                               self.path)
        try:
            self._write(h5py, tmp, compress)
        except OSError as exc:  # full disk, no permission: the old checkpoint is kept
            raise write_failed(exc, self.path, tmp) from exc
        _fsync_replace(tmp, self.path)
        self._last_write = time.monotonic()
        self.n_writes += 1
        return self.path

    def _estimated_bytes(self) -> int:
        """Size of the checkpoint file with a margin for HDF5 metadata and chunking, bytes."""
        it = self.iteration
        data = self.chain[:it].nbytes + self.log_prob[:it].nbytes + self.accepted.nbytes
        if self.has_blobs():
            data += self.blobs[:it].nbytes
        return int(1.25 * data) + 256 * 1024

    def _write(self, h5py, tmp: Path, compress: bool) -> None:
        it = self.iteration
        z = {"compression": "gzip", "compression_opts": 1} if compress else {}
        with h5py.File(tmp, "w") as f:
            g = f.create_group(self.name)
            g.attrs["version"] = emcee.__version__
            g.attrs["nwalkers"] = self.nwalkers
            g.attrs["ndim"] = self.ndim
            g.attrs["has_blobs"] = self.has_blobs()
            g.attrs["iteration"] = it
            g.create_dataset("accepted", data=self.accepted)
            g.create_dataset("chain", data=self.chain[:it],
                             maxshape=(None, self.nwalkers, self.ndim), **z)
            g.create_dataset("log_prob", data=self.log_prob[:it],
                             maxshape=(None, self.nwalkers), **z)
            if self.has_blobs():
                g.create_dataset("blobs", data=self.blobs[:it],
                                 maxshape=(None, *self.blobs.shape[1:]), **z)
            _write_state_attrs(g, self)


def _write_state_attrs(g, backend) -> None:
    """The generator state (``random_state_0..4``) and configuration tags of ``backend``
    as attributes of the HDF5 group ``g``."""
    for i, v in enumerate(backend.random_state or ()):
        g.attrs[f"random_state_{i}"] = v
    for k, v in vars(backend).items():
        if k.startswith(_TAG):
            g.attrs[k[1:]] = v


def _read_random_state(attrs) -> tuple | None:
    """The generator state written by :func:`_write_state_attrs`, or None.

    MT19937 state: (name, key array, pos, has_gauss, cached_gaussian); the name comes
    back from HDF5 as bytes or a numpy string and is returned as ``str``."""
    n = sum(1 for k in attrs if k.startswith("random_state_"))
    if n == 0:
        return None
    rs = [attrs[f"random_state_{i}"] for i in range(n)]
    rs[0] = rs[0].decode() if isinstance(rs[0], bytes) else str(rs[0])
    return tuple(rs)


def checkpoint_iteration(path: str | os.PathLike, name: str = "mcmc") -> int:
    """Steps stored in a checkpoint file (0 when absent or empty)."""
    import h5py

    path = Path(path)
    if not path.is_file():
        return 0
    with h5py.File(path, "r") as f:
        return int(f[name].attrs["iteration"]) if name in f else 0


#: Most steps per walker kept in the trace of a compacted checkpoint (see
#: :func:`trace_stride`).
COMPACT_TRACE_STEPS = 1000


def trace_stride(n_steps: int, burn: int, thin: int,
                 max_steps: int = COMPACT_TRACE_STEPS) -> int:
    """Stride ``k`` of a compacted trace: the smallest divisor of ``gcd(burn, thin)`` that
    keeps at most ``max_steps`` steps, else ``gcd(burn, thin)`` itself.

    Because ``k`` divides both, the retained draws (steps ``burn, burn + thin, ...``) are
    all in the trace (steps ``0, k, 2k, ...``).

    Examples
    --------
    >>> trace_stride(12000, 3000, 504)   # the main job: gcd 24, 12000 / 12 = 1000 steps
    12
    >>> trace_stride(500, 100, 5)
    1
    """
    g = math.gcd(int(burn), int(thin))
    for k in range(1, g + 1):
        if g % k == 0 and -(-int(n_steps) // k) <= max_steps:
            return k
    return g


def compact_checkpoint(path: str | os.PathLike, *, burn: int, thin: int,
                       max_steps: int = COMPACT_TRACE_STEPS) -> Path:
    """Rewrite the checkpoint of a finished run compactly (atomically).

    Kept: group ``mcmc`` with the attributes of emcee's layout (``nwalkers``, ``ndim``,
    ``iteration``, generator state ``random_state_0..4``, configuration tags) plus
    ``compact``, ``trace_stride``, ``burn``, ``thin``; datasets ``trace`` (steps
    ``0, k, 2k, ...`` in emcee's sampling coordinates, float32, shape (n, nwalkers, ndim)),
    ``trace_log_prob`` (float32), ``accepted`` and the final state ``last_coords``,
    ``last_log_prob``, ``last_blobs`` (float64).  A file already compact is left as it is.

    Parameters
    ----------
    path : path
        A complete checkpoint (:class:`AtomicCheckpoint` or emcee ``HDFBackend`` layout).
    burn, thin : int
        The run's burn-in and thinning (the stride divides both).
    max_steps : int
        Most trace steps per walker (:func:`trace_stride`).

    Returns
    -------
    pathlib.Path
    """
    import h5py

    path = Path(path)
    with h5py.File(path, "r") as f:
        if f["mcmc"].attrs.get("compact", False):
            return path
    be = AtomicCheckpoint(path)
    it = be.iteration
    if it == 0:
        raise ConfigError(f"{path}: an empty checkpoint has nothing to compact")
    k = trace_stride(it, burn, thin, max_steps)
    z = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
    tmp = path.with_name(path.name + ".tmp")
    try:
        with h5py.File(tmp, "w") as f:
            g = f.create_group("mcmc")
            for key, val in (("version", emcee.__version__), ("nwalkers", be.nwalkers),
                             ("ndim", be.ndim), ("has_blobs", be.has_blobs()),
                             ("iteration", it), ("compact", True), ("trace_stride", k),
                             ("burn", int(burn)), ("thin", int(thin))):
                g.attrs[key] = val
            g.create_dataset("trace", data=be.chain[:it:k].astype(np.float32), **z)
            g.create_dataset("trace_log_prob", data=be.log_prob[:it:k].astype(np.float32),
                             **z)
            g.create_dataset("accepted", data=be.accepted)
            g.create_dataset("last_coords", data=be.chain[it - 1])
            g.create_dataset("last_log_prob", data=be.log_prob[it - 1])
            if be.has_blobs():
                g.create_dataset("last_blobs", data=be.blobs[it - 1])
            _write_state_attrs(g, be)
    except OSError as exc:
        raise write_failed(exc, path, tmp) from exc
    _fsync_replace(tmp, path)
    return path


def last_state(path: str | os.PathLike) -> emcee.State:
    """The final walker state of a checkpoint, full or compacted, float64, with emcee's
    generator state: ``sampler.run_mcmc(last_state(path), n)`` continues the chain
    exactly (the same steps as one longer run).

    Returns
    -------
    emcee.State
    """
    import h5py

    with h5py.File(path, "r") as f:
        g = f["mcmc"]
        if not g.attrs.get("compact", False):
            be = AtomicCheckpoint(path)
            return be.get_last_sample()
        return emcee.State(np.array(g["last_coords"]), log_prob=np.array(g["last_log_prob"]),
                           blobs=np.array(g["last_blobs"]) if "last_blobs" in g else None,
                           random_state=_read_random_state(g.attrs))


@dataclass(frozen=True)
class Trace:
    """The trace of a compacted checkpoint (:func:`read_trace`).

    Attributes
    ----------
    steps : ndarray of int, shape (n,)
        Step index of each row.
    chain : ndarray of float32, shape (n, nwalkers, ndim)
        Sampling coordinates (emcee's).
    log_prob : ndarray of float32, shape (n, nwalkers)
    stride, burn, thin : int
    """

    steps: np.ndarray
    chain: np.ndarray
    log_prob: np.ndarray
    stride: int
    burn: int
    thin: int

    @property
    def retained(self) -> np.ndarray:
        """The rows of the run's retained draws (steps ``burn, burn + thin, ...``), shape
        (n_draws, nwalkers, ndim)."""
        return self.chain[self.burn // self.stride :: self.thin // self.stride]


def read_trace(path: str | os.PathLike) -> Trace:
    """The float32 trace of a compacted checkpoint.

    Raises
    ------
    ConfigError
        When the file is not compacted (read it with :class:`AtomicCheckpoint`).
    """
    import h5py

    with h5py.File(path, "r") as f:
        g = f["mcmc"]
        if not g.attrs.get("compact", False):
            raise ConfigError(f"{path} is a full checkpoint, not a compacted one; read it "
                              "with AtomicCheckpoint(path).get_chain()")
        k = int(g.attrs["trace_stride"])
        chain = np.array(g["trace"])
        return Trace(np.arange(chain.shape[0]) * k, chain, np.array(g["trace_log_prob"]),
                     k, int(g.attrs["burn"]), int(g.attrs["thin"]))
