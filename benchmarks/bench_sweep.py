"""Speed of a sweep's kernel: runs per second per core, vmap batches vs a serial loop of the same
runs.

    python benchmarks/bench_sweep.py [--batch 8 32 64] [--runs 64] [--duration 10] [--repeats 2]

The `newton-lissajous` kernel computes ``--runs`` runs (fixed and stabilized heads alternating,
K̂ errors spread over ±30 %, one seed each) of ``--duration`` simulated seconds: as vmap batches of
each ``--batch`` size (the last batch padded, as a sweep task does) and as a plain serial loop
(one compiled run, called once per run). Everything runs in this process, pinned to one core, each
kernel compiled before timing; the timings alternate between the variants (best of
``--repeats``), so that the load of a shared machine falls on all of them alike. Printed: the
compile time, runs per second per core, the ratio to the serial loop, and the largest difference
between a batched run's metrics and the same run computed alone (must be ≤ 1e-12).

A sweep's runs/s is about the batched figure times the worker processes; Dask adds a per-task
cost only.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from verticality.sweep.kernels import NEWTON_LISSAJOUS as K


def columns(n: int) -> dict[str, np.ndarray]:
    cols = {k: np.full(n, v.default, dtype=object if v.choices else float)
            for k, v in K.knobs.items()}
    cols["head"] = np.array(["fixed", "stabilized"] * (n // 2) + ["fixed"] * (n % 2))
    cols["K_rel_error"] = np.linspace(-0.3, 0.3, n)
    return cols


def in_batches(cols, seeds, batch: int, duration_s: float) -> dict[str, np.ndarray]:
    """The runs in batches of ``batch`` (the last one padded with its last run), as a sweep task."""
    n = seeds.shape[0]
    parts = []
    for a in range(0, n, batch):
        rows = np.minimum(np.arange(a, a + batch), n - 1)
        parts.append(K.run_batch({k: v[rows] for k, v in cols.items()}, seeds[rows],
                                 duration_s=duration_s))
    return {k: np.concatenate([p[k] for p in parts])[:n] for k in parts[0]}


def timed(f):
    t = time.perf_counter()
    out = f()
    return time.perf_counter() - t, out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, nargs="+", default=[8, 32, 64])
    ap.add_argument("--runs", type=int, default=64)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    n, cols, seeds = a.runs, columns(a.runs), np.arange(a.runs)
    variants = {"serial": 1} | {f"batch {b}": b for b in a.batch}
    best, results = {}, {}
    for name, b in variants.items():  # compile (one batch shape each)
        t, _ = timed(lambda b=b: K.run_batch({k: v[:b] for k, v in cols.items()}, seeds[:b],
                                             duration_s=a.duration))
        print(f"{name:>9}: compile + first batch {t:.1f} s", flush=True)
    for _ in range(a.repeats):
        for name, b in variants.items():
            t, results[name] = timed(lambda b=b: in_batches(cols, seeds, b, a.duration))
            best[name] = min(best.get(name, np.inf), t)
    print(f"{n} runs of {a.duration:g} s simulated, one core")
    for name in variants:
        diff = max(float(np.nanmax(np.abs(results[name][m] - results["serial"][m])
                                   / np.maximum(np.abs(results["serial"][m]), 1e-300)))
                   for m in K.metrics)
        print(f"{name:>9}: {best[name]:7.2f} s → {n / best[name]:6.2f} runs/s/core, "
              f"{best['serial'] / best[name]:4.2f}× serial, max rel. diff to serial {diff:.1e}")


if __name__ == "__main__":
    main()
