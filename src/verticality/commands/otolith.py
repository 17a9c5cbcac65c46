"""``verticality otolith MOTION.csv --out OUT.csv [--model medial|lateral] [--param NAME=VALUE]...``

What the otolith pendulum(s) report for a recorded head motion (file formats in
:mod:`verticality.io.motion` and docs/simulation.md). Defaults: the P13 plant (m = 0.05 kg,
l = 0.06 m, J_S = m·diag(l², l², l²/20) about the pivot, β = 0.001 N·m·s); the lateral model's
pivots at ±r along the head's y, r = 0.05 m.
"""

from __future__ import annotations

import math
from pathlib import Path

from verticality.errors import InputError

PARAM_NAMES = ("m", "l", "beta", "Jxx", "Jyy", "Jzz", "r")


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
    p.add_argument("--model", choices=("medial", "lateral"), default="medial")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help=f"override a parameter: {', '.join(PARAM_NAMES)} (SI units; J about the "
                        "pivot, z along the arm; r: lateral pivot offset)")
    p.set_defaults(func=run)


def parse_params(items: list[str], model: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise InputError(f"--param {item!r}: expected NAME=VALUE")
        if name not in PARAM_NAMES:
            raise InputError(f"--param {name}: unknown name; choose from {', '.join(PARAM_NAMES)}")
        try:
            v = float(value)
        except ValueError:
            raise InputError(f"--param {name}: not a number: {value!r}") from None
        if not math.isfinite(v):
            raise InputError(f"--param {name}: {value} is not finite")
        if name in ("m", "l", "Jxx", "Jyy", "Jzz") and v <= 0.0:
            raise InputError(f"--param {name}: must be positive, not {v:g}")
        if name == "beta" and v < 0.0:
            raise InputError(f"--param beta: must not be negative, not {v:g}")
        if name == "r" and model != "lateral":
            raise InputError("--param r applies to the lateral model only (use --model lateral)")
        out[name] = v
    return out


def pendulums_for(model: str, overrides: dict[str, float]):
    """The pendulum parameter sets (and column suffixes) of the model with the overrides."""
    import jax.numpy as jnp

    from verticality.params import LATERAL_R_M, PendulumParams

    m = overrides.get("m", 0.05)
    l = overrides.get("l", 0.06)
    J = jnp.array([overrides.get("Jxx", m * l * l), overrides.get("Jyy", m * l * l),
                   overrides.get("Jzz", m * l * l / 20.0)])
    base = PendulumParams(m_kg=m, l_m=l, J_pivot_S=J, beta_Nms=overrides.get("beta", 0.001))
    if model == "medial":
        return (base.resolved(),), ("",)
    r = overrides.get("r", LATERAL_R_M)
    return ((base._replace(pivot_H_m=jnp.array([0.0, r, 0.0])).resolved(),
             base._replace(pivot_H_m=jnp.array([0.0, -r, 0.0])).resolved()), ("_left", "_right"))


def run(args) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from verticality import simulation
    from verticality.io.motion import read_motion_csv, write_otolith_csv
    from verticality.io.output import check_writable_file

    check_writable_file(args.out, "--out")
    overrides = parse_params(args.param, args.model)
    rec = read_motion_csv(args.motion)
    pendulums, suffixes = pendulums_for(args.model, overrides)
    err = Console(stderr=True)
    with Progress(TextColumn("otolith"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        task = progress.add_task("integrating", total=None)

        def report(done, total):
            progress.update(task, completed=done, total=total)

        s_H, phi = simulation.otolith_replay(rec.t_s, rec.q_I_H_wxyz, rec.omega_H_rad_s,
                                             rec.a_I_m_s2, pendulums, progress=report)
    write_otolith_csv(args.out, rec.t_s, s_H, phi, suffixes)
    return 0
