"""The reproduction report: one self-contained HTML page built from a results folder.

``verticality reproduce`` writes ``results.json`` and one folder of figures per experiment;
:func:`build` turns them into ``report.html`` beside them (figures embedded), without running
anything again. What each experiment tests and what the seeds published is the table of
:mod:`verticality.report.claims`; the verdicts are :mod:`verticality.report.compare`'s; the run's
provenance is recorded by :mod:`verticality.report.provenance`.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

from verticality.core.errors import InputError
from verticality.report.entries import RESULTS_NAME
from verticality.report.results_schema import check_results

REPORT_NAME = "report.html"


MAX_RESULTS_BYTES = 256 * 2**20  # results.json of every experiment is < 1 MiB


def read_results_text(path: Path) -> str:
    """The text of a ``results.json``, checked before it is read to lie in its folder (links
    followed: a link planted there that leads out is not read) and to be of a results file's size
    (a file of gigabytes is none), then its encoding (one line each)."""
    from verticality.io.paths import inside

    if not inside(path, path.parent):
        raise InputError(f"{path}: a link out of its folder; a results folder holds its own "
                         "results.json")
    size = path.stat().st_size
    if size > MAX_RESULTS_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MiB, larger than any results file "
                         f"({MAX_RESULTS_BYTES // 2**20} MiB at most); not a results.json of "
                         "`verticality reproduce`")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path} is not UTF-8 text (byte {exc.start}); not a results.json of "
                         "`verticality reproduce`") from None


def load_results(results_dir: Path) -> dict:
    """``results.json`` of a results folder, checked to be a reproduce result."""
    path = Path(results_dir) / RESULTS_NAME
    if not path.is_file():
        raise InputError(f"no {RESULTS_NAME} in {results_dir}; run `verticality reproduce "
                         f"--out {results_dir}` first")
    try:
        data = json.loads(read_results_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
    return check_results(data, str(path))


def render(results: dict, results_dir: Path) -> str:
    """The report page for loaded results (figures looked up under ``results_dir``)."""
    from verticality import __version__
    from verticality.report import html

    built = {"by": f"verticality {__version__}",
             "date_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
             "results": str(Path(results_dir).resolve() / RESULTS_NAME)}
    return html.render(results, Path(results_dir), built)


def build(results_dir: Path, out: Path | None = None, warn=None) -> Path:
    """Write the report of ``results_dir`` to ``out`` (default ``results_dir/report.html``).
    ``out`` may not be a file the report reads (results.json, a figure: any file under
    ``results_dir`` but the default page), checked before anything is written. The page is
    written through :func:`verticality.io.paths.write_atomic` (a link where it goes is replaced,
    not written through; an existing page keeps its permissions; the default page must lie
    inside ``results_dir``). Figures are read from inside ``results_dir`` only; ``warn(line)`` is
    told each one that is not shown for that (or another) reason
    (:func:`verticality.report.html.figure_problems`)."""
    from verticality.io.paths import check_paths, write_text
    from verticality.report import html

    results_dir = Path(results_dir)
    target = Path(out) if out is not None else results_dir / REPORT_NAME
    if out is not None and results_dir.is_dir():
        default = results_dir / REPORT_NAME
        read = [p for p in results_dir.rglob("*") if p.is_file() and p != default]
        check_paths({"--out": target}, read)
    results = load_results(results_dir)
    page = render(results, results_dir)
    if warn is not None:
        for line in html.figure_problems(results, results_dir):
            warn(line)
    return write_text(target, page, "--out", root=results_dir if out is None else None)
