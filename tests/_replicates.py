"""Running the replicates of a known-truth study, in processes or in this one (the
coverage benchmarks and their reduced tests)."""

from __future__ import annotations

import sys


def map_replicates(replicate, tasks: list, processes: int = 1,
                   progress: bool = False) -> list:
    """``[replicate(t) for t in tasks]``, in ``processes`` forked processes when above 1
    (results in the order they finish), with an ``i/n`` counter on stderr."""
    out = []

    def tick(i):
        if progress:
            print(f"\r{i + 1}/{len(tasks)}", end="", file=sys.stderr, flush=True)

    if processes > 1:
        import multiprocessing as mp

        from bayesmodal._blas import blas_pool

        with blas_pool(processes, mp.get_context("fork")) as pool:
            for i, res in enumerate(pool.imap_unordered(replicate, tasks)):
                out.append(res)
                tick(i)
    else:
        for i, task in enumerate(tasks):
            out.append(replicate(task))
            tick(i)
    if progress:
        print(file=sys.stderr)
    return out
