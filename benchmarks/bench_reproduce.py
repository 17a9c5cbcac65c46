"""Speed of `verticality reproduce` in worker processes against the same run one experiment after
the other, in the same invocation.

    python benchmarks/bench_reproduce.py [NAME...] [--full] [--jobs N] [--repeats R]

Runs ``verticality reproduce NAME... --json --no-report`` (every experiment when no NAME is given;
``--quick`` unless ``--full``) as a fresh process twice per repeat, alternately: ``--jobs 1`` (in
one process, one after the other) and ``--jobs N`` (default: one per core). Each run starts cold:
an empty JAX compilation cache of its own, so both pay every compilation. Reported per run: wall
seconds and the CPU seconds of the command and its workers; then the ratio parallel / serial of
the wall times (median over the repeats), and whether the two runs' results are the same (every
metric, published value and simulated duration; only the wall times may differ).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(names: list[str], quick: bool, jobs: int) -> tuple[float, float, dict]:
    """Wall seconds, CPU seconds (the command and its workers) and the results object of one
    cold run."""
    with tempfile.TemporaryDirectory(prefix="bench-reproduce-") as cache:
        env = dict(os.environ, VERTICALITY_JAX_CACHE=cache,
                   PYTHONPATH=os.pathsep.join(filter(None, [str(SRC),
                                                            os.environ.get("PYTHONPATH")])))
        env.pop("JAX_COMPILATION_CACHE_DIR", None)
        cmd = [sys.executable, "-m", "verticality", "reproduce", *names, "--json",
               "--no-report", "--jobs", str(jobs), *(["--quick"] if quick else [])]
        cpu0, t0 = _children_cpu_s(), time.perf_counter()
        done = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
    if done.returncode not in (0, 1):  # 1: a check failed, the timing still counts
        sys.exit(f"reproduce --jobs {jobs} failed ({done.returncode}):\n{done.stderr}")
    return wall, cpu, json.loads(done.stdout)


def comparable(results: dict) -> dict:
    """The results without the wall times."""
    return {name: {k: (v if k != "runtime" else v["simulated_s"]) for k, v in entry.items()}
            for name, entry in results["experiments"].items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", metavar="NAME")
    parser.add_argument("--full", action="store_true", help="full runs instead of --quick")
    parser.add_argument("--jobs", type=int, default=len(os.sched_getaffinity(0)))
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    quick = not args.full
    walls: dict[int, list[float]] = {1: [], args.jobs: []}
    results: dict[int, dict] = {}
    for r in range(args.repeats):
        for jobs in (1, args.jobs) if r % 2 == 0 else (args.jobs, 1):
            wall, cpu, res = run_once(args.names, quick, jobs)
            walls[jobs].append(wall)
            results[jobs] = res
            print(f"--jobs {jobs}: {wall:7.1f} s wall, {cpu:7.1f} s CPU "
                  f"({len(res['experiments'])} experiments, {'quick' if quick else 'full'}, cold)",
                  flush=True)
    serial, parallel = statistics.median(walls[1]), statistics.median(walls[args.jobs])
    same = comparable(results[1]) == comparable(results[args.jobs])
    print(f"serial {serial:.1f} s, parallel ({args.jobs} jobs) {parallel:.1f} s: "
          f"ratio parallel/serial {parallel / serial:.2f}; same results: {same}")
    if not same:
        sys.exit(1)


if __name__ == "__main__":
    main()
