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


def load_results(results_dir: Path) -> dict:
    """``results.json`` of a results folder, checked to be a reproduce result."""
    path = Path(results_dir) / RESULTS_NAME
    if not path.is_file():
        raise InputError(f"no {RESULTS_NAME} in {results_dir}; run `verticality reproduce "
                         f"--out {results_dir}` first")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
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


def build(results_dir: Path, out: Path | None = None) -> Path:
    """Write the report of ``results_dir`` to ``out`` (default ``results_dir/report.html``).
    ``out`` may not be a file the report reads (results.json, a figure: any file under
    ``results_dir`` but the default page), checked before anything is written."""
    from verticality.io.paths import check_paths

    results_dir = Path(results_dir)
    target = Path(out) if out is not None else results_dir / REPORT_NAME
    if out is not None and results_dir.is_dir():
        default = results_dir / REPORT_NAME
        read = [p for p in results_dir.rglob("*") if p.is_file() and p != default]
        check_paths({"--out": target}, read)
    page = render(load_results(results_dir), results_dir)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(page, encoding="utf-8")
    return target
