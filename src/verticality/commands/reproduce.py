"""``verticality reproduce [NAME...] [--json] [--out DIR] [--quick] [--no-report]``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from verticality.reporting import flatten, format_value

DEFAULT_OUT = Path("verticality-results")


def register(sub):
    p = sub.add_parser(
        "reproduce",
        help="run the reproduced experiments of the seed papers (all when no NAME is given)",
    )
    p.add_argument("names", nargs="*", metavar="NAME", help="experiments to run (see `list`)")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    p.add_argument("--out", type=Path, default=None,
                   help=f"folder for figures, results.json and report.html (default {DEFAULT_OUT}/ "
                        "without --json; none with --json unless given)")
    p.add_argument("--quick", action="store_true",
                   help="shorter runs (fewer Monte Carlo repetitions, shorter simulations)")
    p.add_argument("--no-report", action="store_true",
                   help="do not write report.html beside results.json")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality import report
    from verticality.io.paths import check_output_folder
    from verticality.reporting import earlier_results, failed_checks, run_experiments

    out_dir = args.out if args.out is not None else (None if args.json else DEFAULT_OUT)
    if out_dir is not None:
        check_output_folder(out_dir, "--out")
        earlier_results(out_dir, args.quick)  # merged into at the end: refused now if it cannot be
    err = Console(stderr=True)
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True, disable=not err.is_terminal) as progress:
        tasks: dict[str, object] = {}

        def on_stage(name: str, stage: str) -> None:
            for task in tasks.values():
                progress.remove_task(task)
            tasks.clear()
            tasks[name] = progress.add_task(f"{name}: {stage}", total=None)
            if stage == "running" and not err.is_terminal and not args.json:
                err.print(f"running {name} …")

        results = run_experiments(args.names, quick=args.quick, out_dir=out_dir,
                                  on_stage=on_stage)
    page = None
    if out_dir is not None and not args.no_report:
        page = report.build(out_dir)
    if args.json:
        json.dump(results, sys.stdout, indent=2)
        sys.stdout.write("\n")
        if page is not None:
            print(f"report: {page}", file=sys.stderr)
    else:
        _print_tables(results, out_dir)
        if page is not None:
            print(f"report: {page}")  # one line, never wrapped
    failed = failed_checks(results)
    if failed:
        err.print("[red]failed checks:[/red] " + "; ".join(failed))
        return 1
    return 0


def _print_tables(results: dict, out_dir: Path | None) -> None:
    console = Console()
    for name, entry in results["experiments"].items():
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
