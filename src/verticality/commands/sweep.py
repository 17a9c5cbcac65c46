"""``verticality sweep SPEC.toml [--scheduler ADDRESS] [--workers N] [--out DIR] [--resume]``: run a
parameter sweep on Dask and write ``DIR/results.parquet`` (docs/sweep.md)."""

from __future__ import annotations

from pathlib import Path

from verticality.commands import add_engine_arguments


def register(sub):
    p = sub.add_parser("sweep", help="run a parameter sweep (Dask) into a Parquet table")
    p.add_argument("spec", type=Path, metavar="SPEC.toml", help="the sweep's specification")
    add_engine_arguments(p, "the sweep's tasks", "a local cluster of one worker per core")
    p.add_argument("--out", type=Path, default=Path("sweep-out"), metavar="DIR",
                   help="output folder (default: sweep-out)")
    p.add_argument("--resume", action="store_true",
                   help="finish an interrupted sweep in DIR: keep its complete parts")
    p.set_defaults(func=run)


def run(args) -> int:
    from rich.console import Console

    from verticality.sweep import distribute, spec

    s = distribute.run(spec.read(args.spec), args.out, scheduler=args.scheduler,
                       workers=args.workers, resume=args.resume)
    Console().print(f"{s.n_runs} runs in {s.n_tasks} tasks ({len(s.computed_tasks)} computed now, "
                    f"{s.wall_s:.1f} s), {s.n_diverged} diverged → {s.results}")
    return 0
