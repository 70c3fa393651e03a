"""Threads for the independent parts of a fit, with the same numbers on any number of them.

A diagnosis spends its time in parts that do not depend on one another: the local
least-squares searches from several starts, the generations of the differential evolution
(one batched call over hundreds of parameter sets), and the leave-one-record-out refits of
each fold.  The simulators behind all of them are compiled without the global interpreter
lock (numba ``nogil``) and give each parameter set the result of its single run, whatever
the rest of its batch, and LAPACK's SVD in ``least_squares`` gives the same bits when two
threads call it at once.  So these parts run side by side in threads and every number is
the one a single thread computes: the thread count is not part of a result's identity.

The count is set for a block of code (``with fit_threads(2): ...``) rather than passed
through every fitting function.  Each call runs in a copy of the caller's context (numpy's
error state as the caller set it) with one thread, so the parts never nest.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .._errors import ConfigError

__all__ = ["fit_threads", "thread_count", "thread_map", "split_rows"]

#: Threads of the independent parts of the fits in this context.
_THREADS: contextvars.ContextVar[int] = contextvars.ContextVar("bayesmodal_fit_threads",
                                                               default=1)


@contextlib.contextmanager
def fit_threads(threads: int) -> Iterator[int]:
    """Run the independent parts of the fits inside the block on up to ``threads`` threads.

    Parameters
    ----------
    threads : int
        At least 1 (``bayesmodal.inference.threads.resolve_threads`` turns ``"auto"``
        into the cores this process may use).

    Yields
    ------
    int
        The count in force.

    Examples
    --------
    >>> with fit_threads(2):
    ...     thread_map(lambda x: x * x, [1, 2, 3])
    [1, 4, 9]
    """
    threads = checked_threads(threads)
    token = _THREADS.set(threads)
    try:
        yield threads
    finally:
        _THREADS.reset(token)


def checked_threads(threads, allowed: str = "a positive integer") -> int:
    """``threads`` as an ``int`` of at least 1.

    Parameters
    ----------
    threads : int
        The count asked for.
    allowed : str
        What the caller accepts, for the error message.

    Raises
    ------
    ConfigError
        One line naming the value and ``allowed``.
    """
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ConfigError(f"threads must be {allowed}, got {threads!r}")
    return int(threads)


def thread_count() -> int:
    """The threads the fits may use here (1 outside ``fit_threads`` and in its workers).

    Returns
    -------
    int
    """
    return _THREADS.get()


def thread_map(fn: Callable, items: Iterable) -> list:
    """``[fn(x) for x in items]``, the calls spread over ``thread_count()`` threads.

    Parameters
    ----------
    fn : callable
        Called once per item; its calls must not share mutable state.
    items : iterable

    Returns
    -------
    list
        In the order of ``items``; the first exception raised by a call is raised here.
    """
    items = list(items)
    k = min(thread_count(), len(items))
    if k <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(k, thread_name_prefix="bayesmodal-fit") as pool:
        # each call in a copy of the caller's context (numpy's error state, as the
        # caller set it), with one thread for the parts it runs itself
        futures = [pool.submit(contextvars.copy_context().run, _single, fn, x)
                   for x in items]
        return [f.result() for f in futures]


def _single(fn: Callable, x):
    _THREADS.set(1)
    return fn(x)


def split_rows(fn: Callable[[np.ndarray], np.ndarray], rows: np.ndarray,
               min_rows: int = 16) -> np.ndarray:
    """``fn(rows)`` computed on contiguous blocks of rows in threads and joined.

    Parameters
    ----------
    fn : callable
        Maps an array of rows (m, ...) to one result row each, (m, ...); a row's result
        must not depend on the other rows (the batched simulators' property).
    rows : ndarray, shape (n, ...)
    min_rows : int
        Fewest rows a block gets (a thread for a handful of parameter sets costs more
        than it saves).

    Returns
    -------
    ndarray, shape (n, ...)
    """
    k = min(thread_count(), rows.shape[0] // max(int(min_rows), 1))
    if k <= 1:
        return fn(rows)
    return np.concatenate(thread_map(fn, np.array_split(rows, k)))
