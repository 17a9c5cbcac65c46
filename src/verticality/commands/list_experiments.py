"""``verticality list``: the registered experiments."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table


def register(sub):
    p = sub.add_parser("list", help="list the reproducible experiments")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality import experiments

    table = Table(title="verticality experiments")
    table.add_column("name")
    table.add_column("source")
    table.add_column("what")
    for name, exp in sorted(experiments.discover().items()):
        table.add_row(name, exp.source, exp.title)
    Console().print(table)
    return 0
