"""A sweep's specification (TOML) and its design: the table of runs, each a point of the knobs and a
seed.

A spec names a kernel (:mod:`verticality.sweep.kernels`), the kernel's options, a design over the
kernel's knobs and the seeds::

    kernel = "newton-lissajous"
    batch = 32                   # runs computed together by one vmap (default 32)
    runs_per_task = 320          # runs in one task: a multiple of batch (default 2 × batch)

    [options]                    # the kernel's fixed settings
    duration_s = 10.0

    [design]
    kind = "grid"                # every combination of the knobs' values; or "random"
    # n = 100                    # random: draws of the knobs ...
    # seed = 0                   # ... from this generator seed

    [knobs]                      # grid: a list of values per knob; random: {min = , max = }
                                 # or a list
    head = ["fixed", "stabilized"]
    K_rel_error = [-0.2, 0.0, 0.2]

    [seeds]
    values = [0, 1]              # or: count = 200, first = 0

Knobs the spec leaves out take the kernel's default and are still columns of the table. The runs
are ordered design point by design point, the seeds innermost; a task is a fixed slice of that
order (run ``i`` is in task ``i // runs_per_task``), and every run carries its own seed. A task
computes its runs in vmap batches of ``batch`` runs aligned on the run index (the last one padded),
so a run is always computed at the same place of the same compiled batch: its numbers do not
depend on the task size or on which worker computes it (they can depend on ``batch``, in the last
bits: XLA may vectorize another batch shape differently).

``batch`` defaults to :data:`DEFAULT_BATCH`: batching pays only from a few tens of runs on
(``benchmarks/bench_sweep.py``: `newton-lissajous` 1.2× a serial loop in batches of 8, 2.1× in
batches of 32, 2.2× in batches of 64, one core), and a batch of 64 takes twice as long to compile.
"""

from __future__ import annotations

import itertools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep.kernels import Kernel
from verticality.sweep.registry import KERNELS

TOP_KEYS = ("kernel", "batch", "runs_per_task", "options", "design", "knobs", "seeds")
# the schema of the top level: each key's type (TOML's: a string, an integer, a table)
TOP_TYPES = {"kernel": (str, "a string"), "batch": (int, "an integer"),
             "runs_per_task": (int, "an integer"), "options": (dict, "a table"),
             "design": (dict, "a table"), "knobs": (dict, "a table"), "seeds": (dict, "a table")}
MAX_SEED = 2**31 - 1
DEFAULT_BATCH = 32
# Memory a run takes, for the size of a spec before its design is built (``sizing``): the
# design's building (a tuple per design point, a Python object per knob value) and the results
# table held twice (the parts and their concatenation), 8 bytes a cell.
DESIGN_RUN_BYTES = 128
DESIGN_KNOB_BYTES = 40
TABLE_CELL_BYTES = 16
# A run's working memory inside a vmap batch: a bound, not a measurement (the kernels keep a
# run's trajectory of up to 600 s at the observer's 25 ms, a few hundred kB); the batch is sized
# with it, since a batch is computed at once even for a shorter design (its last runs padded).
BATCH_RUN_BYTES = 2**20


