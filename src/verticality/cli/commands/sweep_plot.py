"""``verticality sweep-plot DIR [--x KNOB] [--y KNOB] [--curve KNOB] [--out FILE.png]``: the maps
of a finished sweep (divergence probability, median max error per head, their ratio) as one PNG,
or with ``--curve`` the divergence rate along one knob per head (or per value of a kernel's
categorical knob, e.g. the feed of ``ambiguity-walking``), its table printed, or with ``--json``
the same numbers as one JSON object (docs/sweep.md)."""

from __future__ import annotations

import json
import sys
from pathlib import Path


def register(sub):
    p = sub.add_parser("sweep-plot", help="maps of a finished sweep over two knobs (PNG)")
    p.add_argument("dir", type=Path, metavar="DIR", help="the sweep's output folder")
    p.add_argument("--x", default=None, metavar="KNOB",
                   help="knob along x (default: the numeric knob with the most values)")
    p.add_argument("--y", default=None, metavar="KNOB", help="knob along y (default: the next)")
    p.add_argument("--curve", default=None, metavar="KNOB",
                   help="instead of the maps: the divergence rate (95 %% intervals) and median max "
                        "error along KNOB per head (per value of the categorical knob for a "
                        "kernel without heads), drawn and printed as a table")
    p.add_argument("--json", action="store_true",
                   help='with --curve: print {"knob", "group", "metric", "values", "groups": '
                        '{GROUP: {"runs", "diverged", "p_low", "p_high", "median"}}, "figure"} '
                        "instead of the table")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="the figure (default: DIR/maps-X-Y.png or DIR/curve-KNOB.png)")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.core.errors import InputError
    from verticality.io.paths import check_paths
    from verticality.report.entries import to_jsonable
    from verticality.sweep import curves, maps

    if args.out is not None:  # never over the sweep's own files (the table, the spec, a part)
        inputs = [p for p in Path(args.dir).rglob("*") if p.is_file()] \
            if Path(args.dir).is_dir() else []
        check_paths({"--out": args.out}, inputs, figures=["--out"])
    if args.curve is not None:
        if args.x is not None or args.y is not None:
            raise InputError("--curve draws one knob; --x and --y are for the maps")
        path, curve = curves.write(args.dir, args.curve, args.out)
        if args.json:
            json.dump(to_jsonable(curves.as_dict(curve) | {"figure": str(path)}), sys.stdout,
                      indent=2)
            sys.stdout.write("\n")
            return 0
        print("\n".join(curves.table(curve)))
    elif args.json:
        raise InputError("--json: the maps are a figure; with --curve KNOB the curve's numbers")
    else:
        path, _ = maps.write(args.dir, args.x, args.y, args.out)
    print(path)
    return 0
