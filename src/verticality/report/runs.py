"""Running experiments into the results object of ``verticality reproduce`` (each one's entry:
:mod:`verticality.report.entries`), and turning values into terminal text."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from verticality.report.entries import RESULTS_NAME, run_one


def flatten(d: dict, prefix: str = "") -> dict[str, Any]:
    """Flatten nested dicts to dotted keys; a ``{"value", "tolerance", "pass"}`` dict is a leaf."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, dict) and not {"value", "pass"} <= set(v):
            out.update(flatten(v, key))
        else:
            out[key] = v
    return out


def format_value(v: Any) -> str:
    if isinstance(v, dict) and "value" in v:
        mark = "pass" if v.get("pass") else "FAIL"
        return f"{format_value(v['value'])} (tol {format_value(v.get('tolerance'))}) {mark}"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        if v == 0.0 or 1e-3 <= abs(v) < 1e4:
            return f"{v:.4g}"
        return f"{v:.3e}"
    if isinstance(v, list):
        if any(isinstance(x, dict) for x in v):
            return f"{len(v)} rows (see results.json)"
        if len(v) > 6:
            return "[" + ", ".join(format_value(x) for x in v[:6]) + f", … ({len(v)} values)]"
        return "[" + ", ".join(format_value(x) for x in v) + "]"
    if v is None:
        return "null"
    text = str(v)
    return text if len(text) <= 120 else text[:117] + "…"


def run_experiments(names: list[str] | None, *, quick: bool = False, out_dir: Path | None = None,
                    on_stage: Callable[[str, str], None] | None = None, jobs: int = 1) -> dict:
    """Run the named experiments (all registered ones when ``names`` is empty) and return the
    results object of docs/reproduction.md: ``{"experiments": {NAME: {"metrics", "paper",
    "runtime", "figures"?}}, "registry": {NAME: {"title", "source"}}, "provenance": {...}}``.
    With ``out_dir``, each experiment's figures go to ``out_dir/NAME/`` and the object to
    ``out_dir/results.json``. ``on_stage(name, stage)`` is told ``"running"``, ``"figures"`` and
    ``"done"``. ``jobs`` > 1 runs them in that many worker processes at once, longest first
    (:mod:`verticality.report.pool`); the object is the same, in the same order, as with
    ``jobs=1`` (one after the other in this process).
    An unknown name raises :class:`~verticality.core.errors.InputError` before anything runs."""
    from verticality import experiments

    registry = experiments.discover()
    chosen = chosen_names(names)
    exps = [experiments.get(n) for n in chosen]
    if out_dir is None:
        return _run(exps, chosen, registry, quick, names, None, on_stage, jobs)
    from verticality.io.paths import check_output_folder, confined_folder, folder_lock

    with folder_lock(check_output_folder(out_dir, "--out")):  # one run at a time in a folder
        for exp in exps:  # the figures' folders, inside the results folder (no link out)
            if exp.figures is not None:
                confined_folder(out_dir, exp.name)
        return _run(exps, chosen, registry, quick, names, out_dir, on_stage, jobs)


def _run(exps, chosen, registry, quick, names, out_dir, on_stage, jobs) -> dict:
    """:func:`run_experiments` (in its locked results folder when ``out_dir`` is given)."""
    from verticality.report import pool as experiment_pool
    from verticality.report import provenance

    results: dict = {"experiments": {},
                     "registry": {n: {"title": e.title, "source": e.source}
                                  for n, e in sorted(registry.items())},
                     "provenance": provenance.collect(quick=quick, names=list(names or []))}
    if jobs > 1 and len(exps) > 1:
        entries = experiment_pool.run_pool(chosen, quick=quick, out_dir=out_dir, jobs=jobs,
                                           on_stage=on_stage)
    else:
        entries = {}
        for exp in exps:
            entries[exp.name] = run_one(exp, quick=quick, out_dir=out_dir, on_stage=on_stage)
            if on_stage is not None:
                on_stage(exp.name, "done")
    results["experiments"] = {n: entries[n] for n in chosen}
    if out_dir is not None:
        write_results(out_dir, results)
    return results


def earlier_results(out_dir: Path, quick: bool) -> dict | None:
    """The ``results.json`` already in ``out_dir`` (None when there is none), checked to be one
    (:func:`verticality.report.results_schema.check_results`) and of the same mode as a run with
    ``quick``: a rerun merges into it, so a damaged file or one of the other mode is refused
    before anything runs."""
    from verticality.core.errors import InputError
    from verticality.report import read_results_text
    from verticality.report.results_schema import check_results

    path = Path(out_dir) / RESULTS_NAME
    if not path.is_file():
        return None
    try:
        data = check_results(json.loads(read_results_text(path)), str(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not valid JSON ({exc.msg} at line {exc.lineno}); a rerun "
                         "into this folder would merge into it: mend or move it, or give another "
                         "--out") from None
    mode = (data.get("provenance") or {}).get("mode")
    want = "quick" if quick else "full"
    if mode is not None and mode != want:
        raise InputError(f"{path} holds a {mode} run; a {want} run would mix the two in one "
                         f"report: give another --out{'' if quick else ' or add --quick'}")
    return data


def write_results(out_dir: Path, results: dict) -> Path:
    """Write ``results`` to ``out_dir/results.json``, merged into what is there: an experiment of
    this run replaces only its own entry, the others stay (and the report lists them), the
    earlier runs' date, version, commit and experiments are kept under ``provenance.earlier``.
    Written under a temporary name and renamed, so an interrupted write loses nothing."""
    from verticality.io.paths import write_atomic

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    quick = (results.get("provenance") or {}).get("mode") == "quick"
    old = earlier_results(out_dir, quick) or {"experiments": {}}
    merged = dict(results)
    merged["experiments"] = {**old["experiments"], **results["experiments"]}
    prov = results.get("provenance")
    if old.get("provenance") and isinstance(prov, dict):
        before = old["provenance"]
        kept = {k: before.get(k) for k in ("date_utc", "experiments_requested", "version", "git")}
        merged["provenance"] = {**prov, "earlier": [*before.get("earlier", []), kept]}
    text = json.dumps(merged, indent=2)
    return write_atomic(out_dir / RESULTS_NAME,
                        lambda tmp: tmp.write_text(text, encoding="utf-8"), root=out_dir)


def chosen_names(names: list[str] | None) -> list[str]:
    """The experiments a run of ``names`` runs, in the order of its results: those named, else
    every registered one by name. An unknown name raises
    :class:`~verticality.core.errors.InputError`."""
    from verticality import experiments

    for name in names or ():
        experiments.get(name)
    return list(names) if names else sorted(experiments.discover())


def failed_checks(results: dict) -> list[str]:
    """``"NAME: metric.path"`` of every check that did not pass."""
    failed = []
    for name, entry in results["experiments"].items():
        for key, value in flatten(entry["metrics"]).items():
            if isinstance(value, dict) and value.get("pass") is False:
                failed.append(f"{name}: {key}")
    return failed
