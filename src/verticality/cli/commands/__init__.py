"""CLI subcommands, one module each; each defines ``register(subparsers)``. The helpers they share:
their engine options, and their tables, printed whole whatever the width (a name or a number
copied from them is the one the program holds; ``--json`` gives the same as data)."""


def add_engine_arguments(p, what: str, default: str) -> None:
    """``--workers N`` and ``--scheduler ADDRESS`` of a command that runs ``what`` (e.g. "one
    task per trial") on the Dask engine (``verticality.sweep.engine``); ``default`` says what
    happens without either."""
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"{what} on a local Dask cluster of N worker processes (default: "
                        f"{default})")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help=f"{what} on a running Dask scheduler")


def print_table(table, console=None) -> None:
    """Print ``table`` (rich) without losing a character of a cell. Piped or redirected (not a
    terminal): at the width the table needs, one line per row, whatever ``COLUMNS`` says. At a
    terminal: at its width; columns made ``no_wrap`` (names, numbers) keep their whole width when
    the terminal can hold them beside the others, whose cells wrap; where it cannot, every cell
    wraps, a word longer than its column (a name, a number) folded onto the next line, rather than
    cropped or ended with "…" as rich does to a cell it may not wrap."""
    from rich.console import Console

    console = console if console is not None else Console()
    wide = console.options.update_width(1_000_000)  # measured unbounded
    for column in table.columns:
        column.overflow = "fold"
    if not console.is_terminal:
        console.width = max(console.width, console.measure(table, options=wide).maximum)
    else:
        kept = sum(max(console.measure(c, options=wide).maximum for c in (column.header,
                                                                          *column.cells))
                   for column in table.columns if column.no_wrap)
        # each column's padding and rule (3), the outer rule, and 4 for a wrapped column
        wrapped = sum(4 for column in table.columns if not column.no_wrap)
        if kept + wrapped + 3 * len(table.columns) + 1 > console.width:
            for column in table.columns:
                column.no_wrap = False
    console.print(table)
