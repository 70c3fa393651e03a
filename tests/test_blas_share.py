"""Each process of a pool gets its share of the cores for BLAS (bayesmodal._blas)."""

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import pytest

from bayesmodal._blas import available_cores, blas_pool, blas_share, limit_blas


def _blas_threads() -> list[int]:
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def _in_pool(**kw) -> list[int]:
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx, **kw) as pool:
        return pool.submit(_blas_threads).result()


def test_share_divides_the_cores():
    n = available_cores()
    assert blas_share(1) == n
    assert blas_share(n) == 1
    assert blas_share(2 * n + 1) == 1
    assert blas_share(0) == n  # no processes counts as one


def test_a_pool_initializer_limits_its_process():
    threads = _in_pool(initializer=limit_blas, initargs=(1,))
    assert threads and all(t == 1 for t in threads)


def _pool_threads() -> list[int]:
    with blas_pool(2, multiprocessing.get_context("spawn")) as pool:
        return pool.apply(_blas_threads)


def test_a_blas_pool_gives_each_worker_its_share():
    threads = _pool_threads()
    assert threads and all(t == blas_share(2) for t in threads)


def test_without_the_initializer_a_process_takes_every_core():
    # negative control: what the initializer changes
    if available_cores() < 2:
        pytest.skip("one core: BLAS starts one thread anyway")
    threads = _in_pool()
    assert threads and all(t == available_cores() for t in threads)
