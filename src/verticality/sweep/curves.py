"""A sweep's divergence rate along one knob, per head (or per value of a categorical knob), with
its uncertainty.

For each value of the knob and each head (``fixed``, ``stabilized``): the number of runs, the
number that **diverged** and their share with its 95 % **Wilson score interval**
(:func:`wilson`; it stays inside [0, 1] and is not degenerate at 0 or n divergences, unlike the
normal approximation), and the **median max error** of the runs that did not diverge (NaN when all
did). A kernel without a ``head`` knob (``ambiguity-walking``) is split instead by its first
categorical knob (:func:`verticality.sweep.category_maps.category_of`, e.g. the feed), and the
median is of its first metric. Unlike the maps (:mod:`verticality.sweep.maps`) the knob is not
binned: a curve is for a knob the design sets to a few values, such as ``error_level``.

:func:`compute` makes the curve from the table's columns; :func:`write` reads a finished sweep and
writes ``DIR/curve-KNOB.png``; :func:`table` is the curve as Markdown rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.sweep import category_maps
from verticality.sweep.kernels import Kernel
from verticality.sweep.maps import HEADS

Z_95 = 1.959963984540054  # the standard normal's 97.5 % quantile
MAX_VALUES = 30
# a published threshold on a knob of a kernel: (kernel, knob) → (value, label)
MARKS = {("newton-lissajous", "error_level"):
         (0.15, "P11: the fixed head's observer diverged beyond 15 %")}


def wilson(k: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a proportion ``k / n`` (two-sided, ``z`` = 1.96 for 95 %)."""
    if n <= 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # at k = 0 (k = n) the lower (upper) bound is 0 (1) exactly; rounding would leave ~1e-18
    return (0.0 if k == 0 else centre - half), (1.0 if k == n else centre + half)


@dataclass(frozen=True)
class Curve:
    """Per group (a value of the column ``group``: the heads, or a categorical knob's values; the
    keys of the dicts), arrays over ``values`` (the knob's distinct values)."""

    knob: str
    values: np.ndarray
    group: str  # the column that splits the runs ("head", or a categorical knob)
    groups: tuple[str, ...]
    metric: str  # the metric whose median is given ("max_error_deg" for heads)
    runs: dict[str, np.ndarray]
    diverged: dict[str, np.ndarray]  # counts
    p_low: dict[str, np.ndarray]  # the 95 % Wilson interval of the share diverged
    p_high: dict[str, np.ndarray]
    median: dict[str, np.ndarray]  # of ``metric``, over the runs that did not diverge
    mark: tuple[float, str] | None = None  # a published threshold on the knob

    def p_diverged(self, group: str) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.diverged[group] / self.runs[group]


def grouping(kernel: Kernel, columns: dict[str, np.ndarray]) -> tuple[str, tuple[str, ...], str]:
    """How a sweep of ``kernel`` is split: ``(column, its values, metric)`` — the heads and the max
    error for a kernel with a ``head`` knob, else its first categorical knob's values (those
    present in the table) and its first metric."""
    if "head" not in kernel.knobs:
        return category_maps.split(kernel, columns)
    missing = [c for c in ("head", "diverged", "max_error_deg") if c not in columns]
    if missing:
        raise InputError(f"a sweep of {kernel.name} has no {', '.join(missing)}: no head curve")
    return "head", HEADS, "max_error_deg"


def compute(kernel: Kernel, columns: dict[str, np.ndarray], knob: str) -> Curve:
    """The curve along ``knob`` of the table ``columns`` (name → array) of a sweep of ``kernel``."""
    column, groups, metric = grouping(kernel, columns)
    numeric = [k for k, v in kernel.knobs.items() if not v.choices]
    if knob not in numeric:
        raise InputError(f"cannot draw a curve over {knob!r}; the numeric knobs of {kernel.name} "
                         f"are {', '.join(numeric)}")
    x = np.asarray(columns[knob], dtype=np.float64)
    values = np.unique(x)
    if values.size > MAX_VALUES:
        raise InputError(f"{knob} takes {values.size} values in this sweep (more than "
                         f"{MAX_VALUES}): a curve is for a knob set to a few values; map it "
                         "instead (sweep-plot --x)")
    head = np.asarray(columns[column]).astype(str)
    div = np.asarray(columns["diverged"], dtype=bool)
    err = np.asarray(columns[metric], dtype=np.float64)
    runs, n_div, lo, hi, med = {}, {}, {}, {}, {}
    for h in groups:
        n = np.array([np.sum((head == h) & (x == v)) for v in values], dtype=np.int64)
        k = np.array([np.sum((head == h) & (x == v) & div) for v in values], dtype=np.int64)
        kept = [err[(head == h) & (x == v) & ~div] for v in values]
        bounds = [wilson(int(a), int(b)) for a, b in zip(k, n, strict=True)]
        runs[h], n_div[h] = n, k
        lo[h] = np.array([b[0] for b in bounds])
        hi[h] = np.array([b[1] for b in bounds])
        med[h] = np.array([np.median(e) if e.size else np.nan for e in kept])
    return Curve(knob, values, column, groups, metric, runs, n_div, lo, hi, med,
                 MARKS.get((kernel.name, knob)))


