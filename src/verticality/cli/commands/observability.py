"""``verticality observability [--model …] [--motion …] [--control …] [--chart …] [--json]``.

The generic-rank observability test of the otolith models, one row per case of F Tables 3.1/3.2:
model, motion, control, published answer, ours, and why (read from the unobservable directions).
"""

from __future__ import annotations

import json
import sys

from rich.console import Console
from rich.table import Table

from verticality.analysis.otolith_observability import CONTROLS, MODELS, MOTIONS, OUTPUTS
from verticality.cli.commands import print_table


def register(sub):
    p = sub.add_parser("observability",
                       help="nonlinear observability of the head's tilt from the otoliths (F §3.1)")
    p.add_argument("--model", choices=MODELS, help="only this model (default both)")
    p.add_argument("--motion", choices=MOTIONS, help="only this motion (default both)")
    p.add_argument("--control", choices=CONTROLS, help="only this head control (default all)")
    p.add_argument("--chart", choices=("tangent", "ambient"), default="tangent",
                   help="tangent: rotations on SO(3) (default); ambient: matrix entries as free "
                        "variables (the published formulation for the medial table)")
    p.add_argument("--output", choices=OUTPUTS, default="thesis",
                   help="otolith angles from the third row of R_HS as in F 2.8-2.9 (default) or "
                        "from its third column (the pendulum axis in the head frame)")
    p.add_argument("--params", choices=("generic", "p13"), default="generic",
                   help="parameter values for the rank test (default: O(1) time scales)")
    p.add_argument("--points", type=int, default=2, help="random points per case (default 2)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.set_defaults(func=run)


def _yn(v) -> str:
    return "–" if v is None else ("yes" if v else "no")


def run(args) -> int:
    from verticality.analysis import otolith_observability as oo
    from verticality.report.entries import to_jsonable

    report = oo.table(model=args.model, motion=args.motion, control=args.control,
                      chart=args.chart, params=args.params, output=args.output,
                      points=args.points)
    if args.json:
        json.dump(to_jsonable(report), sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    table = Table(title=f"Observability of the head's tilt from the otoliths ({args.chart} chart, "
                        f"{args.output} outputs, {args.params} parameters)")
    for col in ("model", "motion", "control", "published tilt/acc", "ours tilt/acc", "", "why"):
        table.add_column(col, no_wrap=col in ("model", "motion", "control"))
    rows = report["rows"]
    for r in rows:
        table.add_row(r["model"], r["motion"], r["control"],
                      f"{_yn(r['published_orientation_observable'])} / "
                      f"{_yn(r['published_acceleration_identifiable'])}",
                      f"{_yn(r['orientation_observable'])} / {_yn(r['acceleration_identifiable'])}",
                      "=" if r["agrees"] else "≠", r["why"])
    console = Console()
    print_table(table, console)
    if any("[1]" in r["why"] for r in rows):
        console.print(oo.FREE_ENTRY_NOTE)
    console.print(f"agreement with F Tables 3.1/3.2: {report['agreement']}/{report['cases']}"
                  f"  ({report['wall_s']:.1f} s)")
    return 0
