"""BLAS threads for processes that share the cores.

OpenBLAS starts one thread per core in every process.  Where a job runs one process per
core (a batch of runs, the folds of a leave-one-record-out check, a pytest-xdist worker
per core), each process's BLAS threads then wait for the others': an SVD of a
least-squares Jacobian (7 200 x 12) took 3 ms on one thread and 16-73 ms on two beside a
busy process (``python benchmarks/blas_threads.py``).  As joblib does for its workers,
each process of a pool gets its share of the cores, through ``threadpoolctl``.
"""

from __future__ import annotations

import os

__all__ = ["available_cores", "blas_pool", "blas_share", "limit_blas"]

#: The limit set in this process by :func:`limit_blas` (kept so that it stays in force).
_LIMIT = []


def available_cores() -> int:
    """The number of cores this process may run on (its CPU affinity where the platform
    has one, else the machine's count).

    Returns
    -------
    int
        At least 1.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (not on every platform)
        return max(1, os.cpu_count() or 1)


def blas_share(n_processes: int) -> int:
    """BLAS threads for each of ``n_processes`` processes that share this machine's cores.

    Parameters
    ----------
    n_processes : int
        Processes running at once (>= 1).

    Returns
    -------
    int
        ``max(1, cores // n_processes)``.

    Examples
    --------
    >>> blas_share(10 ** 6)
    1
    >>> blas_share(1) == available_cores()
    True
    """
    return max(1, available_cores() // max(1, int(n_processes)))


def limit_blas(n_threads: int) -> None:
    """Limit this process's BLAS libraries to ``n_threads`` threads from now on (a pool's
    initializer: ``initializer=limit_blas, initargs=(blas_share(n),)``).

    Parameters
    ----------
    n_threads : int
        Threads per BLAS call (>= 1).
    """
    from threadpoolctl import threadpool_limits

    _LIMIT.append(threadpool_limits(max(1, int(n_threads)), user_api="blas"))


def blas_pool(processes: int, context=None):
    """A ``multiprocessing`` pool of ``processes`` workers, each limited to its share of
    the cores for BLAS (:func:`blas_share`, set by :func:`limit_blas` as the initializer).

    Parameters
    ----------
    processes : int
        Worker processes (>= 1).
    context : multiprocessing context, optional
        E.g. ``multiprocessing.get_context("fork")``; the default context when None.

    Returns
    -------
    multiprocessing.pool.Pool
    """
    import multiprocessing

    ctx = multiprocessing if context is None else context
    return ctx.Pool(processes, limit_blas, (blas_share(processes),))
