"""``verticality list [--json]``: the registered experiments, their sources and what they show."""

from __future__ import annotations

import json
import sys


def register(sub):
    p = sub.add_parser("list", help="list the reproducible experiments")
    p.add_argument("--json", action="store_true",
                   help='print {"experiments": {NAME: {"source", "what"}}}')
    p.set_defaults(func=run)


def rows() -> dict[str, dict[str, str]]:
    """``{name: {"source", "what"}}`` of every experiment, by name."""
    from verticality import experiments

    return {name: {"source": exp.source, "what": exp.title}
            for name, exp in sorted(experiments.discover().items())}


def table(experiments: dict[str, dict[str, str]]):
    """The experiments as a rich table (printed by :func:`print_table`, which never cuts a name:
    they are typed into `reproduce`)."""
    from rich.table import Table

    t = Table(title="verticality experiments")
    t.add_column("name", no_wrap=True, style="bold")
    t.add_column("source")
    t.add_column("what")
    for name, row in experiments.items():
        t.add_row(name, row["source"], row["what"])
    return t


def run(args) -> int:
    from verticality.cli.commands import print_table

    experiments = rows()
    if args.json:
        json.dump({"experiments": experiments}, sys.stdout, indent=2, ensure_ascii=False)
        sys.stdout.write("\n")
        return 0
    print_table(table(experiments))
    return 0
