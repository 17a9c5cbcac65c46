"""``verticality report [RESULTS_DIR] [--out FILE.html]``: the reproduction report, rebuilt from a
results folder without running anything."""

from __future__ import annotations

from pathlib import Path

from verticality.cli.commands.reproduce import DEFAULT_OUT


def register(sub):
    p = sub.add_parser(
        "report",
        help="build the HTML reproduction report from a results folder of `reproduce`",
    )
    p.add_argument("results_dir", nargs="?", type=Path, default=DEFAULT_OUT, metavar="RESULTS_DIR",
                   help=f"folder with results.json and the figures (default {DEFAULT_OUT}/)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.html",
                   help="where to write the page (default RESULTS_DIR/report.html)")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from verticality import report
    from verticality.io.paths import check_written

    page = report.build(args.results_dir, args.out,
                        warn=lambda line: print(f"warning: {line}", file=sys.stderr))
    print(check_written(page))
    return 0
