"""A batched log posterior evaluated on several cores by threads, with the same numbers.

emcee (``vectorize=True``) hands the log posterior one half of the ensemble at a time.
The simulators behind it are compiled without the global interpreter lock (numba
``nogil``), so the half-ensemble can be cut into contiguous blocks of walkers evaluated
side by side in threads.  Each thread has its own deep copy of the log posterior: the
likelihoods reuse their simulators' output buffers, which threads must not share.  Every
walker's value is computed by the same code on the same numbers as in one call (the
batched simulators give each parameter set the result of its single run), so a threaded
run is the serial run, bit for bit, and the number of threads is not part of a run's
identity (its configuration hash).

What it is for: an extended model, whose likelihood is almost all compiled simulation
(LuGre friction on the four measured records: 1.6-1.9 times faster with 2 threads on 2
cores, ``python benchmarks/threads.py``).  The linear model spends a larger share of its
evaluation in numpy under the lock (about 1.1 times faster on the same cores); run several
independent jobs in processes there instead (``bayesmodal batch``, ``crossval``).
"""

from __future__ import annotations

import copy
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .._blas import available_cores
from ..fit._threads import checked_threads

__all__ = ["ThreadedLogPosterior", "resolve_threads"]


def resolve_threads(threads) -> int:
    """The number of threads ``threads`` asks for: a positive integer (or its digits, as
    a command line gives it), or ``"auto"`` for the cores this process may use.

    Raises
    ------
    ConfigError
        One line naming the value and what is allowed.

    Examples
    --------
    >>> resolve_threads(2)
    2
    >>> resolve_threads("3")
    3
    >>> resolve_threads("auto") >= 1
    True
    """
    if isinstance(threads, str) and threads.strip().isdigit():
        threads = int(threads)
    if isinstance(threads, str) and threads.strip().lower() == "auto":
        return available_cores()
    return checked_threads(threads, "a positive integer or 'auto'")


class ThreadedLogPosterior:
    """``log_post`` evaluated on blocks of walkers in ``threads`` threads.

    Parameters
    ----------
    log_post : LogPosterior
        Batched log posterior: ``(nb, P)`` sampling coordinates -> ``(nb, 2)`` (log
        posterior, log-likelihood).
    threads : int
        Number of threads, at least 1.  With 1 the call is ``log_post`` itself.

    Notes
    -----
    The thread pool is started by the first call and stopped by ``close`` (or at the end
    of a ``with`` block).  ``likelihood``, ``priors`` and ``temperature`` are those of
    ``log_post``, so the object stands wherever a ``LogPosterior`` does.

    Examples
    --------
    >>> class Sq:                        # any batched log posterior
    ...     likelihood = priors = None; temperature = 1.0
    ...     def __call__(self, z):
    ...         return np.column_stack([-np.sum(z ** 2, axis=1), np.zeros(len(z))])
    >>> z = np.arange(12.0).reshape(6, 2)
    >>> with ThreadedLogPosterior(Sq(), 2) as lp:
    ...     bool(np.array_equal(lp(z), Sq()(z)))
    True
    """

    def __init__(self, log_post, threads: int = 1) -> None:
        self._base = log_post
        self.threads = resolve_threads(threads)
        # one copy per thread beyond the first: their buffers are their own
        self._copies = [log_post] + [copy.deepcopy(log_post) for _ in range(self.threads - 1)]
        self._pool: ThreadPoolExecutor | None = None

    @property
    def likelihood(self):
        return self._base.likelihood

    @property
    def priors(self):
        return self._base.priors

    @property
    def temperature(self) -> float:
        return self._base.temperature

    def __call__(self, z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(np.asarray(z, dtype=float))
        k = min(self.threads, z.shape[0])
        if k <= 1:
            return self._base(z)
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads - 1,
                                            thread_name_prefix="bayesmodal-logpost")
        blocks = np.array_split(z, k)
        futures = [self._pool.submit(lp, b)
                   for lp, b in zip(self._copies[1:k], blocks[1:], strict=True)]
        first = self._copies[0](blocks[0])  # this thread takes the first block
        return np.concatenate([first] + [f.result() for f in futures])

    def close(self) -> None:
        """Stop the thread pool (a later call starts a new one)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> ThreadedLogPosterior:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
