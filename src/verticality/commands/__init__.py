"""CLI subcommands, one module each; each defines ``register(subparsers)``."""


def add_engine_arguments(p, what: str, default: str) -> None:
    """``--workers N`` and ``--scheduler ADDRESS`` of a command that runs ``what`` (e.g. "one
    task per trial") on the Dask engine (``verticality.sweep.engine``); ``default`` says what
    happens without either."""
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"{what} on a local Dask cluster of N worker processes (default: "
                        f"{default})")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help=f"{what} on a running Dask scheduler")
