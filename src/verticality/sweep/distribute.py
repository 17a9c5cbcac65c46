"""Run a sweep's tasks on Dask and assemble the results table.

:func:`run` starts a ``LocalCluster`` of worker processes (one thread each) or connects to a
running scheduler, submits one task per slice of the design (:func:`run_task`), and shows a
progress bar with tasks done and the time left (:mod:`verticality.sweep.engine`, shared with the
folders of recordings). A task writes its Parquet part to
``OUT/parts/part-NNNNNN.parquet`` under a temporary name and renames it when complete, so a part
that exists is finished; ``resume`` keeps the finished parts and computes only the others. The
parts, in task order, make ``OUT/results.parquet`` (column ``run``, the knobs, ``seed``, what
the runs drew from their seeds (the kernel's ``drawn``), the metrics, ``diverged``);
``OUT/spec.toml`` is the spec as given and ``OUT/provenance.json`` says how the table was made.

A task computes its runs in vmap batches of the spec's ``batch`` runs, the last one padded (its
last run repeated, then dropped), so all tasks share one compiled batch shape and a run's numbers
do not depend on the task size or the worker.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep import spec as sweep_spec
from verticality.sweep.engine import (  # noqa: F401  (INSTALL_HINT: imported from here too)
    INSTALL_HINT,
    check_scheduler,
    check_workers,
    map_tasks,
    require_engine,
    use_compile_cache,
    write_atomic,
)
from verticality.sweep.registry import KERNELS

PART_DIGITS = 6


@dataclass(frozen=True)
class Summary:
    out_dir: Path
    n_runs: int
    n_tasks: int
    computed_tasks: tuple[int, ...]  # tasks run this time (the others were already complete)
    wall_s: float
    n_diverged: int

    @property
    def results(self) -> Path:
        return self.out_dir / "results.parquet"


def part_path(parts_dir: Path, task: int) -> Path:
    return Path(parts_dir) / f"part-{task:0{PART_DIGITS}d}.parquet"


def task_table(kernel_name: str, options: dict, design: sweep_spec.Design, first_run: int,
               batch: int):
    """The results of the runs of ``design`` (the first one is run ``first_run``, a multiple of
    ``batch``), computed in vmap batches of ``batch``, as a ``pyarrow.Table``."""
    import pyarrow as pa

    kernel = KERNELS[kernel_name]
    n = design.n_runs
    chunks = []
    for a in range(0, n, batch):
        rows = np.minimum(np.arange(a, a + batch), n - 1)  # the last batch repeats its last run
        chunks.append(kernel.run_batch({k: v[rows] for k, v in design.columns.items()},
                                       design.seeds[rows], **options))
    metrics = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    cols = {"run": pa.array(np.arange(first_run, first_run + n, dtype=np.int64))}
    cols |= {k: pa.array(v) for k, v in design.columns.items()}
    cols["seed"] = pa.array(design.seeds)
    cols |= {d: pa.array(np.asarray(metrics[d], dtype=np.float64)[:n]) for d in kernel.drawn}
    cols |= {m: pa.array(np.asarray(metrics[m], dtype=np.float64)[:n]) for m in kernel.metrics}
    cols["diverged"] = pa.array(np.asarray(metrics["diverged"], dtype=bool)[:n])
    return pa.table(cols)


# the manifest in a part's Parquet metadata: what it belongs to and what it holds
MANIFEST_KEYS = (b"verticality.spec", b"verticality.task", b"verticality.runs",
                 b"verticality.content")


def runs_digest(design: sweep_spec.Design, first_run: int) -> str:
    """SHA-256 of a task's runs: their ids, seeds and knob values."""
    import hashlib

    h = hashlib.sha256(np.arange(first_run, first_run + design.n_runs, dtype=np.int64).tobytes())
    h.update(np.asarray(design.seeds, dtype=np.int64).tobytes())
    for name in sorted(design.columns):
        h.update(name.encode())
        h.update(_column_bytes(design.columns[name]))
    return h.hexdigest()


def _column_bytes(values) -> bytes:
    a = np.asarray(values)
    if a.dtype.kind in "USO":
        return "\x1f".join(str(v) for v in a.tolist()).encode("utf-8")
    return np.ascontiguousarray(a).tobytes()


def content_digest(table) -> str:
    """SHA-256 of a part's cells (column names and values), not of its file's bytes."""
    import hashlib

    h = hashlib.sha256()
    for name in table.column_names:
        h.update(name.encode())
        h.update(_column_bytes(table.column(name).to_numpy(zero_copy_only=False)))
    return h.hexdigest()


