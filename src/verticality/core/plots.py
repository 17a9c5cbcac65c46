"""Figure helpers shared by experiments and commands.

Figures are :class:`matplotlib.figure.Figure` objects made without pyplot, so that importing this
module (or any that uses it) leaves matplotlib's backend and pyplot's figure list alone: a
caller's interactive session is untouched, and a headless run needs no backend switch (saving a
PNG renders with Agg whatever the backend).
"""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure


def new_figure(nrows: int = 1, ncols: int = 1, *, width: float = 8.0, height_per_row: float = 2.6,
               sharex: bool = True):
    fig = Figure(figsize=(width, height_per_row * nrows + 0.6))
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=False)
    return fig, axes


def save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path


def published_line(ax, value: float, label: str = "published", **kw):
    """A dashed horizontal line at a published value, labelled."""
    kw.setdefault("color", "0.3")
    kw.setdefault("linestyle", "--")
    kw.setdefault("linewidth", 1.0)
    ax.axhline(value, label=label, **kw)
