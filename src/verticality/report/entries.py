"""One experiment's entry of the results object of ``verticality reproduce`` (run in this process
or in a worker process), the file the results are saved in, and values made plain JSON. Kept apart
from the orchestration (:mod:`verticality.report.runs`) so that the worker pool and the cost table
import it without importing the orchestrator that imports them."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

RESULTS_NAME = "results.json"


def to_jsonable(value: Any) -> Any:
    """Plain-JSON copy of ``value``: arrays to lists, NumPy/JAX scalars to Python, NaN/inf to
    None."""
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
