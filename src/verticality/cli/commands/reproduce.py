"""``verticality reproduce [NAME...] [--json] [--out DIR] [--quick] [--no-report] [--jobs N]``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import Progress, ProgressColumn, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table
from rich.text import Text

from verticality.cli.commands import print_table
from verticality.core.errors import InputError
from verticality.report.pool import default_jobs
from verticality.report.progress import Tracker, duration_text
from verticality.report.runs import flatten, format_value

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
    p.add_argument("--jobs", default=None, metavar="N",
                   help="experiments run at once, each in its own worker process (default: one "
                        f"per core as memory allows, here {default_jobs()}); 1 runs them one after "
                        "the other in this process")
    p.set_defaults(func=run)


def parse_jobs(text: str | None) -> int:
    """``--jobs``: a whole number ≥ 1 (default :func:`~verticality.report.pool.default_jobs`)."""
    if text is None:
        return default_jobs()
    try:
        jobs = int(text)
    except ValueError:
        raise InputError(f"--jobs must be a whole number of processes, at least 1 (got {text!r})"
                         ) from None
    if jobs < 1:
        raise InputError(f"--jobs must be at least 1 (got {jobs})")
    return jobs


def run(args) -> int:
    from verticality import report
    from verticality.io.paths import check_output_folder
    from verticality.report.runs import (
        chosen_names,
        earlier_results,
        failed_checks,
        run_experiments,
    )

    out_dir = args.out if args.out is not None else (None if args.json else DEFAULT_OUT)
    if out_dir is not None:
        check_output_folder(out_dir, "--out")
        earlier_results(out_dir, args.quick)  # merged into at the end: refused now if it cannot be
    jobs = parse_jobs(args.jobs)
    err = Console(stderr=True)
    tracker = Tracker(chosen_names(args.names), quick=args.quick, jobs=jobs, out_dir=out_dir)
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), _TimeLeftColumn(tracker),
                  TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        overall = progress.add_task("", total=None)
        tasks: dict[str, object] = {}

        def on_stage(name: str, stage: str) -> None:
            tracker.stage(name, stage)
            progress.update(overall, description=tracker.headline())
            if stage == "done":
                progress.remove_task(tasks.pop(name))
                if not err.is_terminal:  # one plain line: never wrapped or cut when piped
                    print(tracker.done_line(name), file=sys.stderr, flush=True)
            elif name in tasks:
                progress.update(tasks[name], description=f"  {name}: {stage}")
            else:
                tasks[name] = progress.add_task(f"  {name}: {stage}", total=None)

        progress.update(overall, description=tracker.headline())
        results = run_experiments(args.names, quick=args.quick, out_dir=out_dir,
                                  on_stage=on_stage, jobs=jobs)
    page = None
    if out_dir is not None and not args.no_report:
        page = report.build(out_dir, warn=lambda line: print(f"warning: {line}",
                                                              file=sys.stderr))
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
        print_table(table, console)
    if out_dir is not None:
        console.print(f"figures and results.json written under {out_dir}/")


class _TimeLeftColumn(ProgressColumn):
    """The estimated time left, on the overall line only."""

    def __init__(self, tracker: Tracker):
        super().__init__()
        self.tracker = tracker

    def render(self, task) -> Text:
        if task.description.startswith("reproduce:"):
            return Text(f"about {duration_text(self.tracker.time_left())} left", style="cyan")
        return Text("")
