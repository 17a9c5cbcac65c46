"""``verticality sweep-plot DIR [--x KNOB] [--y KNOB] [--out FILE.png]``: the maps of a finished
sweep (divergence probability, median max error per head, their ratio) as one PNG
(docs/sweep.md)."""

from __future__ import annotations

from pathlib import Path


def register(sub):
    p = sub.add_parser("sweep-plot", help="maps of a finished sweep over two knobs (PNG)")
    p.add_argument("dir", type=Path, metavar="DIR", help="the sweep's output folder")
    p.add_argument("--x", default=None, metavar="KNOB",
                   help="knob along x (default: the numeric knob with the most values)")
    p.add_argument("--y", default=None, metavar="KNOB", help="knob along y (default: the next)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="the figure (default: DIR/maps-X-Y.png)")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.sweep import maps

    path, _ = maps.write(args.dir, args.x, args.y, args.out)
    print(path)
    return 0