def run_task(kernel_name: str, options: dict, design: sweep_spec.Design, task: int,
             first_run: int, batch: int, parts_dir: str, compile_cache: str | None = None,
             spec_digest: str = "") -> int:
    """Compute one task and write its part (temporary name, then an atomic rename), with its
    manifest in the Parquet metadata: the spec's digest, the task, the digest of its runs and of
    its cells. ``compile_cache``: JAX's persistent compilation cache for the worker, so that a
    worker process loads the kernel compiled once instead of compiling it again."""
    import pyarrow.parquet as pq

    use_compile_cache(compile_cache)
    table = task_table(kernel_name, options, design, first_run, batch)
    manifest = dict(zip(MANIFEST_KEYS, (spec_digest, str(task), runs_digest(design, first_run),
                                        content_digest(table)), strict=True))
    table = table.replace_schema_metadata({k: v.encode() for k, v in manifest.items()})
    write_atomic(part_path(Path(parts_dir), task), lambda tmp: pq.write_table(table, tmp))
    return task


def part_state(path: Path, spec_digest: str, task: int, runs: str) -> str:
    """What the part at ``path`` is for task ``task`` (whose runs have the digest ``runs``) of
    the spec with digest ``spec_digest``: ``"done"`` (its manifest names this spec, this task and
    these runs, and its cells are the ones it was written with), ``"redo"`` (missing, torn, or a
    part of this spec that is not this task's finished part: a copy of another, a damaged
    one), or ``"foreign"`` (readable, but written for another spec or without a manifest)."""
    import pyarrow.parquet as pq

    if not Path(path).is_file():
        return "redo"
    try:
        meta = pq.read_schema(path).metadata or {}
    except Exception:  # noqa: BLE001 (a torn or non-Parquet file: recomputed)
        return "redo"
    if meta.get(MANIFEST_KEYS[0], b"").decode(errors="replace") != spec_digest:
        return "foreign"
    if (meta.get(MANIFEST_KEYS[1]) != str(task).encode()
            or meta.get(MANIFEST_KEYS[2]) != runs.encode()):
        return "redo"
    try:
        table = pq.read_table(path)
    except Exception:  # noqa: BLE001
        return "redo"
    return "done" if content_digest(table).encode() == meta.get(MANIFEST_KEYS[3]) else "redo"


def table_columns(kernel, design: sweep_spec.Design) -> list[str]:
    """The columns of a task's table (:func:`task_table`), in order."""
    return (["run", *design.columns, "seed", *kernel.drawn, *kernel.metrics, "diverged"])


def check_part_columns(parts: Path, finished: list[int], expected: list[str], out_dir: Path):
    """Refuse to resume with finished parts whose columns are not ``expected`` (written by a
    version of the kernel with other knobs or metrics): the table would mix two layouts."""
    import pyarrow.parquet as pq

    for t in finished:
        names = pq.read_schema(part_path(parts, t)).names
        if names != expected:
            extra = [c for c in names if c not in expected]
            lacking = [c for c in expected if c not in names]
            raise InputError(
                f"{out_dir}: its finished part {t} has other columns than this version of the "
                f"kernel writes (without {', '.join(lacking) or '–'}; with "
                f"{', '.join(extra) or '–'}, or in another order); finish it with the version "
                "that started it, or run the spec into another --out")


def prepare(spec: sweep_spec.Spec, out_dir: Path, resume: bool,
            limit_bytes: float | None = None) -> Path:
    """Make ``out_dir`` and check it matches ``spec`` (resume) or holds no sweep yet."""
    from verticality.io.paths import check_output_folder, confined_folder

    out_dir = check_output_folder(out_dir, "--out")
    parts = out_dir / "parts"
    old_spec = out_dir / "spec.toml"
    if old_spec.exists():
        if not resume:
            raise InputError(f"{out_dir} already holds a sweep; use --resume to finish it or "
                             "another --out")
        old = sweep_spec.read(old_spec, limit_bytes)
        if replace(old, text="") != replace(spec, text=""):
            raise InputError(f"{out_dir} holds a sweep of another spec ({old_spec}); "
                             "cannot resume it with this one")
    confined_folder(out_dir, parts.name)  # (a link planted there would take the parts out)
    write_atomic(old_spec, lambda tmp: tmp.write_text(spec.text, encoding="utf-8"),
                 root=out_dir)
    return parts


