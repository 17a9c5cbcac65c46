"""``verticality estimate`` over a folder of recordings (IMU CSVs, BROAD-layout HDF5 files, or a
list or glob of them), one task per recording on the sweeps' engine
(:mod:`verticality.sweep.engine`): in this process one after the other, on a ``LocalCluster`` of
worker processes, or on a running Dask scheduler.

Each recording ``NAME.csv`` / ``NAME.hdf5`` gives ``OUT/NAME.csv``, written by
:func:`verticality.tilt.files.estimate_file` exactly as the single-file command writes
it (bit for bit), and one row of the summary table ``OUT/summary.csv`` / ``OUT/summary.json``
(:data:`SUMMARY_COLUMNS`). A recording that cannot be read or filtered is a row with its error
(``status`` ``error``), not the end of the run. A task writes its row to ``OUT/rows/NAME.json``
(temporary name, then renamed) after its output, with the fingerprints (size, modification time,
SHA-256) of the input it read and the output it wrote: with ``resume`` an input is not computed
again only if its row says ``ok`` and both fingerprints still hold (a recording that grew or was
edited after its estimate is estimated again). ``OUT/folder.json`` holds the options, so that a
resumed run uses the ones the finished outputs were made with.
"""

from __future__ import annotations

import glob
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.tilt.flags import FLAG_KEYS

RECORDING_SUFFIXES = (".csv", ".hdf5", ".h5", ".ulg", ".bag", ".mcap")  # (logs: docs/logs.md)
SUMMARY_NAMES = ("summary.csv", "summary.json", "folder.json")  # in OUT beside the outputs
# suffixes of files, not folders: a new --out with one is a file name given by mistake
FILE_SUFFIXES = (".csv", ".json", ".parquet", ".h5", ".hdf5", ".txt", ".png")
ROWS_DIR = "rows"
MANIFEST = "made_from"  # the row file's proof: the input's and the output's fingerprints
# the summary's count of samples carrying each flag bit (tilt_flags), by column
FLAG_COLUMNS = {bit: f"n_{key}" for bit, key in FLAG_KEYS.items()}
SUMMARY_COLUMNS = (("file", "output", "status", "error", "rows", "duration_s", "share_flagged",
                    "mean_sigma_deg") + tuple(FLAG_COLUMNS.values()) + ("wall_s",))