def table(curve: Curve) -> list[str]:
    """The curve as Markdown table lines: per value, each group's diverged/runs (share, 95 %
    interval) and the median of its metric (max error for heads) over the runs that did not
    diverge."""
    what = "median max error (°)" if curve.metric == "max_error_deg" else f"median {curve.metric}"
    lines = [f"| {curve.knob} | " + " | ".join(f"{h}: diverged | {h}: {what}"
                                                for h in curve.groups) + " |",
             "|---" * (1 + 2 * len(curve.groups)) + "|"]
    for i, v in enumerate(curve.values):
        cells = []
        for h in curve.groups:
            n, k = int(curve.runs[h][i]), int(curve.diverged[h][i])
            share = (f"{k}/{n} ({100 * k / n:.1f} %, {100 * curve.p_low[h][i]:.1f}–"
                     f"{100 * curve.p_high[h][i]:.1f} %)") if n else "–"
            m = curve.median[h][i]
            cells += [share, f"{m:.3g}" if np.isfinite(m) else "–"]
        lines.append(f"| {v:g} | " + " | ".join(cells) + " |")
    return lines


def as_dict(curve: Curve) -> dict:
    """The numbers of :func:`table` as data: per group, arrays over ``values``."""
    keys = ("runs", "diverged", "p_low", "p_high", "median")
    return {"knob": curve.knob, "group": curve.group, "metric": curve.metric,
            "values": curve.values,
            "groups": {g: {k: getattr(curve, k)[g] for k in keys} for g in curve.groups}}


def write(out_dir: Path, knob: str, path: Path | None = None) -> tuple[Path, Curve]:
    """Read the sweep in ``out_dir``, compute its curve along ``knob`` and draw it (default
    ``out_dir/curve-KNOB.png``)."""
    from verticality.sweep import maps
    from verticality.sweep.distribute import require_engine

    require_engine()
    kernel, columns = maps.read(out_dir)
    curve = compute(kernel, columns, knob)
    path = Path(path) if path is not None else Path(out_dir) / f"curve-{knob}.png"
    return figure(curve, path, f"{kernel.name}: {columns['run'].size} runs"), curve


def figure(curve: Curve, path: Path, title: str) -> Path:
    """Two panels along the knob: the share diverged with its 95 % intervals, and the median of
    the metric (max error for heads) over the runs that did not diverge; one line per group, the
    published threshold marked."""
    from verticality.core import plots

    fig, axes = plots.new_figure(1, 2, width=11.0, height_per_row=3.8, sharex=False)
    axes = axes[0]
    heads = curve.group == "head"
    colours = {"fixed": "tab:red", "stabilized": "tab:blue"}
    label = (lambda h: f"{h} head") if heads else (lambda h: f"{curve.group} {h}")  # noqa: E731
    for n_group, h in enumerate(curve.groups):
        if not np.any(curve.runs[h]):
            continue
        p = curve.p_diverged(h)
        axes[0].errorbar(curve.values, 100 * p,
                         yerr=100 * np.clip(np.vstack([p - curve.p_low[h], curve.p_high[h] - p]),
                                            0.0, None),
                         marker="o", capsize=3, color=colours.get(h, f"C{n_group}"),
                         label=label(h))
        axes[1].plot(curve.values, curve.median[h], marker="o",
                     color=colours.get(h, f"C{n_group}"), label=label(h))
    axes[0].set_ylabel("runs diverged (%, 95 % Wilson interval)")
    axes[1].set_ylabel(("median max error (°)" if heads else f"median {curve.metric}")
                       + ", runs not diverged")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.set_xlabel(curve.knob)
        if curve.mark is not None:
            ax.axvline(curve.mark[0], color="grey", linestyle="--", label=curve.mark[1])
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(title)
    return plots.save(fig, path)
