"""Turning experiment results into JSON and terminal tables."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


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