@dataclass(frozen=True)
class FolderSummary:
    out_dir: Path
    rows: tuple[dict, ...]  # one per input, in input order (SUMMARY_COLUMNS)
    computed: tuple[str, ...]  # the inputs computed this time (the others were complete)
    wall_s: float

    @property
    def n_errors(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    @property
    def table_csv(self) -> Path:
        return self.out_dir / "summary.csv"


def is_folder_input(arg) -> bool:
    """Whether a command's INPUT means many recordings: a folder (not a ROS 2 bag's: one
    recording), or a glob pattern that is not an existing file."""
    path = Path(arg)
    if path.is_dir():
        return not (path / "metadata.yaml").is_file()
    return not path.exists() and glob.has_magic(str(arg))


def find_recordings(inputs) -> list[Path]:
    """The recordings named by ``inputs`` (a path or a list of paths): a folder gives its
    files of :data:`RECORDING_SUFFIXES` (not its subfolders, not hidden files), sorted by
    name; a glob pattern its matches, sorted; a file itself. Refuses an empty result."""
    items = [inputs] if isinstance(inputs, (str, Path)) else list(inputs)
    found: list[Path] = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            found += sorted(p for p in path.iterdir() if p.is_file()
                            and p.suffix.lower() in RECORDING_SUFFIXES
                            and not p.name.startswith("."))
        elif path.exists():
            found.append(path)
        elif glob.has_magic(str(item)):
            found += sorted(Path(p) for p in glob.glob(str(item)) if Path(p).is_file())
        else:
            raise InputError(f"{path}: no such file or folder")
    if not found:
        raise InputError(f"{', '.join(map(str, items))}: no recordings found "
                         f"({', '.join(RECORDING_SUFFIXES)})")
    return found


def output_names(recordings: list[Path]) -> list[str]:
    """Each recording's output file name in OUT (its stem + ``.csv``), checked unique and not a
    summary file's name."""
    from verticality.io.paths import resolved

    names = [p.stem + ".csv" for p in recordings]
    seen: dict[str, Path] = {}
    for name, path in zip(names, recordings, strict=True):
        if name in seen:
            if resolved(seen[name]) == resolved(path):
                raise InputError(f"{path}: given twice")
            raise InputError(f"{seen[name]} and {path} would both be written to {name}; "
                             "rename one or run them into two folders")
        if name in SUMMARY_NAMES:
            raise InputError(f"{path}: its output would be {name}, the name of the summary "
                             "table; rename the recording")
        seen[name] = path
    return names


def run_summary(run) -> dict:
    """The summary row's numbers of one :class:`~verticality.tilt.files.EstimateRun`
    (``mean_sigma_deg``: the mean σ of the tilt over the settled samples, None for a peer or
    when no sample settled)."""
    from verticality.tilt.files import settled_samples

    flags = np.asarray(run.flags).astype(np.int64)
    row = {"rows": int(run.n), "duration_s": float(run.duration_s),
           "share_flagged": float(np.mean(flags != 0)) if flags.size else None,
           "mean_sigma_deg": None}
    if run.sigma_rad is not None:
        settled = settled_samples(flags)
        if np.any(settled):
            sig = np.asarray(run.sigma_rad, dtype=np.float64)[settled]
            row["mean_sigma_deg"] = float(np.degrees(np.mean(sig)))
    row |= {col: int(np.count_nonzero(flags & bit)) for bit, col in FLAG_COLUMNS.items()}
    return row


def error_message(exc: BaseException) -> str:
    """One line for a recording that failed: a user error's own words, else the exception's type
    and message."""
    if isinstance(exc, InputError):
        return str(exc)
    if isinstance(exc, UnicodeDecodeError):
        return f"the input is not UTF-8 text ({exc.reason} at byte {exc.start})"
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror} ({exc.filename})" if exc.filename else exc.strerror
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def estimate_one(path: str, out_path: str, row_path: str, options: dict,
                 compile_cache: str | None = None) -> dict:
    """One task: ``estimate`` of the recording ``path`` into ``out_path`` with ``options``
    (:func:`~verticality.tilt.files.estimate_file`'s keywords), then its summary row
    into ``row_path`` (atomically). A failure is the row's ``error``; the task never raises for a
    bad recording."""
    from verticality.io.paths import write_text
    from verticality.sweep.engine import use_compile_cache
    from verticality.tilt.files import estimate_file

    use_compile_cache(compile_cache)
    row = dict.fromkeys(SUMMARY_COLUMNS)
    row |= {"file": str(path), "output": Path(out_path).name, "status": "ok", "error": ""}
    start = time.perf_counter()
    from verticality.io.paths import fingerprint

    manifest = {}
    try:
        source = fingerprint(path)  # before the read: a file changed meanwhile is redone later
        from verticality.io.logs import is_log

        if is_log(path):
            from verticality.tilt.logs import estimate_log_file

            run = estimate_log_file(path, out_path, units=options["units"],
                                    filter_name=options["filter_name"], sigma=options["sigma"],
                                    offline=options["offline"], ranges=options["ranges"]).run
        else:
            run = estimate_file(path, out_path, options["units"], options["columns"],
                                options["time_unit"], options["filter_name"],
                                sigma=options["sigma"], offline=options["offline"],
                                ranges=options["ranges"])
        row |= run_summary(run)
        manifest = {MANIFEST: {"input": source, "output": fingerprint(out_path)}}
    except Exception as exc:  # a bad recording is a row with its error, never the run's end
        row |= {"output": "", "status": "error", "error": error_message(exc)}
    row["wall_s"] = time.perf_counter() - start
    write_text(Path(row_path), json.dumps(row | manifest) + "\n")
    return row


