"""Maps of a sweep's results over two knobs: where head stabilization pays.

For each cell of two knobs (``x``, ``y``) and each head (``fixed``, ``stabilized``): the
**probability of divergence** (share of the cell's runs flagged ``diverged``), the **median max
error** (degrees, over the cell's runs that did not diverge; NaN when all did), the number of runs,
and the **ratio** of the fixed head's median max error to the stabilized head's. A knob with at
most :data:`~verticality.sweep.grid.MAX_LEVELS` distinct values is mapped value by value; a knob
with more (a random design) is cut into :data:`~verticality.sweep.grid.BINS` equal-width bins, each
cell labelled by its centre. The kernel's published point
(:attr:`~verticality.sweep.kernels.Kernel.published`), when both knobs are among its settings, is
marked on every panel.

:func:`compute` makes the maps from the table's columns; :func:`write` reads ``DIR/results.parquet``
and ``DIR/spec.toml`` and writes ``DIR/maps-X-Y.png``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep import spec as sweep_spec
from verticality.sweep.grid import cells, choose_knobs, grid_cells
from verticality.sweep.kernels import Kernel

if TYPE_CHECKING:
    from verticality.sweep.category_maps import CategoryMaps

HEADS = ("fixed", "stabilized")
NEEDED = ("head", "diverged", "max_error_deg")


@dataclass(frozen=True)
class Maps:
    """The maps over knobs ``x`` (columns) and ``y`` (rows); every array is (len(y_values),
    len(x_values)); the per-head arrays are keyed by head."""

    x: str
    y: str
    x_values: np.ndarray  # the knob's values, or the bins' centres
    y_values: np.ndarray
    binned: tuple[bool, bool]  # (x, y) cut into bins
    runs: dict[str, np.ndarray]
    p_diverged: dict[str, np.ndarray]
    median_max_error_deg: dict[str, np.ndarray]  # over the runs that did not diverge
    published: tuple[float, float] | None  # the kernel's published point in (x, y), if any
    published_label: str = ""

    @property
    def ratio(self) -> np.ndarray:
        """Fixed over stabilized median max error."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.median_max_error_deg["fixed"] / self.median_max_error_deg["stabilized"]


def compute(kernel: Kernel, columns: dict[str, np.ndarray], x: str | None = None,
            y: str | None = None) -> Maps:
    """The maps of the table ``columns`` (name → array) of a sweep of ``kernel``."""
    missing = [c for c in NEEDED if c not in columns]
    if missing:
        raise InputError(f"a sweep of {kernel.name} has no {', '.join(missing)}: no head maps")
    x, y = choose_knobs(kernel, columns, x, y)
    xv, xi, xb = cells(columns[x])
    yv, yi, yb = cells(columns[y])
    runs, p_div, med = grid_cells(columns["head"], HEADS, xi, yi, xv.size, yv.size,
                                  columns["diverged"], columns["max_error_deg"])
    point = None
    if x in kernel.published and y in kernel.published:
        point = (kernel.published[x], kernel.published[y])
    return Maps(x, y, xv, yv, (xb, yb), runs, p_div, med, point, kernel.published_label)


def read(out_dir: Path) -> tuple[Kernel, dict[str, np.ndarray]]:
    """The kernel and the table's columns of the sweep in ``out_dir``."""
    import pyarrow.parquet as pq

    out_dir = Path(out_dir)
    table, spec_path = out_dir / "results.parquet", out_dir / "spec.toml"
    if not table.is_file() or not spec_path.is_file():
        raise InputError(f"{out_dir} holds no finished sweep (results.parquet and spec.toml)")
    spec = sweep_spec.read(spec_path)
    try:
        t = pq.read_table(table)
    except Exception as exc:  # noqa: BLE001 (pyarrow's errors for a torn or foreign file)
        reason = " ".join(str(exc).split())[:100]
        raise InputError(f"{table}: not a readable Parquet table ({reason}); rerun the sweep "
                         f"with --resume to rebuild it from its parts") from None
    kernel = spec.kernel_value
    expected = ["run", *kernel.knobs, "seed", *kernel.metrics, "diverged"]
    lacking = [c for c in expected if c not in t.column_names]
    if lacking:
        raise InputError(f"{table}: lacks the column(s) {', '.join(lacking)} of a "
                         f"{kernel.name} sweep ({spec_path}); not this spec's table")
    columns = {name: t.column(name).to_numpy(zero_copy_only=False) for name in t.column_names}
    for name in (*[k for k in kernel.knobs if not kernel.knobs[k].choices], *kernel.metrics):
        if columns[name].dtype.kind != "f":
            raise InputError(f"{table}: column {name} holds {columns[name].dtype}, not numbers")
    if columns["diverged"].dtype != bool:
        raise InputError(f"{table}: column diverged holds {columns['diverged'].dtype}, not "
                         "true/false")
    return kernel, columns


