"""The ``verticality`` command. Subcommands live in :mod:`verticality.commands`, one module each,
each with ``register(subparsers)``; this module only assembles them and turns user errors into one
line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from verticality import commands
from verticality.errors import InputError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="verticality",
        description="Estimate the gravitational vertical the way a vestibular system does.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for mod in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{commands.__name__}.{mod.name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"verticality {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