def estimate_options(units=(), columns=None, time_unit=None, filter_name: str | None = None,
                     sigma: bool = False, offline: bool = False,
                     ranges: dict | None = None) -> dict:
    """The options of every recording's ``estimate`` (checked once, before any task), as a
    JSON-able dict."""
    from verticality.io.recording import parse_units
    from verticality.tilt.evaluation.broad import OURS
    from verticality.tilt.files import check_offline, check_ranges, check_sigma

    filter_name = filter_name or OURS
    check_offline(filter_name, offline)
    check_sigma(filter_name, sigma)
    parse_units(units)
    if isinstance(columns, str):
        from verticality.io.imu_layout import parse_columns_spec

        parse_columns_spec(columns)
    return {"units": list(units), "columns": columns, "time_unit": time_unit,
            "filter_name": filter_name, "sigma": bool(sigma), "offline": bool(offline),
            "ranges": check_ranges(filter_name, ranges)}


def output_folder(out_dir: Path, recordings: list[Path]) -> Path:
    """Make ``out_dir``: a folder, not an input."""
    from verticality.io.paths import check_output_folder

    if not out_dir.exists() and out_dir.suffix.lower() in FILE_SUFFIXES:
        raise InputError(f"--out {out_dir}: a folder of recordings gives one output per "
                         f"recording, so --out names a folder, not a {out_dir.suffix} file")
    return check_output_folder(out_dir, "--out", recordings)


def prepare(out_dir: Path, options: dict, resume: bool, recordings: list[Path]) -> Path:
    """Make ``out_dir`` (:func:`output_folder`) and check it holds no folder run yet, or
    (``resume``) one made with the same options."""
    from verticality.io.paths import confined_folder, write_text

    out_dir = output_folder(out_dir, recordings)
    record = out_dir / "folder.json"
    if record.exists():
        if not resume:
            raise InputError(f"{out_dir} already holds estimates of a folder; use --resume to "
                             "finish it or another --out")
        try:
            old = json.loads(record.read_text(encoding="utf-8"))
        except (ValueError, UnicodeDecodeError) as exc:
            raise InputError(f"{record} is damaged ({str(exc)[:80]}); the options of the "
                             "estimates there are unknown: use another --out") from None
        if not isinstance(old, dict) or old.get("options") != options:
            raise InputError(f"{out_dir} holds estimates made with other options "
                             f"({old.get('options')}); cannot resume them with these")
    confined_folder(out_dir, ROWS_DIR)  # (a link planted there would take the rows out)
    write_text(record, json.dumps({"options": options}, indent=2) + "\n", root=out_dir)
    return out_dir