@dataclass(frozen=True)
class Spec:
    """A validated sweep specification; ``text`` is the TOML it was read from."""

    kernel: str
    options: dict[str, Any]
    design: str  # "grid" | "random"
    knobs: dict[str, Any]  # as written: a list per knob, or {"min", "max"} (random)
    seeds: tuple[int, ...]
    runs_per_task: int
    batch: int = DEFAULT_BATCH
    n_draws: int = 0  # random design
    design_seed: int = 0
    text: str = ""

    @property
    def kernel_value(self) -> Kernel:
        return KERNELS[self.kernel]

    @property
    def n_runs(self) -> int:
        """The number of runs, without building the design."""
        return n_points(self.design, self.knobs, self.n_draws) * len(self.seeds)

    @property
    def digest(self) -> str:
        """SHA-256 of the validated spec (not of its text: comments and spacing do not count),
        carried by every part of its sweep so that a resume keeps only its own parts."""
        import hashlib
        import json

        fields = {"kernel": self.kernel, "options": self.options, "design": self.design,
                  "knobs": self.knobs, "seeds": list(self.seeds),
                  "runs_per_task": self.runs_per_task, "batch": self.batch,
                  "n_draws": self.n_draws, "design_seed": self.design_seed}
        text = json.dumps(fields, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class Size:
    """What a spec asks for, before anything is built: runs, tasks and memory (bytes)."""

    n_runs: int
    n_tasks: int
    table_bytes: float
    batch_bytes: float

    def line(self) -> str:
        return (f"{self.n_runs} runs in {self.n_tasks} tasks, ~{self.table_bytes / 2**20:.3g} MiB "
                f"for the design and table, ~{self.batch_bytes / 2**20:.3g} MiB per batch")


def n_points(kind: str, knobs: dict[str, Any], n_draws: int) -> int:
    """The design's points: a grid's product of the knobs' value counts, a random design's draws."""
    if kind == "random":
        return int(n_draws)
    return math.prod(len(v) for v in knobs.values())


def size(kernel: Kernel, kind: str, knobs: dict[str, Any], n_draws: int, n_seeds: int,
         batch: int, runs_per_task: int, source: str = "spec",
         limit_bytes: float | None = None) -> Size:
    """The size of a spec (:class:`Size`), refused (one :class:`InputError` line, the option to
    change named) above ``limit_bytes`` (default :data:`verticality.core.sizing.MAX_WORK_BYTES`)."""
    from verticality.core.sizing import check_work_size

    n_runs = n_points(kind, knobs, n_draws) * int(n_seeds)
    n_knobs = len(kernel.knobs)
    cells = n_knobs + 3 + len(kernel.drawn) + len(kernel.metrics)
    per_run = DESIGN_RUN_BYTES + DESIGN_KNOB_BYTES * n_knobs + TABLE_CELL_BYTES * cells
    advice = ("fewer seeds, knob values or draws (n), or a larger limit: --max-memory GIB")
    table = check_work_size(n_runs, per_run, f"runs in {source}", advice, limit_bytes)
    batch_bytes = check_work_size(batch, BATCH_RUN_BYTES, f"runs in one vmap batch ({source})",
                                  "a smaller batch, or a larger limit: --max-memory GIB",
                                  limit_bytes)
    return Size(n_runs, -(-n_runs // runs_per_task), table, batch_bytes)


@dataclass(frozen=True)
class Design:
    """The runs of a sweep, one row each: ``columns`` (every knob of the kernel) and ``seeds``."""

    columns: dict[str, np.ndarray]
    seeds: np.ndarray  # int64

    @property
    def n_runs(self) -> int:
        return int(self.seeds.shape[0])

    def rows(self, start: int, stop: int) -> Design:
        return Design({k: v[start:stop] for k, v in self.columns.items()}, self.seeds[start:stop])


def read(path: Path, limit_bytes: float | None = None) -> Spec:
    """Read and validate the spec at ``path`` (:class:`InputError` on any problem)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no sweep spec at {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); expected a "
                         "TOML sweep spec") from None
    return parse(text, source=str(path), limit_bytes=limit_bytes)


def parse(text: str, source: str = "spec", limit_bytes: float | None = None) -> Spec:
    """Validate the TOML ``text`` of a spec; every problem is one :class:`InputError` line. Its
    size (:func:`size`) is checked before the seeds or the design are built, against
    ``limit_bytes`` (default :data:`verticality.core.sizing.MAX_WORK_BYTES`)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not valid TOML ({exc})") from None
    unknown = sorted(set(raw) - set(TOP_KEYS))
    if unknown:
        raise InputError(f"{source}: unknown key(s) {', '.join(unknown)}; "
                         f"expected {', '.join(TOP_KEYS)}")
    for key, (kind_, what) in TOP_TYPES.items():
        value = raw.get(key)
        if value is not None and (not isinstance(value, kind_) or isinstance(value, bool)):
            raise InputError(f"{source}: {key} = {value!r} must be {what}")
    name = raw.get("kernel")
    if name not in KERNELS:
        raise InputError(f"{source}: kernel must be one of {', '.join(sorted(KERNELS))} "
                         f"(got {name!r})")
    kernel = KERNELS[name]
    batch = raw.get("batch", DEFAULT_BATCH)
    if not _is_int(batch) or batch < 1:
        raise InputError(f"{source}: batch must be a positive integer (got {batch!r})")
    runs_per_task = raw.get("runs_per_task", 2 * batch)
    if not _is_int(runs_per_task) or runs_per_task < 1 or runs_per_task % batch:
        raise InputError(f"{source}: runs_per_task must be a positive multiple of batch = {batch} "
                         f"(got {runs_per_task!r})")
    options = _options(kernel, raw.get("options", {}), source)
    design = raw.get("design", {})
    if not isinstance(design, dict):
        raise InputError(f"{source}: [design] must be a table")
    kind = design.get("kind", "grid")
    if not isinstance(kind, str):
        raise InputError(f"{source}: [design] kind = {kind!r} must be \"grid\" or \"random\"")
    extra = sorted(set(design) - {"kind", "n", "seed"})
    if kind not in ("grid", "random") or extra:
        raise InputError(f"{source}: [design] takes kind = \"grid\" or \"random\" "
                         "(with n and seed); "
                         f"got kind={kind!r}{' and ' + ', '.join(extra) if extra else ''}")
    n_draws, design_seed = 0, 0
    if kind == "random":
        n_draws, design_seed = design.get("n"), design.get("seed", 0)
        if not _is_int(n_draws) or n_draws < 1:
            raise InputError(f"{source}: a random design needs n, a positive integer "
                             f"(got {n_draws!r})")
        if not _is_int(design_seed) or not 0 <= design_seed <= MAX_SEED:
            raise InputError(f"{source}: [design] seed must be an integer in 0..{MAX_SEED}")
    elif "n" in design or "seed" in design:
        raise InputError(f"{source}: n and seed belong to a random design (kind = \"random\")")
    knobs = raw.get("knobs", {})
    if not isinstance(knobs, dict):
        raise InputError(f"{source}: [knobs] must be a table")
    for knob, values in knobs.items():
        _check_knob(kernel, knob, values, kind, source)
    problem = kernel.check_knobs(_extents(kernel, knobs))
    if problem:
        raise InputError(f"{source}: [knobs] {problem}")
    size(kernel, kind, knobs, n_draws, _seed_count(raw.get("seeds"), source), batch,
         runs_per_task, source, limit_bytes)
    return Spec(kernel=name, options=options, design=kind, knobs=dict(knobs),
                seeds=_seeds(raw.get("seeds"), source), runs_per_task=int(runs_per_task),
                batch=int(batch), n_draws=int(n_draws), design_seed=int(design_seed), text=text)


def design(spec: Spec) -> Design:
    """The runs of ``spec`` in their fixed order (design points, seeds innermost)."""
    kernel = spec.kernel_value
    names = list(kernel.knobs)
    if spec.design == "grid":
        values = [spec.knobs.get(k, [kernel.knobs[k].default]) for k in names]
        points = list(itertools.product(*values))
        cols = {k: [p[j] for p in points] for j, k in enumerate(names)}
    else:
        rng = np.random.default_rng(spec.design_seed)
        cols = {}
        for k in names:  # drawn in the kernel's knob order, so a spec's draws are reproducible
            v = spec.knobs.get(k, [kernel.knobs[k].default])
            if isinstance(v, dict):
                cols[k] = list(rng.uniform(float(v["min"]), float(v["max"]), spec.n_draws))
            else:
                cols[k] = [v[i] for i in rng.integers(0, len(v), spec.n_draws)]
    n_points = len(next(iter(cols.values())))
    seeds = np.tile(np.asarray(spec.seeds, dtype=np.int64), n_points)
    columns = {k: kernel.knobs[k].column(np.repeat(np.asarray(cols[k], dtype=object),
                                                   len(spec.seeds)))
               for k in names}
    return Design(columns, seeds)


def n_tasks(spec: Spec, n_runs: int) -> int:
    return -(-n_runs // spec.runs_per_task)


# ------------------------------------------------------------------------------------ checks
def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _options(kernel: Kernel, given, source: str) -> dict[str, Any]:
    if not isinstance(given, dict):
        raise InputError(f"{source}: [options] must be a table")
    unknown = sorted(set(given) - set(kernel.options))
    if unknown:
        raise InputError(f"{source}: kernel {kernel.name} has no option(s) {', '.join(unknown)}; "
                         f"its options are {', '.join(kernel.options) or 'none'}")
    for key, value in given.items():  # the schema: each option has its default's type
        default = kernel.options[key]
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, int | float):
            ok = _is_number(value)
        else:
            ok = isinstance(value, type(default))
        if not ok:
            raise InputError(f"{source}: [options] {key} = {value!r} must be "
                             f"{_type_name(default)} (like its default {default!r})")
    out = dict(kernel.options) | dict(given)
    problem = kernel.check_options(out)
    if problem:
        raise InputError(f"{source}: [options] {problem}")
    return out


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _type_name(default) -> str:
    if isinstance(default, bool):
        return "true or false"
    if isinstance(default, int | float):
        return "a finite number"
    return "a string" if isinstance(default, str) else type(default).__name__


def _check_knob(kernel: Kernel, knob: str, values, kind: str, source: str) -> None:
    if knob not in kernel.knobs:
        raise InputError(f"{source}: kernel {kernel.name} has no knob {knob!r}; its knobs are "
                         f"{', '.join(kernel.knobs)}")
    spec = kernel.knobs[knob]
    if isinstance(values, dict):
        if kind != "random" or spec.choices or set(values) != {"min", "max"}:
            raise InputError(f"{source}: knob {knob}: a range {{min = , max = }} is for a "
                             "numeric knob of a random design; give a list of values")
        lo, hi = values["min"], values["max"]
        bad = [v for v in (lo, hi) if spec.problem(v)]
        if bad or not lo <= hi:
            raise InputError(f"{source}: knob {knob}: range [{lo}, {hi}] invalid "
                             f"({spec.problem(bad[0]) if bad else 'min > max'})")
        return
    if not isinstance(values, list) or not values:
        raise InputError(f"{source}: knob {knob}: give a non-empty list of values")
    for v in values:
        problem = spec.problem(v)
        if problem:
            raise InputError(f"{source}: knob {knob}: {problem}")


def _extents(kernel: Kernel, knobs: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """(least, greatest) value of every numeric knob over the design (its default if left out)."""
    out = {}
    for name, k in kernel.knobs.items():
        if k.choices:
            continue
        v = knobs.get(name, [k.default])
        lo, hi = (v["min"], v["max"]) if isinstance(v, dict) else (min(v), max(v))
        out[name] = (float(lo), float(hi))
    return out


def _seed_count(raw, source: str) -> int:
    """How many seeds ``[seeds]`` asks for, without listing them (:func:`_seeds` checks them)."""
    if isinstance(raw, dict) and "values" in raw and isinstance(raw["values"], list):
        return len(raw["values"])
    if isinstance(raw, dict) and _is_int(raw.get("count")):
        count = raw["count"]
        first = raw.get("first", 0)
        if count >= 1 and _is_int(first) and not 0 <= first <= MAX_SEED - count + 1:
            raise InputError(f"{source}: [seeds] first = {first} and count = {count} reach "
                             f"beyond the seeds 0..{MAX_SEED}")
        return max(count, 0)
    return 0  # refused by _seeds, in its own words


def _seeds(raw, source: str) -> tuple[int, ...]:
    if not isinstance(raw, dict) or not (set(raw) == {"values"} or set(raw) <= {"count", "first"}
                                         and "count" in raw):
        raise InputError(f"{source}: [seeds] needs values = [...] or count = N (and first = S)")
    if "values" in raw:
        seeds = raw["values"]
        if not isinstance(seeds, list) or not seeds:
            raise InputError(f"{source}: [seeds] values must be a non-empty list of integers")
    else:
        count, first = raw["count"], raw.get("first", 0)
        if not _is_int(count) or count < 1 or not _is_int(first):
            raise InputError(f"{source}: [seeds] count must be a positive integer and first an "
                             "integer")
        seeds = list(range(first, first + count))
    if not all(_is_int(s) and 0 <= s <= MAX_SEED for s in seeds):
        raise InputError(f"{source}: seeds must be integers in 0..{MAX_SEED}")
    if len(set(seeds)) != len(seeds):
        raise InputError(f"{source}: seeds repeat")
    return tuple(int(s) for s in seeds)
