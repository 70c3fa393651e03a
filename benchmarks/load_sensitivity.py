"""Which side of a `bayesmodal bench` ratio a neighbouring process slows.

Times the linear simulator (the benchmark's baseline) and two friction kernels on the
rig-like input, as `bayesmodal bench` does (CPU time of this process, best of three
repeats, median of ``--rounds`` rounds), four times: on the idle machine, beside a
process that only computes (a pure-Python loop: no memory traffic), beside one that
streams memory (copies of a 256 MB array: the shared cache and the memory bus), and idle
again.  On 25 Nov 2026 (2 cores) two runs disagreed: in the first the memory neighbour
slowed the baseline by 45 % (21.7-26.8 -> 31.6 us per evaluation) and left the friction
kernels unchanged (ratios 15.7x -> 10.9x Coulomb, 34.7x -> 24.4x LuGre + dead band +
offset); in the second the baseline was faster beside it (27.5 idle, 22.6 beside the
memory neighbour).  The friction kernels' own times stayed within a few per cent in both;
the baseline moves by up to a factor 1.8 between runs with nothing of ours beside it
(docs/performance.md, "Status on an idle machine").

Usage::

    python benchmarks/load_sensitivity.py            # about 2.5 minutes on 2 cores
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

MODELS = ("coulomb_friction", "lugre_friction+drive_deadband+input_offset")


def _neighbour(kind: str, stop) -> None:
    if kind == "compute":
        x = 0
        while not stop.is_set():
            for i in range(100_000):
                x += i * i
    else:
        a = np.ones(32_000_000)  # 256 MB
        b = np.empty_like(a)
        while not stop.is_set():
            np.copyto(b, a)


def main(argv=None) -> int:
    from bayesmodal.bench import (
        _bench_problem,
        extension_theta,
        reused_linear,
        rig_input,
        time_per_call,
    )
    from bayesmodal.model.effects import get_extension

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    batch, n, dt = 64, 8000, 0.005
    model, theta, _ = _bench_problem(n, batch, 0)
    u = rig_input(n, dt)
    linear = reused_linear(model, theta, u, dt)
    exts = {m: get_extension(m) for m in MODELS}
    thetas = {m: extension_theta(theta, m) for m in MODELS}

    def timed(fn):
        return time_per_call(fn, min_time_s=1.0, repeat=3, clock=time.process_time)

    for kind in ("idle", "compute", "memory", "idle"):
        stop = mp.Event()
        proc = None
        if kind != "idle":
            proc = mp.Process(target=_neighbour, args=(kind, stop))
            proc.start()
            time.sleep(1.0)
        t = {"linear": [], **{m: [] for m in MODELS}}
        try:
            for _ in range(args.rounds):
                t["linear"].append(timed(linear))
                for m in MODELS:
                    t[m].append(timed(lambda e=exts[m], th=thetas[m]:
                                      e.simulate(model.rig, th, u, dt)))
        finally:
            if proc is not None:
                stop.set()
                proc.join()
        lin = np.array(t["linear"])
        line = [f"{kind:8s} linear {np.median(lin) / batch * 1e6:6.1f} us"]
        for m in MODELS:
            tm = np.array(t[m])
            line.append(f"{m}: {np.median(tm) / batch * 1e6:6.0f} us, "
                        f"{np.median(tm / lin):5.1f}x")
        print(" | ".join(line), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
