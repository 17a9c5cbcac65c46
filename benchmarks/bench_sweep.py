"""Speed of a sweep's kernel: runs per second per core, one vmap batch vs a serial loop of the same runs.

    python benchmarks/bench_sweep.py [--batch 8] [--duration 10] [--repeats 2]

The `newton-lissajous` kernel runs ``--batch`` runs (fixed and stabilized heads, K̂ errors spread
over ±30 %, one seed each) of ``--duration`` simulated seconds twice: as one vmap batch of
``--batch`` and as a loop of batches of 1 (one compiled run, called once per run). Both are
compiled before timing (best of ``--repeats``); one process, one core. The ratio is batch runs/s
over serial runs/s. The distribution itself (Dask) adds a per-task cost only; a sweep's runs/s is
about this figure times the worker processes.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from verticality.sweep.kernels import NEWTON_LISSAJOUS as K


def columns(n: int) -> dict[str, np.ndarray]:
    cols = {k: np.full(n, v.default, dtype=object if v.choices else float)
            for k, v in K.knobs.items()}
    cols["head"] = np.array(["fixed", "stabilized"] * (n // 2) + ["fixed"] * (n % 2))
    cols["K_rel_error"] = np.linspace(-0.3, 0.3, n)
    return cols


def best(f, repeats: int) -> float:
    f()  # compile
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    n, cols, seeds = a.batch, columns(a.batch), np.arange(a.batch)
    batch_s = best(lambda: K.run_batch(cols, seeds, duration_s=a.duration), a.repeats)

    def serial():
        for i in range(n):
            K.run_batch({k: v[i:i + 1] for k, v in cols.items()}, seeds[i:i + 1],
                        duration_s=a.duration)

    serial_s = best(serial, a.repeats)
    print(f"{n} runs of {a.duration:g} s, one core")
    print(f"vmap batch of {n}: {batch_s:.2f} s  → {n / batch_s:.2f} runs/s")
    print(f"serial loop     : {serial_s:.2f} s  → {n / serial_s:.2f} runs/s")
    print(f"batch / serial  : {serial_s / batch_s:.2f}×")


if __name__ == "__main__":
    main()