def run(spec: sweep_spec.Spec, out_dir: Path, *, scheduler: str | None = None,
        workers: int | None = None, resume: bool = False, progress: bool = True,
        compile_cache: Path | str | None = None, limit_bytes: float | None = None) -> Summary:
    """Run the sweep ``spec`` into ``out_dir`` (see the module docstring). ``compile_cache``:
    JAX's persistent compilation cache folder for the workers (default: this process's, which
    the ``verticality`` command sets). A part already in ``out_dir/parts`` is kept only if its
    manifest proves it is this task's of this spec (:func:`part_state`); one of another spec is
    refused, one of this spec that is not what it claims is computed again."""
    require_engine()
    from verticality.io.paths import check_output_folder, folder_lock

    check_workers(workers)
    design = sweep_spec.design(spec)
    if scheduler:  # before anything is written: an address that is wrong or does not answer
        scheduler = check_scheduler(scheduler)
    with folder_lock(check_output_folder(out_dir, "--out")):  # one sweep at a time in a folder
        return _run(spec, design, Path(out_dir), scheduler, workers, resume, progress,
                    compile_cache, limit_bytes)


def _run(spec, design, out_dir, scheduler, workers, resume, progress, compile_cache,
         limit_bytes) -> Summary:
    """:func:`run` in its locked output folder."""
    import jax
    import pyarrow as pa
    import pyarrow.parquet as pq

    n_runs, size = design.n_runs, spec.runs_per_task
    n_tasks = sweep_spec.n_tasks(spec, n_runs)
    parts = prepare(spec, out_dir, resume, limit_bytes)
    bounds = [(t * size, min((t + 1) * size, n_runs)) for t in range(n_tasks)]
    digest = spec.digest
    states = [part_state(part_path(parts, t), digest, t, runs_digest(design.rows(a, b), a))
              for t, (a, b) in enumerate(bounds)]
    readable = [t for t, s in enumerate(states) if s != "redo"]
    check_part_columns(parts, readable, table_columns(spec.kernel_value, design), out_dir)
    if "foreign" in states:
        t = states.index("foreign")
        raise InputError(f"{out_dir}: {part_path(parts, t).name} was written for another spec "
                         "(or without a manifest); its results are not this sweep's: run the "
                         "spec into another --out, or remove that folder's parts")
    todo = [t for t, s in enumerate(states) if s != "done"]
    from verticality.report import provenance

    commit = provenance.git_commit()  # the code the tasks run, before they run
    start = time.perf_counter()
    n_workers = workers or min(os.cpu_count() or 1, max(len(todo), 1))
    if todo:
        own = jax.config.jax_compilation_cache_dir
        cache = compile_cache if compile_cache is not None else own
        if not scheduler and cache and str(cache) == str(own):
            # compile once here, into the cache the local workers load from (else every worker
            # process compiles the same kernel, ~10 s each on this machine's shared cores;
            # every compiled form the design's batches need)
            spec.kernel_value.compile_batch(spec.batch, design.columns, **spec.options)
        _compute(spec, design, bounds, todo, parts, scheduler, n_workers, progress,
                 str(cache) if cache else None)
    wall = time.perf_counter() - start
    table = pa.concat_tables([pq.read_table(part_path(parts, t)).replace_schema_metadata(None)
                              for t in range(n_tasks)])
    write_atomic(out_dir / "results.parquet", lambda tmp: pq.write_table(table, tmp),
                 root=out_dir)
    n_div = int(np.sum(table.column("diverged").to_numpy()))
    _write_provenance(out_dir, spec, n_runs, n_tasks, todo, wall, scheduler, n_workers, commit)
    return Summary(out_dir, n_runs, n_tasks, tuple(todo), wall, n_div)


def _compute(spec, design, bounds, todo, parts, scheduler, n_workers, progress, cache) -> None:
    calls = {f"sweep-task-{t}": (spec.kernel, spec.options, design.rows(*bounds[t]), t,
                                 bounds[t][0], spec.batch, str(parts), cache, spec.digest)
             for t in todo}
    map_tasks(run_task, calls, scheduler=scheduler, workers=n_workers, progress=progress,
              description=f"sweep {spec.kernel}")


def _write_provenance(out_dir, spec, n_runs, n_tasks, todo, wall, scheduler, n_workers,
                      commit) -> None:
    from verticality import __version__
    from verticality.report import provenance

    record = {
        "package": "verticality", "version": __version__, "git": commit,
        "kernel": spec.kernel, "options": spec.options, "runs": n_runs, "tasks": n_tasks,
        "runs_per_task": spec.runs_per_task, "batch": spec.batch, "tasks_computed": len(todo),
        "scheduler": scheduler or f"LocalCluster({n_workers} worker processes)",
        "wall_s": wall,
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "libraries": provenance.library_versions(provenance.LIBRARIES
                                                 + ("dask", "distributed", "pyarrow")),
        "jax_backend": provenance.jax_backend(), "machine": provenance.machine(),
    }
    write_atomic(out_dir / "provenance.json",
                 lambda tmp: tmp.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8"),
                 root=out_dir)
