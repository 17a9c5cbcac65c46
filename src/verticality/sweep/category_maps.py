"""Maps of a sweep over two knobs, one column of panels per value of the kernel's categorical knob.

For a kernel without a ``head`` knob (whose maps :mod:`verticality.sweep.maps` draws), e.g.
``ambiguity-walking`` and its ``feed``: the kernel's first categorical knob (the *category*)
splits the runs, and for each of its values and each cell of two numeric knobs (``x``, ``y``,
chosen as :func:`verticality.sweep.grid.choose_knobs` does, cut into cells as
:func:`verticality.sweep.grid.cells` does) the maps give the **probability of divergence** (share
of the cell's runs flagged ``diverged``) and the **median** of the kernel's first metric over the
cell's runs that did not diverge (NaN when all did or none ran).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep import grid
from verticality.sweep.kernels import Kernel


@dataclass(frozen=True)
class CategoryMaps:
    """The maps over knobs ``x`` (columns) and ``y`` (rows), keyed by the category's value; every
    array is (len(y_values), len(x_values))."""

    x: str
    y: str
    category: str  # the categorical knob
    metric: str  # the metric whose median is mapped
    x_values: np.ndarray
    y_values: np.ndarray
    binned: tuple[bool, bool]
    runs: dict[str, np.ndarray]
    p_diverged: dict[str, np.ndarray]
    median: dict[str, np.ndarray]  # of ``metric``, over the runs that did not diverge


def category_of(kernel: Kernel) -> str:
    """The kernel's first categorical knob."""
    names = [k for k, v in kernel.knobs.items() if v.choices]
    if not names:
        raise InputError(f"{kernel.name} has no categorical knob to split its maps by")
    return names[0]


def split(kernel: Kernel, columns: dict[str, np.ndarray]) -> tuple[str, tuple[str, ...], str]:
    """How a sweep's table of a kernel without heads is split: ``(category, its values present in
    the table, metric)`` — :func:`category_of` and the kernel's first metric."""
    category, metric = category_of(kernel), kernel.metrics[0]
    missing = [c for c in (category, metric, "diverged") if c not in columns]
    if missing:
        raise InputError(f"a sweep of {kernel.name} has no {', '.join(missing)}")
    cat = np.asarray(columns[category]).astype(str)
    return category, tuple(c for c in kernel.knobs[category].choices if np.any(cat == c)), metric


def compute(kernel: Kernel, columns: dict[str, np.ndarray], x: str | None = None,
            y: str | None = None) -> CategoryMaps:
    """The maps of the table ``columns`` (name → array) of a sweep of ``kernel``."""
    category, present, metric = split(kernel, columns)
    x, y = grid.choose_knobs(kernel, columns, x, y)
    xv, xi, xb = grid.cells(columns[x])
    yv, yi, yb = grid.cells(columns[y])
    runs, p_div, med = grid.grid_cells(columns[category], present, xi, yi, xv.size,
                                            yv.size, columns["diverged"], columns[metric])
    return CategoryMaps(x, y, category, metric, xv, yv, (xb, yb), runs, p_div, med)


def write(kernel: Kernel, columns: dict[str, np.ndarray], out_dir: Path, x: str | None = None,
          y: str | None = None, path: Path | None = None) -> tuple[Path, CategoryMaps]:
    """Compute the maps of a sweep's table and write them as a PNG (default
    ``out_dir/maps-X-Y.png``)."""
    maps = compute(kernel, columns, x, y)
    path = Path(path) if path is not None else Path(out_dir) / f"maps-{maps.x}-{maps.y}.png"
    return figure(maps, path, f"{kernel.name}: {columns['run'].size} runs"), maps


def figure(maps: CategoryMaps, path: Path, title: str) -> Path:
    """Two rows of panels, one column per category value: the divergence probability and the
    median of the metric (one colour scale, logarithmic when every value is positive)."""
    from matplotlib.colors import LogNorm, Normalize

    from verticality.core import plots

    cats = list(maps.runs)
    fig, axes = plots.new_figure(2, len(cats), width=3.4 * len(cats), height_per_row=3.4,
                                 sharex=False)
    finite = np.concatenate([a[np.isfinite(a)].ravel() for a in maps.median.values()])
    if finite.size and np.all(finite > 0):
        norm = LogNorm(finite.min(), max(finite.max(), finite.min() * 1.01))
    else:
        norm = Normalize()
    for col, c in enumerate(cats):
        for row, (values, label, nrm, cmap) in enumerate((
                (maps.p_diverged[c], f"P(diverged), {c}", Normalize(0, 1), "magma_r"),
                (maps.median[c], f"median {maps.metric}, {c}", norm, "viridis"))):
            ax = axes[row, col]
            im = ax.imshow(np.ma.masked_invalid(values), origin="lower", aspect="auto", norm=nrm,
                           cmap=cmap, interpolation="nearest")
            fig.colorbar(im, ax=ax)
            ax.set_title(label, fontsize=8)
            ax.set_xticks(np.arange(maps.x_values.size))
            ax.set_xticklabels([f"{v:.3g}" for v in maps.x_values], fontsize=7)
            ax.set_yticks(np.arange(maps.y_values.size))
            ax.set_yticklabels([f"{v:.3g}" for v in maps.y_values], fontsize=7)
            ax.set_xlabel(maps.x + (" (bin centre)" if maps.binned[0] else ""), fontsize=8)
            ax.set_ylabel(maps.y + (" (bin centre)" if maps.binned[1] else ""), fontsize=8)
    fig.suptitle(f"{title}, by {maps.category}")
    return plots.save(fig, path)