def finished_row(row_path: Path, out_path: Path, in_path: Path | None = None) -> dict | None:
    """The row of a finished input, else None: its row file says ``ok``, and its manifest proves
    that the output is the one written (size and SHA-256) from the input as it is now (size,
    modification time and SHA-256; ``in_path`` None: not checked). A recording that grew or was
    edited after its estimate, or an output replaced, is not finished."""
    from verticality.io.paths import fingerprint

    try:
        row = json.loads(row_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if (not isinstance(row, dict) or row.get("status") != "ok" or not out_path.is_file()
            or not set(SUMMARY_COLUMNS) <= set(row)):
        return None
    made = row.pop(MANIFEST, None)
    if not isinstance(made, dict) or not isinstance(made.get("output"), dict):
        return None  # no proof of what it was made from
    try:
        out_now = fingerprint(out_path)
        in_now = fingerprint(in_path) if in_path is not None else made.get("input")
    except OSError:
        return None
    same_out = {k: out_now[k] for k in ("size", "sha256")} == \
        {k: made["output"].get(k) for k in ("size", "sha256")}
    return row if same_out and in_now == made.get("input") else None


def estimate_folder(inputs, out_dir, *, units=(), columns=None, time_unit=None,
                    filter_name: str | None = None, sigma: bool = False, offline: bool = False,
                    ranges: dict | None = None, scheduler: str | None = None,
                    workers: int | None = None, resume: bool = False, progress: bool = True,
                    compile_cache: str | Path | None = None) -> FolderSummary:
    """``estimate`` every recording of ``inputs`` (:func:`find_recordings`) into ``out_dir``, one
    task each (:func:`estimate_one`), on the scheduler at ``scheduler``, a ``LocalCluster`` of
    ``workers`` processes, or (neither given) in this process; write the summary table
    (``summary.csv``, ``summary.json``). ``units`` … ``ranges``: as for
    :func:`~verticality.tilt.files.estimate_file` (:func:`estimate_options`).
    ``compile_cache``: JAX's persistent compilation cache for the workers (default: this
    process's)."""
    from verticality.io.paths import folder_lock, resolved
    from verticality.sweep import engine

    engine.check_workers(workers)
    if scheduler or workers is not None:
        engine.require_engine()
    if scheduler:  # before anything is written: an address that is wrong or does not answer
        scheduler = engine.check_scheduler(scheduler)
    options = estimate_options(units, columns, time_unit, filter_name, sigma, offline, ranges)
    recordings = find_recordings(inputs)
    names = output_names(recordings)
    out_dir = Path(out_dir)
    sources = {resolved(p): p for p in recordings}
    for name in names:
        if resolved(out_dir / name) in sources:
            raise InputError(f"--out {out_dir}: {name} there is the input "
                             f"{sources[resolved(out_dir / name)]}; give another folder")
    with folder_lock(output_folder(out_dir, recordings)):  # one run at a time in a folder
        return _estimate_into(recordings, names, out_dir, options, scheduler, workers, resume,
                              progress, compile_cache)


def _estimate_into(recordings, names, out_dir, options, scheduler, workers, resume, progress,
                   compile_cache) -> FolderSummary:
    """:func:`estimate_folder` in its locked output folder."""
    from verticality.sweep import engine

    out_dir = prepare(out_dir, options, resume, recordings)
    rows_dir = out_dir / ROWS_DIR
    done = {}
    if resume:
        done = {n: r for p, n in zip(recordings, names, strict=True)
                if (r := finished_row(rows_dir / (n + ".json"), out_dir / n, p)) is not None}
    if compile_cache is None:
        import jax

        compile_cache = jax.config.jax_compilation_cache_dir
    cache = str(compile_cache) if compile_cache else None
    todo = {f"estimate-{i}": (p, n) for i, (p, n) in enumerate(zip(recordings, names,
                                                                   strict=True)) if n not in done}
    calls = {key: (str(p), str(out_dir / n), str(rows_dir / (n + ".json")), options, cache)
             for key, (p, n) in todo.items()}

    def lost(key, exc):  # a task that did not return (e.g. its worker died): a row, not written
        row = dict.fromkeys(SUMMARY_COLUMNS)
        return row | {"file": str(todo[key][0]), "output": "", "status": "error",
                      "error": error_message(exc)}

    start = time.perf_counter()
    results = engine.map_tasks(estimate_one, calls, scheduler=scheduler, workers=workers,
                               progress=progress, description="estimate",
                               on_error=lost) if calls else {}
    wall = time.perf_counter() - start
    by_name = {todo[key][1]: row for key, row in results.items()}
    rows = tuple(done.get(n) or by_name[n] for n in names)
    write_summary(out_dir, rows)
    computed = tuple(str(p) for p, _ in todo.values())
    return FolderSummary(out_dir, rows, computed, wall)


def write_summary(out_dir: Path, rows) -> None:
    """``summary.csv`` (empty cells for missing numbers) and ``summary.json`` (a list of rows,
    null for missing numbers), each written under a temporary name and renamed."""
    import csv
    import io

    from verticality.io.paths import write_text

    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row[k] is None else row[k]) for k in SUMMARY_COLUMNS})
    # (a file name that is not valid UTF-8 is written with backslash escapes)
    write_text(out_dir / "summary.csv", text.getvalue(), root=out_dir)
    write_text(out_dir / "summary.json", json.dumps(list(rows), indent=1) + "\n", root=out_dir)
