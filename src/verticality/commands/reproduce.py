"""``verticality reproduce [NAME...] [--json] [--out DIR] [--quick]``."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from verticality.reporting import flatten, format_value, to_jsonable

DEFAULT_OUT = Path("verticality-results")


def register(sub):
    p = sub.add_parser(
        "reproduce",
        help="run the reproduced experiments of the seed papers (all when no NAME is given)",
    )
    p.add_argument("names", nargs="*", metavar="NAME", help="experiments to run (see `list`)")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    p.add_argument("--out", type=Path, default=None,
                   help=f"folder for figures and results.json (default {DEFAULT_OUT}/ "
                        "without --json; none with --json unless given)")
    p.add_argument("--quick", action="store_true",
                   help="shorter runs (fewer Monte Carlo repetitions, shorter simulations)")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality import experiments

    registry = experiments.discover()
    names = args.names or sorted(registry)
    exps = [experiments.get(n) for n in names]  # raises InputError on an unknown name
    out_dir = args.out if args.out is not None else (None if args.json else DEFAULT_OUT)
    err = Console(stderr=True)
    report: dict = {"experiments": {}}
    failed_checks: list[str] = []
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True, disable=not err.is_terminal) as progress:
        for exp in exps:
            task = progress.add_task(f"{exp.name}: running", total=None)
            if not err.is_terminal and not args.json:
                err.print(f"running {exp.name} …")
            t0 = time.perf_counter()
            result = exp.run(quick=args.quick)
            wall = time.perf_counter() - t0
            entry = {
                "metrics": to_jsonable(result.metrics),
                "paper": to_jsonable(result.paper),
                "runtime": {"wall_s": wall, "simulated_s": float(result.simulated_s)},
            }
            if out_dir is not None and exp.figures is not None:
                progress.update(task, description=f"{exp.name}: figures")
                fig_dir = out_dir / exp.name
                fig_dir.mkdir(parents=True, exist_ok=True)
                entry["figures"] = [str(p) for p in exp.figures(result, fig_dir)]
            report["experiments"][exp.name] = entry
            for key, value in flatten(entry["metrics"]).items():
                if isinstance(value, dict) and value.get("pass") is False:
                    failed_checks.append(f"{exp.name}: {key}")
            progress.remove_task(task)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "results.json").write_text(json.dumps(report, indent=2))
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        _print_tables(report, out_dir)
    if failed_checks:
        err.print("[red]failed checks:[/red] " + "; ".join(failed_checks))
        return 1
    return 0


def _print_tables(report: dict, out_dir: Path | None) -> None:
    console = Console()
    for name, entry in report["experiments"].items():
        table = Table(title=f"{name}  ({entry['runtime']['wall_s']:.1f} s wall, "
                            f"{entry['runtime']['simulated_s']:.1f} s simulated)")
        table.add_column("metric", overflow="fold")
        table.add_column("ours", justify="right")
        table.add_column("published", justify="right")
        paper = flatten(entry["paper"])
        for key, value in flatten(entry["metrics"]).items():
            table.add_row(key, format_value(value), format_value(paper.get(key, "")))
        console.print(table)
    if out_dir is not None:
        console.print(f"figures and results.json written under {out_dir}/")
