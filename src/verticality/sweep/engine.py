"""The Dask engine shared by the sweeps and the folders of recordings: run one function over many
argument tuples as one task each, on a ``LocalCluster`` of worker processes (one thread each) or a
running scheduler, with a progress bar of tasks done and time left on standard error; write a
result file under a temporary name and rename it when complete, so that a file that exists is
finished.

:func:`map_tasks` without a scheduler and without a worker count runs the tasks one after the
other in this process (no Dask needed): the same function, the same results.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from pathlib import Path

from verticality.core.errors import InputError

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


def write_atomic(final: Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)`` to a temporary name beside ``final``, then rename it to ``final`` (atomic on
    one file system): ``final`` exists only complete."""
    final = Path(final)
    tmp = final.with_name(final.name + f".tmp-{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, final)
    finally:
        tmp.unlink(missing_ok=True)
    return final


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


@contextmanager
def connect(scheduler: str | None, n_workers: int):
    """A ``distributed.Client`` of the running scheduler at ``scheduler`` or of a new
    ``LocalCluster`` of ``n_workers`` worker processes (closed on exit)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
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
