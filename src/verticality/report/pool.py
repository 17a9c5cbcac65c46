"""Experiments of ``verticality reproduce`` run in worker processes, several at once.

:func:`run_pool` starts ``jobs`` worker processes (``spawn``: a fresh interpreter each, as JAX
wants, no forked copy of its threads) that take the experiments from one queue, longest expected
first (:mod:`verticality.report.costs`), run each with the same function as the in-process path
(:func:`verticality.report.entries.run_one`, figures included) and send its entry back. The workers
load and store compiled kernels in this process's JAX persistent compilation cache, so that a
function one of them compiled is loaded by the others and by the next run; within a worker,
experiments that share a compiled function (the ekf-* closed loops, keyed on their static settings)
reuse it from memory. Ctrl-C ends the workers (they ignore the interrupt themselves, so that only
this process reports it).
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import signal
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from verticality.report import costs as experiment_costs

_POLL_S = 0.5  # how often the waiting process looks at its workers when no message comes
# Memory set aside per worker for the default number of workers: a worker holds one experiment at
# a time, and the largest of a full run's two peaked at 2.9 GB of RSS (docs/reproduction.md).
WORKER_MEMORY_BYTES = 4 * 2**30


def _available_memory_bytes() -> int | None:
    """The memory the kernel says new processes can use (Linux's MemAvailable), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def default_jobs() -> int:
    """One worker per core this process may use, no more than the available memory holds at
    :data:`WORKER_MEMORY_BYTES` each (at least one)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        cores = os.cpu_count() or 1
    memory = _available_memory_bytes()
    if memory is not None:
        cores = min(cores, memory // WORKER_MEMORY_BYTES)
    return max(int(cores), 1)


class WorkerFailed(RuntimeError):
    """An experiment raised in its worker, or a worker process ended while it ran one."""


def _compile_cache_settings() -> tuple[str | None, float]:
    import jax

    return (jax.config.jax_compilation_cache_dir,
            float(jax.config.jax_persistent_cache_min_compile_time_secs))


def _worker(inbox, outbox, quick: bool, out_dir: str | None, cache_dir: str | None,
            min_compile_s: float) -> None:
    """A worker process: run the experiments named on ``inbox`` until ``None``, telling
    ``outbox`` ``(stage, name, pid, payload)`` for each stage, its entry when done, or the
    traceback of its error."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _end_with_parent()
    import jax

    from verticality import experiments
    from verticality.report.entries import run_one

    if cache_dir:
        jax.config.update("jax_compilation_cache_dir", cache_dir)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", min_compile_s)
    pid = os.getpid()
    folder = Path(out_dir) if out_dir is not None else None
    while (name := inbox.get()) is not None:
        try:
            entry = run_one(experiments.get(name), quick=quick, out_dir=folder,
                            on_stage=lambda n, stage: outbox.put((stage, n, pid, None)))
            outbox.put(("done", name, pid, entry))
        except BaseException:  # noqa: BLE001 (reported by the parent, which stops the run)
            outbox.put(("error", name, pid, traceback.format_exc()))
            return


def _end_with_parent() -> None:
    """End this worker as soon as the process that started it ends (killed, not only
    interrupted), rather than finish its experiment for no one and wait on the queue for ever."""
    parent = multiprocessing.parent_process()
    if parent is None:
        return

    def watch():
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="watch-parent").start()


def run_pool(names: list[str], *, quick: bool, out_dir: Path | None, jobs: int,
             on_stage: Callable[[str, str], None] | None = None) -> dict[str, dict]:
    """``{name: entry}`` of every experiment of ``names``, run in ``jobs`` worker processes
    (fewer when there are fewer experiments), longest expected first; ``on_stage(name, stage)``
    as in :func:`verticality.report.runs.run_experiments`. An experiment that raises stops the run
    with :class:`WorkerFailed` carrying its traceback."""
    expected = experiment_costs.expected_wall_s(names, quick, out_dir)
    order = experiment_costs.longest_first(expected)
    n_workers = max(1, min(jobs, len(order)))
    ctx = multiprocessing.get_context("spawn")
    inbox, outbox = ctx.Queue(), ctx.Queue()
    for name in order:
        inbox.put(name)
    for _ in range(n_workers):
        inbox.put(None)
    cache_dir, min_compile_s = _compile_cache_settings()
    args = (inbox, outbox, quick, None if out_dir is None else str(out_dir), cache_dir,
            min_compile_s)
    workers = [ctx.Process(target=_worker, args=args, daemon=True, name=f"verticality-{i}")
               for i in range(n_workers)]
    _start_ignoring_interrupts(workers)
    entries: dict[str, dict] = {}
    running: dict[int, str] = {}  # worker pid: the experiment it runs
    try:
        while len(entries) < len(order):
            try:
                stage, name, pid, payload = outbox.get(timeout=_POLL_S)
            except queue.Empty:
                _check_alive(workers, running)
                continue
            if stage == "error":
                raise WorkerFailed(f"experiment {name} failed in its worker process:\n{payload}")
            if stage == "done":
                entries[name] = payload
                running.pop(pid, None)
            else:
                running[pid] = name
            if on_stage is not None:
                on_stage(name, stage)
    finally:
        _stop(workers, inbox, outbox, finished=len(entries) == len(order))
    return entries


def _start_ignoring_interrupts(workers) -> None:
    """Start the workers with SIGINT ignored from their first instruction (an ignored signal
    stays ignored in the new interpreter), so that a Ctrl-C while they import prints nothing."""
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if in_main else None
    try:
        for w in workers:
            w.start()
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)


def _check_alive(workers, running: dict[int, str]) -> None:
    for w in workers:
        if w.exitcode not in (None, 0):
            what = running.get(w.pid)
            during = f" while running {what}" if what else ""
            raise WorkerFailed(f"a worker process ended with status {w.exitcode}{during} "
                               "(out of memory?)")


def _stop(workers, inbox, outbox, finished: bool) -> None:
    """End the workers: after the last experiment they are leaving (given a moment); after an
    error or Ctrl-C they are terminated at once. The queues are closed without waiting for what
    no one will read."""
    deadline = time.monotonic() + (5.0 if finished else 0.0)
    for w in workers:
        w.join(timeout=max(deadline - time.monotonic(), 0.0))
    for w in workers:
        if w.is_alive():
            w.terminate()
    for w in workers:
        w.join()
    for q in (inbox, outbox):
        q.cancel_join_thread()
        q.close()
