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
Attributes named ``_bayesmodal_<key>`` (how ``bayesmodal.inference.sample_posterior``
tags a non-HDF backend with its configuration hash) are stored as ``bayesmodal_<key>``,
the attribute name it uses in HDF files.
"""

from __future__ import annotations

import errno
import os
import shutil
import time
from pathlib import Path

import emcee
import numpy as np

from .folder import _fsync_replace, write_failed

__all__ = ["AtomicCheckpoint", "checkpoint_iteration"]

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
            it = int(g.attrs["iteration"])
            self.reset(int(g.attrs["nwalkers"]), int(g.attrs["ndim"]))
            self.iteration = it
            self.chain = np.array(g["chain"][:it], dtype=self.dtype)
            self.log_prob = np.array(g["log_prob"][:it], dtype=self.dtype)
            self.accepted = np.array(g["accepted"][:], dtype=self.dtype)
            if g.attrs["has_blobs"]:
                self.blobs = np.array(g["blobs"][:it])
            keys = sorted(k for k in g.attrs if k.startswith("random_state_"))
            if keys:
                self.random_state = tuple(g.attrs[f"random_state_{i}"]
                                          for i in range(len(keys)))
                # MT19937 state: (name, key array, pos, has_gauss, cached_gaussian)
                rs = list(self.random_state)
                rs[0] = rs[0].decode() if isinstance(rs[0], bytes) else str(rs[0])
                self.random_state = tuple(rs)
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
            if self.random_state is not None:
                for i, v in enumerate(self.random_state):
                    g.attrs[f"random_state_{i}"] = v
            for k, v in vars(self).items():
                if k.startswith(_TAG):
                    g.attrs[k[1:]] = v


def checkpoint_iteration(path: str | os.PathLike, name: str = "mcmc") -> int:
    """Steps stored in a checkpoint file (0 when absent or empty)."""
    import h5py

    path = Path(path)
    if not path.is_file():
        return 0
    with h5py.File(path, "r") as f:
        return int(f[name].attrs["iteration"]) if name in f else 0
