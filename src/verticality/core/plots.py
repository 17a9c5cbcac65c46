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


def save(fig, path: Path, option: str = "--plot", root=None) -> Path:
    """Draw ``fig`` into ``path`` (its format from the extension) through
    :func:`verticality.io.paths.write_atomic`: complete or not there, never through a link, its
    permissions kept; ``root``, the folder the user named, must hold it (links followed)."""
    from verticality.io.paths import write_atomic

    path = Path(path)
    fig.tight_layout()
    ext = path.suffix.lower().removeprefix(".") or None  # the temporary name has another one
    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120, format=ext), option, root)


def published_line(ax, value: float, label: str = "published", **kw):
    """A dashed horizontal line at a published value, labelled."""
    kw.setdefault("color", "0.3")
    kw.setdefault("linestyle", "--")
    kw.setdefault("linewidth", 1.0)
    ax.axhline(value, label=label, **kw)
