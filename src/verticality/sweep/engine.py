"""The Dask engine shared by the sweeps and the folders of recordings: run one function over many
argument tuples as one task each, on a ``LocalCluster`` of worker processes (one thread each) or a
running scheduler, with a progress bar of tasks done and time left on standard error; write a
result file under a temporary name and rename it when complete, so that a file that exists is
finished (:func:`verticality.io.paths.write_atomic`).

:func:`map_tasks` without a scheduler and without a worker count runs the tasks one after the
other in this process (no Dask needed): the same function, the same results.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from contextlib import contextmanager

from verticality.core.errors import InputError
from verticality.io.paths import write_atomic  # noqa: F401 (the one atomic writer, used here)

INSTALL_HINT = "pip install 'verticality[sweep]'"


def require_engine() -> None:
    """Raise one :class:`InputError` line if Dask's ``distributed`` or ``pyarrow`` (the optional
    extra ``sweep``) is not installed."""
    import importlib

    missing = []
    for module in ("distributed", "pyarrow.parquet"):
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(module.split(".")[0])
    if missing:
        raise InputError(f"this needs {' and '.join(missing)} (the optional extra 'sweep'): "
                         f"{INSTALL_HINT}")


def check_workers(workers: int | None) -> None:
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be at least 1 (got {workers})")


def use_compile_cache(cache: str | None) -> None:
    """Point this (worker) process's JAX at the persistent compilation cache ``cache``, so that it
    loads a kernel compiled once instead of compiling it again."""
    if not cache:
        return
    import jax

    if jax.config.jax_compilation_cache_dir != cache:
        jax.config.update("jax_compilation_cache_dir", cache)


@contextmanager
def workers_ignore_interrupt():
    """Start worker processes inside this block with Ctrl-C (SIGINT) ignored: a terminal's Ctrl-C
    reaches every process of its group, and a worker that took it would print its own traceback;
    this process alone answers it (one line, exit status 130) and closes the cluster. A process
    started with SIGINT ignored keeps it ignored (Python installs its KeyboardInterrupt handler
    only over the default)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers belong to the main thread; nothing to change here
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


CONNECT_TIMEOUT_S = 20.0  # a scheduler that does not answer within this is refused


def check_scheduler_address(scheduler: str) -> str:
    """``scheduler`` as Dask's ``PROTOCOL://HOST:PORT`` (``HOST:PORT`` is TCP), checked before
    anything is written or connected: a missing or non-numeric port, a port outside 1–65535, an
    empty host and an unknown protocol are refused in one line."""
    from distributed.comm import registry
    from distributed.comm.addressing import parse_address, parse_host_port

    text = str(scheduler).strip()
    hint = "give PROTOCOL://HOST:PORT or HOST:PORT, e.g. tcp://127.0.0.1:8786"
    try:
        protocol, location = parse_address(text if "://" in text else f"tcp://{text}")
    except ValueError as exc:
        raise InputError(f"--scheduler {scheduler!r}: not an address ({exc}); {hint}") from None
    try:
        registry.get_backend(protocol)
    except ValueError:
        raise InputError(f"--scheduler {scheduler!r}: unknown protocol {protocol!r}; {hint}"
                         ) from None
    if protocol in ("tcp", "tls", "ws", "wss"):
        try:
            host, port = parse_host_port(location)
        except ValueError as exc:
            why = (f"port {location.rsplit(':', 1)[-1]!r} is not a number"
                   if "invalid literal" in str(exc) else str(exc))
            raise InputError(f"--scheduler {scheduler!r}: {why}; {hint}") from None
        if not host:
            raise InputError(f"--scheduler {scheduler!r}: no host; {hint}")
        if not 0 < int(port) < 65536:
            raise InputError(f"--scheduler {scheduler!r}: port {port} is not 1–65535; {hint}")
    return f"{protocol}://{location}"


