"""``verticality otolith MOTION.csv --out OUT.csv [--model medial|lateral] [--param NAME=VALUE]...``

What the otolith pendulum(s) report for a recorded head motion (file formats in
:mod:`verticality.io.motion` and docs/simulation.md):
:func:`verticality.simulation.closed_loop.otolith_replay` of the pendula of
:func:`verticality.models.otolith_presets.otolith_pendula` (the P13 plant, m = 0.05 kg, l = 0.06 m,
J_S = m·diag(l², l², l²/20) about the pivot, β = 0.001 N·m·s; the lateral model's pivots at ±r
along the head's y, r = 0.05 m; NAME=VALUE overrides, read into values by
:func:`verticality.cli.name_values.parse_name_values`).
"""

from __future__ import annotations

from pathlib import Path

from verticality.models.otolith_presets import OTOLITH_MODELS, OTOLITH_PARAM_NAMES


def register(sub):
    p = sub.add_parser(
        "otolith",
        help="otolith pendulum response (s_H, φ_x, φ_y) to a recorded head motion",
        description="Integrate the otolith pendulum(s) under the head motion of MOTION.csv "
                    "(columns t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az; see docs/simulation.md) and write "
                    "t,sx,sy,sz,phi_x,phi_y on the same rows.",
    )
    p.add_argument("motion", type=Path, metavar="MOTION.csv")
    p.add_argument("--out", type=Path, required=True, metavar="OUT.csv")
    p.add_argument("--model", choices=OTOLITH_MODELS, default="medial")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help=f"override a parameter: {', '.join(OTOLITH_PARAM_NAMES)} "
                        "(SI units; J about the pivot, z along the arm; r: lateral pivot offset)")
    p.set_defaults(func=run)


def run(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from verticality.cli.name_values import parse_name_values
    from verticality.io.motion import read_motion_csv, write_otolith_csv
    from verticality.io.paths import check_input_file, check_paths
    from verticality.models.otolith_presets import otolith_pendula
    from verticality.simulation import closed_loop as simulation

    check_input_file(args.motion)
    check_paths({"--out": args.out}, [args.motion])
    pendula, suffixes = otolith_pendula(
        args.model, parse_name_values(args.param, OTOLITH_PARAM_NAMES))
    rec = read_motion_csv(args.motion)
    err = Console(stderr=True)
    with Progress(TextColumn("otolith"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        task = progress.add_task("integrating", total=None)

        def report(done, total):
            progress.update(task, completed=done, total=total)

        s_H, phi = simulation.otolith_replay(rec.t_s, rec.q_I_H_wxyz, rec.omega_H_rad_s,
                                             rec.a_I_m_s2, pendula, progress=report)
    write_otolith_csv(args.out, rec.t_s, s_H, phi, suffixes)
    return 0
