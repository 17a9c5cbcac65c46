"""``verticality ambiguity MOTION.csv [--out OUT.csv] [--plot P.png] [--json] [--otolith f452|p13]``

The head acceleration the otoliths would indicate for a recorded head motion if the head were
taken as upright (F 3.14–3.15), and its error against the true acceleration:
:func:`verticality.analysis.ambiguity_replay.report`.
"""

from __future__ import annotations

import json
from pathlib import Path

from verticality.analysis.ambiguity_replay import OTOLITHS


def register(sub):
    p = sub.add_parser(
        "ambiguity",
        help="acceleration the otoliths indicate under the upright assumption, and its error",
        description="Replay the otolith under the head motion of MOTION.csv (columns "
                    "t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az; see docs/simulation.md), read it as an "
                    "accelerometer on an upright head (F 3.14–3.15, a_z from the saccule) and "
                    "compare with the true head-frame acceleration (docs/ambiguity.md).",
    )
    p.add_argument("motion", type=Path, metavar="MOTION.csv")
    p.add_argument("--out", type=Path, metavar="OUT.csv",
                   help="write t, ax/ay/az_true, ax/ay_upright, ax/ay_error, tilt_x/y_deg, phi_x/y")
    p.add_argument("--plot", type=Path, metavar="P.png", help="write a figure")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--otolith", choices=OTOLITHS, default="f452",
                   help="f452: critically damped, 300 Hz (F §4.5.2; default); p13: P13's pendulum")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.analysis.ambiguity_replay import report
    from verticality.io.paths import check_input_file, check_paths

    check_input_file(args.motion)
    check_paths({"--out": args.out, "--plot": args.plot}, [args.motion], figures=["--plot"])
    summary = report(args.motion, args.out, args.plot, args.otolith)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(f"{summary['samples']} samples, {summary['duration_s']:.3f} s, "
          f"otolith {summary['otolith']}")
    for k, plane in (("x", "y"), ("y", "x")):
        print(f"a_{k}: rms true {summary['rms_true_acceleration_m_s2'][k]:.4g} m/s², "
              f"rms error of the upright reading {summary['rms_error_m_s2'][k]:.4g} m/s², "
              f"max {summary['max_abs_error_m_s2'][k]:.4g} m/s² (max |Θ{plane}| "
              f"{summary['max_abs_tilt_deg'][plane]:.3g}°: a still head there reads "
              f"{summary['still_head_error_at_max_tilt_m_s2'][k]:.3g} m/s²)")
    return 0
