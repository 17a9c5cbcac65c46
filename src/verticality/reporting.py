"""Running experiments into the results object of ``verticality reproduce``, and turning values
into JSON and terminal text."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

RESULTS_NAME = "results.json"


def to_jsonable(value: Any) -> Any:
    """Plain-JSON copy of ``value``: arrays to lists, NumPy/JAX scalars to Python, NaN/inf to None."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "shape") and hasattr(value, "dtype"):
        arr = np.asarray(value)
        if arr.ndim == 0:
            return to_jsonable(arr.item())
        return [to_jsonable(v) for v in arr.tolist()]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        f = float(value)
        return f if math.isfinite(f) else None
    return value


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
    (:mod:`verticality.experiment_pool`); the object is the same, in the same order, as with
    ``jobs=1`` (one after the other in this process).
    An unknown name raises :class:`~verticality.errors.InputError` before anything runs."""
    from verticality import experiment_pool, experiments
    from verticality.report import provenance

    registry = experiments.discover()
    chosen = chosen_names(names)
    exps = [experiments.get(n) for n in chosen]
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
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        (Path(out_dir) / RESULTS_NAME).write_text(json.dumps(results, indent=2))
    return results


def chosen_names(names: list[str] | None) -> list[str]:
    """The experiments a run of ``names`` runs, in the order of its results: those named, else
    every registered one by name. An unknown name raises
    :class:`~verticality.errors.InputError`."""
    from verticality import experiments

    for name in names or ():
        experiments.get(name)
    return list(names) if names else sorted(experiments.discover())


def run_one(exp, *, quick: bool = False, out_dir: Path | None = None,
            on_stage: Callable[[str, str], None] | None = None) -> dict:
    """One experiment's entry of the results object (its figures drawn under ``out_dir/NAME/``
    with ``out_dir``); the same function in this process and in a worker process."""
    if on_stage is not None:
        on_stage(exp.name, "running")
    t0 = time.perf_counter()
    result = exp.run(quick=quick)
    wall = time.perf_counter() - t0
    entry = {
        "metrics": to_jsonable(result.metrics),
        "paper": to_jsonable(result.paper),
        "runtime": {"wall_s": wall, "simulated_s": float(result.simulated_s)},
    }
    if out_dir is not None and exp.figures is not None:
        if on_stage is not None:
            on_stage(exp.name, "figures")
        fig_dir = Path(out_dir) / exp.name
        fig_dir.mkdir(parents=True, exist_ok=True)
        entry["figures"] = [str(p) for p in exp.figures(result, fig_dir)]
    return entry


def failed_checks(results: dict) -> list[str]:
    """``"NAME: metric.path"`` of every check that did not pass."""
    failed = []
    for name, entry in results["experiments"].items():
        for key, value in flatten(entry["metrics"]).items():
            if isinstance(value, dict) and value.get("pass") is False:
                failed.append(f"{name}: {key}")
    return failed
