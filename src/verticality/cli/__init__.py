"""The ``verticality`` command. Subcommands live in :mod:`verticality.cli.commands`, one module
each, each with ``register(subparsers)``; this module only assembles them and turns user errors into
one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from pathlib import Path

from verticality.cli import commands
from verticality.core.errors import InputError


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


def compile_cache_dir() -> Path | None:
    """Where the command keeps JAX's persistent compilation cache: ``$VERTICALITY_JAX_CACHE``
    (``off`` for none), else ``$XDG_CACHE_HOME/verticality/jax`` (``~/.cache/...``); None when
    turned off or when ``JAX_COMPILATION_CACHE_DIR`` already tells JAX."""
    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return None
    setting = os.environ.get("VERTICALITY_JAX_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false"):
        return None
    if setting:
        return Path(setting).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "verticality" / "jax"


def _enable_compile_cache() -> None:
    """Keep the compiled kernels between runs (JAX's persistent cache), so that a second call
    of a command does not compile them again (`estimate` on a 37 556-sample file: 9.7 s the
    first time, 4.2 s after)."""
    path = compile_cache_dir()
    if path is None:
        return
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return  # an unwritable cache folder costs only the compile time
    import jax

    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def main(argv: list[str] | None = None) -> int:
    """The command: its status (0 done, 1 done with failed checks or recordings, 2 refused, 130
    interrupted). Ctrl-C anywhere, also while a cluster is being closed, is one line."""
    command = "verticality"
    restore = _escape_unprintable()
    try:
        _enable_compile_cache()
        args = build_parser().parse_args(argv)
        command = f"verticality {args.command}"
        return _run(args)
    except KeyboardInterrupt:
        return _interrupted(command)
    finally:
        restore()


def _escape_unprintable():
    """Print what the output's encoding cannot hold (a file name that is not valid in the locale,
    whose undecodable bytes Python keeps as escapes) with backslash escapes instead of failing
    after the work is done; returns the function that restores the streams' setting."""
    old = []
    for stream in (sys.stdout, sys.stderr):
        errors = getattr(stream, "errors", None)
        if errors in (None, "backslashreplace") or not hasattr(stream, "reconfigure"):
            continue
        try:
            stream.reconfigure(errors="backslashreplace")
        except (AttributeError, ValueError, OSError):
            continue
        old.append((stream, errors))

    def restore():
        for stream, errors in old:
            try:
                stream.reconfigure(errors=errors)
            except (AttributeError, ValueError, OSError):
                pass
    return restore


def _interrupted(command: str) -> int:
    print(f"{command}: interrupted", file=sys.stderr)
    return 130


def _run(args) -> int:
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"verticality {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except UnicodeDecodeError as exc:  # a binary or non-UTF-8 file where text was expected
        print(f"verticality {args.command}: error: the input is not UTF-8 text ({exc.reason} at "
              f"byte {exc.start}); expected a CSV file", file=sys.stderr)
        return 2
    except OSError as exc:  # a file that could not be read or written, as one line
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"verticality {args.command}: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
