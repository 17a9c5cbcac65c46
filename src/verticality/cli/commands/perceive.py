"""``verticality perceive MOTION.csv --model merfeld|laurens [--preset NAME] [--param NAME=VALUE]...
[--otolith unity|pendulum] [--canal high-pass|torsion] [--out OUT.csv] [--plot OUT.png] [--json]``

What a vestibular perception model perceives for a head motion (MOTION.csv as `otolith` reads it,
or a BROAD-layout recording): :func:`verticality.perception.perceive.perceive_file` (models, presets
and sensors in docs/perception.md). The model's name, preset and ``NAME=VALUE`` strings are read
here into the parameter value the library takes.
"""

from __future__ import annotations

import json
from pathlib import Path


def register(sub):
    from verticality.perception.params import PRESETS
    from verticality.perception.perceive import CANALS, MODELS, OTOLITHS

    presets = "; ".join(f"{m}: {', '.join(p)}" for m, p in PRESETS.items())
    p = sub.add_parser(
        "perceive",
        help="perceived tilt, rotation, acceleration and velocity of a head motion "
             "(Merfeld–Zupan observer or Laurens–Angelaki Kalman model)",
        description="Run a vestibular perception model on the head motion of MOTION.csv "
                    "(columns t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az; see docs/simulation.md) and print a "
                    "summary; --out writes the perceived quantities on the same rows.",
    )
    p.add_argument("motion", type=Path, metavar="MOTION.csv")
    p.add_argument("--model", choices=MODELS, default="merfeld")
    p.add_argument("--preset", default=None, help=f"parameter preset ({presets})")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="override one parameter of the preset (names in docs/perception.md)")
    p.add_argument("--otolith", choices=OTOLITHS, default="unity")
    p.add_argument("--canal", choices=CANALS, default="high-pass")
    p.add_argument("--out", type=Path, default=None, metavar="OUT.csv")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.cli.name_values import parse_name_values
    from verticality.io.paths import check_input_file, check_paths, check_written
    from verticality.perception.params import PRESETS, perception_params
    from verticality.perception.perceive import perceive_file

    check_input_file(args.motion)
    check_paths({"--out": args.out, "--plot": args.plot}, [args.motion], figures=["--plot"])
    names = next(iter(PRESETS[args.model].values()))._fields
    params = perception_params(args.model, args.preset,
                               parse_name_values(args.param, names, allow_inf=True))
    summary = {"preset": args.preset, **perceive_file(args.motion, params, args.otolith,
                                                      args.canal, args.out, args.plot)}
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    f = summary["final"]
    print(f"{args.model} ({summary['preset'] or 'default preset'}, otolith {args.otolith}, "
          f"canal {args.canal}): {summary['rows']} rows, {summary['duration_s']:.6g} s")
    print(f"  final perceived tilt {f['tilt_deg']:.3f}° (actual {f['tilt_true_deg']:.3f}°), "
          f"max tilt error {summary['max_tilt_error_deg']:.3f}°")
    print("  final perceived ω (°/s) " + ", ".join(f"{v:.3f}" for v in f["omega_deg_s"])
          + "; a (m/s²) " + ", ".join(f"{v:.3f}" for v in f["a_m_s2"])
          + "; v (m/s) " + ", ".join(f"{v:.3f}" for v in f["v_m_s"]))
    for key in ("out", "plot"):
        if summary[key]:
            check_written(summary[key], f"--{key}")
            print(f"  wrote {summary[key]}")
    return 0
