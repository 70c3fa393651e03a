"""What BLAS threads buy a least-squares fit, alone and beside another busy process.

scipy's trust-region least squares (``method="trf"``) takes an SVD of the Jacobian at
every step: a record of 2 400 samples of three carts with 12 parameters gives a 7 200 x
12 matrix, the four measured records with 22 parameters 87 000 x 22.  OpenBLAS starts one
thread per core.  Where every core already runs a process of the same job (a pytest-xdist
worker per core, a replicate pool of ``--processes`` equal to the cores), those threads
wait for each other.  This times the SVD (wall time, median of ``--repeats`` blocks of one
second) with one and with all BLAS threads (``threadpoolctl``), on the machine as it is
and beside one process per other core that keeps computing (as a second pytest worker
does).

Usage::

    python benchmarks/blas_threads.py          # about 20 s
    python benchmarks/blas_threads.py --json
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SHAPES = ((7_200, 12), (87_000, 22))


def _busy(stop) -> None:
    """A neighbour that computes: numpy arithmetic on a small array, one thread."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        a = np.random.default_rng(1).normal(size=(64, 64))
        while not stop.is_set():
            a = np.tanh(a @ a.T * 1e-3)


def ms_per_svd(shape: tuple[int, int], threads: int, repeats: int, rng) -> float:
    """Median wall time (ms) of ``scipy.linalg.svd(J, full_matrices=False)`` of a
    Gaussian ``J`` of ``shape``, with ``threads`` BLAS threads."""
    from scipy.linalg import svd
    from threadpoolctl import threadpool_limits

    jac = rng.normal(size=shape)
    times = []
    with threadpool_limits(threads, user_api="blas"):
        svd(jac, full_matrices=False)
        for _ in range(repeats):
            n, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < 1.0:
                svd(jac, full_matrices=False)
                n += 1
            times.append(1e3 * (time.perf_counter() - t0) / n)
    return float(np.median(times))


def run(repeats: int = 3) -> dict:
    from bayesmodal._blas import available_cores

    cores = available_cores()
    rng = np.random.default_rng(0)
    out = {"cores": cores, "load_at_start": os.getloadavg()[0], "rows": []}
    for beside in (False, True):
        stop = mp.Event()
        procs = [mp.Process(target=_busy, args=(stop,), daemon=True)
                 for _ in range(cores - 1 if beside else 0)]
        for p in procs:
            p.start()
        try:
            for shape in SHAPES:
                one = ms_per_svd(shape, 1, repeats, rng)
                every = ms_per_svd(shape, cores, repeats, rng)
                out["rows"].append({"shape": list(shape), "busy_neighbours": len(procs),
                                    "ms_1_thread": one, f"ms_{cores}_threads": every,
                                    "ratio": every / one})
        finally:
            stop.set()
            for p in procs:
                p.join()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    res = run(a.repeats)
    if a.json:
        print(json.dumps(res, indent=1))
        return 0
    print(f"{res['cores']} cores, load at start {res['load_at_start']:.2f}")
    print("shape          busy neighbours  1 thread (ms)  all threads (ms)  ratio")
    for r in res["rows"]:
        every = r[f"ms_{res['cores']}_threads"]
        print(f"{r['shape'][0]:>6} x {r['shape'][1]:<4} {r['busy_neighbours']:>15} "
              f"{r['ms_1_thread']:>14.2f} {every:>17.2f} {r['ratio']:>6.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