def write(out_dir: Path, x: str | None = None, y: str | None = None,
          path: Path | None = None) -> tuple[Path, Maps | CategoryMaps]:
    """Read the sweep in ``out_dir``, compute its maps and write them as a PNG (default
    ``out_dir/maps-X-Y.png``); a kernel without a ``head`` knob gets
    :mod:`verticality.sweep.category_maps`' maps instead."""
    from verticality.sweep.distribute import require_engine

    require_engine()
    kernel, columns = read(out_dir)
    if "head" not in kernel.knobs:  # no heads to compare: maps per value of its category
        from verticality.sweep import category_maps

        return category_maps.write(kernel, columns, out_dir, x, y, path)
    maps = compute(kernel, columns, x, y)
    path = Path(path) if path is not None else Path(out_dir) / f"maps-{maps.x}-{maps.y}.png"
    return figure(maps, path, f"{kernel.name}: {columns['run'].size} runs"), maps


def figure(maps: Maps, path: Path, title: str) -> Path:
    """Six panels: divergence probability and median max error for each head, run counts per
    cell, and the fixed/stabilized ratio."""
    from matplotlib.colors import LogNorm, Normalize

    from verticality.core import plots

    fig, axes = plots.new_figure(2, 3, width=13.0, height_per_row=3.6, sharex=False)
    positive = [a[np.isfinite(a) & (a > 0)] for a in (*maps.median_max_error_deg.values(),)]
    pos = np.concatenate(positive) if positive else np.array([])
    err_norm = LogNorm(pos.min(), max(pos.max(), pos.min() * 1.01)) if pos.size else Normalize()
    ratio = maps.ratio
    rpos = ratio[np.isfinite(ratio) & (ratio > 0)]
    ratio_norm = (LogNorm(rpos.min(), max(rpos.max(), rpos.min() * 1.01)) if rpos.size
                  else Normalize())
    panels = [
        (axes[0, 0], maps.p_diverged["fixed"], "P(diverged), fixed head", Normalize(0, 1),
         "magma_r"),
        (axes[0, 1], maps.p_diverged["stabilized"], "P(diverged), stabilized head", Normalize(0, 1),
         "magma_r"),
        (axes[0, 2], maps.runs["fixed"] + maps.runs["stabilized"], "runs per cell", Normalize(),
         "Greys"),
        (axes[1, 0], maps.median_max_error_deg["fixed"], "median max error (°), fixed head",
         err_norm, "viridis"),
        (axes[1, 1], maps.median_max_error_deg["stabilized"],
         "median max error (°), stabilized head", err_norm, "viridis"),
        (axes[1, 2], ratio, "ratio fixed / stabilized (median max error)", ratio_norm, "cividis"),
    ]
    for ax, values, label, norm, cmap in panels:
        im = ax.imshow(np.ma.masked_invalid(values), origin="lower", aspect="auto", norm=norm,
                       cmap=cmap, interpolation="nearest")
        fig.colorbar(im, ax=ax)
        ax.set_title(label, fontsize=9)
        _axis(ax.set_xticks, ax.set_xticklabels, maps.x_values)
        _axis(ax.set_yticks, ax.set_yticklabels, maps.y_values)
        ax.set_xlabel(maps.x + (" (bin centre)" if maps.binned[0] else ""))
        ax.set_ylabel(maps.y + (" (bin centre)" if maps.binned[1] else ""))
        if maps.published is not None:
            px, py = (_position(maps.x_values, maps.published[0]),
                      _position(maps.y_values, maps.published[1]))
            ax.plot([px], [py], marker="*", color="red", markersize=12, linestyle="none",
                    label=maps.published_label)
    if maps.published is not None:
        axes[1, 2].legend(loc="upper left", fontsize=7)
    fig.suptitle(title)
    return plots.save(fig, path)


def _axis(set_ticks, set_labels, values) -> None:
    step = max(1, int(np.ceil(values.size / 8)))
    idx = np.arange(0, values.size, step)
    set_ticks(idx)
    set_labels([f"{v:.3g}" for v in values[idx]], fontsize=7)


def _position(values: np.ndarray, v: float) -> float:
    """Where ``v`` falls on a cell axis whose cell ``i`` is centred at ``values[i]``."""
    if values.size == 1:
        return 0.0
    return float(np.interp(v, values, np.arange(values.size)))
