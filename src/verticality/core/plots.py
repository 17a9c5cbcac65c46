"""Figure helpers shared by experiments and commands (matplotlib, non-interactive backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def new_figure(nrows: int = 1, ncols: int = 1, *, width: float = 8.0, height_per_row: float = 2.6,
               sharex: bool = True):
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, height_per_row * nrows + 0.6),
                             sharex=sharex, squeeze=False)
    return fig, axes


def save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def published_line(ax, value: float, label: str = "published", **kw):
    """A dashed horizontal line at a published value, labelled."""
    kw.setdefault("color", "0.3")
    kw.setdefault("linestyle", "--")
    kw.setdefault("linewidth", 1.0)
    ax.axhline(value, label=label, **kw)