def check_scheduler(scheduler: str, timeout_s: float | None = None) -> str:
    """The address of a running Dask scheduler that answers: :func:`check_scheduler_address`,
    then its identity asked within ``timeout_s`` (default :data:`CONNECT_TIMEOUT_S`); nothing
    listening there, a server that accepts and never answers and one that is not a scheduler are
    refused in one line, before any work."""
    import asyncio

    from distributed.core import rpc

    address = check_scheduler_address(scheduler)
    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    if address.startswith("tcp://"):  # nothing listening: said at once (Dask would retry)
        import socket

        from distributed.comm.addressing import parse_host_port

        host, port = parse_host_port(address.removeprefix("tcp://"))
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
        except OSError as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect "
                             f"({exc.strerror or type(exc).__name__})") from None

    async def identity():
        r = rpc(address)
        try:
            return await r.identity()
        finally:
            await r.close_rpc()

    try:
        ident = asyncio.run(asyncio.wait_for(identity(), timeout_s))
    except TimeoutError:
        raise InputError(f"--scheduler {scheduler}: no answer within {timeout_s:g} s (nothing "
                         "listening there, or not a Dask scheduler)") from None
    except (OSError, ValueError, TypeError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot reach it "
                         f"({' '.join(str(exc).split())[:120] or type(exc).__name__})") from None
    if not isinstance(ident, dict) or ident.get("type") != "Scheduler":
        kind = ident.get("type") if isinstance(ident, dict) else type(ident).__name__
        raise InputError(f"--scheduler {scheduler}: answers as {kind}, not as a Dask scheduler")
    return address


@contextmanager
def connect(scheduler: str | None, n_workers: int):
    """A ``distributed.Client`` of the running scheduler at ``scheduler`` (checked first: it
    must answer within :data:`CONNECT_TIMEOUT_S`, :func:`check_scheduler`) or of a new
    ``LocalCluster`` of ``n_workers`` worker processes (closed on exit)."""
    from distributed import Client, LocalCluster

    if scheduler:
        address = check_scheduler(scheduler)
        try:
            client = Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s")
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        cluster = None
    else:
        import dask

        # the workers log only errors: a task's failure reaches this process as its exception,
        # and the cancelled tasks of an interrupted run are not news
        spawn_env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
        spawn_env["DASK_LOGGING__DISTRIBUTED"] = "error"
        with workers_ignore_interrupt(), dask.config.set(
                {"distributed.nanny.pre-spawn-environ": spawn_env}):
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0")  # any free port: no clash warning
        client = Client(cluster)
    import logging

    log = logging.getLogger("distributed")
    level = log.level
    try:
        yield client
    except KeyboardInterrupt:
        log.setLevel(logging.CRITICAL)  # closing an interrupted cluster: the one line is ours
        raise
    finally:
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        finally:
            log.setLevel(level)


@contextmanager
def progress_bar(description: str, total: int, enabled: bool = True):
    """A rich progress bar on standard error (tasks done, elapsed, time left); yields the
    function that advances it by one task."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("tasks"), TimeElapsedColumn(), TextColumn("left"),
               TimeRemainingColumn())
    with Progress(*columns, disable=not enabled, transient=False,
                  console=Console(stderr=True)) as bar:
        task = bar.add_task(description, total=total)
        yield lambda: bar.advance(task)


def map_tasks(fn: Callable, calls: Mapping[str, tuple], *, scheduler: str | None = None,
              workers: int | None = None, progress: bool = True, description: str = "tasks",
              on_error: Callable[[str, BaseException], object] | None = None) -> dict[str, object]:
    """``{key: fn(*args)}`` for every ``key: args`` of ``calls``, one task each: on the Dask
    scheduler at ``scheduler``, or on a ``LocalCluster`` of ``workers`` processes, or (neither
    given) one after the other in this process. A task's exception is raised here, or with
    ``on_error`` its result is ``on_error(key, exception)`` (e.g. a worker lost while it ran the
    task) and the other tasks go on. ``fn`` must be importable by the workers (a module-level
    function)."""
    check_workers(workers)
    results: dict[str, object] = {}

    def settle(key, get):  # the task's result, or its error's fate
        try:
            results[key] = get()
        except Exception as exc:
            if on_error is None:
                raise
            results[key] = on_error(key, exc)

    if not scheduler and workers is None:
        with progress_bar(description, len(calls), progress) as advance:
            for key, args in calls.items():
                settle(key, lambda args=args: fn(*args))
                advance()
        return results
    require_engine()
    from distributed import as_completed

    with connect(scheduler, workers or 1) as client:
        futures = {client.submit(fn, *args, pure=False, key=key): key
                   for key, args in calls.items()}
        with progress_bar(description, len(futures), progress) as advance:
            for fut in as_completed(list(futures)):
                settle(futures[fut], fut.result)  # a task's error is raised by result()
                advance()
    return {key: results[key] for key in calls}
