"""The grid a sweep's maps are drawn on: each knob's cells (its values, or equal-width bins of a
random design), the two knobs chosen for the axes, and per group the run counts, divergence share
and median error of every cell. The head maps (:mod:`verticality.sweep.maps`) and the maps per
category (:mod:`verticality.sweep.category_maps`) share it."""

from __future__ import annotations

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep.kernels import Kernel

MAX_LEVELS = 12
BINS = 10


def cells(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(centres, index of each value's cell, binned)`` for one knob's column."""
    values = np.asarray(values, dtype=np.float64)
    levels = np.unique(values)
    if levels.size <= MAX_LEVELS:
        return levels, np.searchsorted(levels, values), False
    edges = np.linspace(levels[0], levels[-1], BINS + 1)
    index = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, BINS - 1)
    return 0.5 * (edges[:-1] + edges[1:]), index, True


def choose_knobs(kernel: Kernel, columns: dict[str, np.ndarray], x: str | None,
                 y: str | None) -> tuple[str, str]:
    """The two knobs to map: those given, else the numeric knobs that vary most (kernel order)."""
    numeric = [k for k, v in kernel.knobs.items() if not v.choices]
    for name in (x, y):
        if name is not None and name not in numeric:
            raise InputError(f"cannot map over {name!r}; the numeric knobs of {kernel.name} are "
                             f"{', '.join(numeric)}")
    by_spread = sorted(numeric, key=lambda k: -np.unique(columns[k]).size)
    rest = [k for k in by_spread if k not in (x, y)]
    x = x or rest.pop(0)
    y = y or next(k for k in rest if k != x)
    if x == y:
        raise InputError(f"--x and --y are the same knob ({x})")
    return x, y


def grid_cells(group, groups, xi, yi, nx: int, ny: int, diverged, values):
    """Per value ``g`` of ``groups`` (the runs whose column ``group`` equals it), on the (ny, nx)
    grid of cell indices ``xi``, ``yi``: the number of runs, the share that diverged and the
    median of ``values`` over the runs that did not (NaN where a cell has none); three dicts
    ``g →`` (ny, nx) array."""
    group = np.asarray(group).astype(str)
    diverged = np.asarray(diverged, dtype=bool)
    values = np.asarray(values, dtype=np.float64)
    runs, p_div, med = {}, {}, {}
    for g in groups:
        n = np.zeros((ny, nx))
        p = np.full((ny, nx), np.nan)
        m = np.full((ny, nx), np.nan)
        for j in range(ny):
            for i in range(nx):
                sel = (group == g) & (xi == i) & (yi == j)
                n[j, i] = np.sum(sel)
                if n[j, i]:
                    p[j, i] = np.mean(diverged[sel])
                    kept = values[sel & ~diverged]
                    if kept.size:
                        m[j, i] = np.median(kept)
        runs[g], p_div[g], med[g] = n, p, m
    return runs, p_div, med
