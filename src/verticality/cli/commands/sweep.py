"""``verticality sweep SPEC.toml [--scheduler ADDRESS] [--workers N] [--out DIR] [--resume]``: run a
parameter sweep on Dask and write ``DIR/results.parquet`` (docs/sweep.md)."""

from __future__ import annotations

from pathlib import Path

from verticality.cli.commands import add_engine_arguments


def register(sub):
    p = sub.add_parser("sweep", help="run a parameter sweep (Dask) into a Parquet table")
    p.add_argument("spec", type=Path, metavar="SPEC.toml", help="the sweep's specification")
    add_engine_arguments(p, "the sweep's tasks", "a local cluster of one worker per core")
    p.add_argument("--out", type=Path, default=Path("sweep-out"), metavar="DIR",
                   help="output folder (default: sweep-out)")
    p.add_argument("--resume", action="store_true",
                   help="finish an interrupted sweep in DIR: keep its complete parts")
    p.add_argument("--max-memory", type=float, default=None, metavar="GIB",
                   help="refuse a spec whose design, table or batch would need more memory than "
                        "this (default 2 GiB); the estimate is shown before the sweep starts")
    p.set_defaults(func=run)


def run(args) -> int:
    import math

    from rich.console import Console

    from verticality.core.errors import InputError
    from verticality.sweep import distribute, spec

    limit = None
    if args.max_memory is not None:
        if not (math.isfinite(args.max_memory) and args.max_memory > 0):
            raise InputError(f"--max-memory must be a positive number of GiB (got "
                             f"{args.max_memory})")
        limit = args.max_memory * 2**30
    sp = spec.read(args.spec, limit)
    k = sp.kernel_value
    size = spec.size(k, sp.design, sp.knobs, sp.n_draws, len(sp.seeds), sp.batch,
                     sp.runs_per_task, str(args.spec), limit)
    print(f"{args.spec}: {size.line()}")  # the estimate first (stdout: a refusal stays one line)
    s = distribute.run(sp, args.out, scheduler=args.scheduler, workers=args.workers,
                       resume=args.resume, limit_bytes=limit)
    Console().print(f"{s.n_runs} runs in {s.n_tasks} tasks ({len(s.computed_tasks)} computed now, "
                    f"{s.wall_s:.1f} s), {s.n_diverged} diverged → {s.results}")
    return 0
