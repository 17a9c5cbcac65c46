"""Observability of the head's tilt from the otoliths: the 16 cases of F Tables 3.1 and 3.2.

Models: the :class:`~verticality.models.otolith_head.OtolithHead` values of the package, consumed
unchanged (:func:`~verticality.models.otolith_head.medial`, one pendulum at the head centre, F 2.7;
:func:`~verticality.models.otolith_head.lateral`, two pendula at ``±r`` on the head's y axis,
F 2.12, ``r = 0.05`` m). ``form="simplified"`` (default) is F 2.7 / 2.12:
``PendulumParams.simplified()`` (no gyroscopic and no Euler term; the centripetal term of the
lateral model kept) and ``HeadParams(gyroscopic=0)`` (the head ``J_H ω̇_H = τ``); ``form="full"``
keeps every term.

Outputs: the model's output, the otolith angles of F 2.8–2.9 / 2.13–2.16 (``output="thesis"``);
``output="axis"`` reads the same angles from the pendulum's axis in the head frame instead.

Around the model, the problem declares what F §3.1.2 makes unknown or known, through the model's
input ``HeadInput(τ_H, a_I)``::

    τ_H = θ.tau_H + u.tau_u + θ.stab · global_stabilizer(R_IH, ω_H)      a_I = R_IH θ.a_H

Motion ``rot``: ``a = 0``; ``rot+trans``: ``H a`` a constant unknown (F §3.1.2 defines the
head-frame acceleration as a symbolic parameter). Control: ``zero`` (τ = 0), ``unknown`` (τ a
constant unknown parameter), ``known`` (τ a known input with free derivatives, not stabilized),
``stabilized`` (the feedback of F 2.20–2.21,
:func:`verticality.simulation.control.global_stabilizer`: the stabilizing sign,
``τ = K_p Σ_i e_i × (R_IHᵀ e_i) − K_d ω_H``; the sign does not change the generic rank).

Quantities asked: ``tilt`` = ``R_IHᵀ e3`` (gravity's up direction in the head frame, which fixes
Θx and Θy of F 3.8–3.9; two degrees of freedom on SO(3)); ``acceleration`` = ``H a``; also
``torque`` (for the ``unknown`` control) and ``heading`` = ``R_IH e1`` (the head's yaw).

Parameters: the rank is a structural (generic) property, but a float64 rank test is better
conditioned when all the time scales are O(1). ``params="generic"`` (default) uses m = l = 1,
β = 1.5, J_S = (1, 1, 0.3), J_H = (1, 1.2, 0.9), K_p = 2, K_d = 1.5; ``params="p13"`` the P13
plant (m = 0.05 kg, l = 0.06 m, β = 0.001, J_H = 0.125, K_p = 32, K_d = 5). Tests check that both
give the same answers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from verticality.analysis.observability import (
    ObservabilityResult,
    Problem,
    analyze,
    curve_directions,
    random_rotation,
)
from verticality.core import so3
from verticality.core.errors import InputError
from verticality.models import otolith_head, pendulum
from verticality.models.head import HeadInput, HeadState
from verticality.models.params import (
    LATERAL_R_M,
    P13_HEAD,
    P13_KD_NMS_RAD,
    P13_KP_NM_RAD,
    P13_PENDULUM,
    HeadParams,
    PendulumParams,
)
from verticality.simulation.control import global_stabilizer

MODELS = ("medial", "lateral")
MOTIONS = ("rot", "rot+trans")
CONTROLS = ("zero", "unknown", "known", "stabilized")
FORMS = ("simplified", "full")
OUTPUTS = ("thesis", "axis")

E3 = jnp.array([0.0, 0.0, 1.0])

# F Table 3.1 (medial) and Table 3.2 (lateral): (orientation observable, acceleration identifiable).
PUBLISHED = {
    ("medial", "rot", "zero"): (False, None),
    ("medial", "rot", "unknown"): (False, None),
    ("medial", "rot", "known"): (False, None),
    ("medial", "rot", "stabilized"): (True, None),
    ("medial", "rot+trans", "zero"): (False, False),
    ("medial", "rot+trans", "unknown"): (False, False),
    ("medial", "rot+trans", "known"): (False, True),
    ("medial", "rot+trans", "stabilized"): (True, True),
    **{("lateral", m, c): (True, None if m == "rot" else True) for m in MOTIONS for c in CONTROLS},
}


@dataclass(frozen=True)
class PlantParams:
    pendulum: PendulumParams
    head: HeadParams
    kp: float
    kd: float
    r_m: float = LATERAL_R_M


def plant_params(which: str = "generic", r_m: float = LATERAL_R_M) -> PlantParams:
    if which == "generic":
        pend = PendulumParams(m_kg=1.0, l_m=1.0, J_pivot_S=jnp.array([1.0, 1.0, 0.3]),
                              beta_Nms=1.5).resolved()
        return PlantParams(pend, HeadParams(J_H=jnp.array([1.0, 1.2, 0.9])).resolved(), 2.0, 1.5,
                           r_m)
    if which == "p13":
        return PlantParams(P13_PENDULUM, P13_HEAD, P13_KP_NM_RAD, P13_KD_NMS_RAD, r_m)
    raise InputError(f"params must be 'generic' or 'p13', got {which!r}")


def otolith_model(model: str, *, params: str = "generic", form: str = "simplified",
                  r_m: float = LATERAL_R_M) -> otolith_head.OtolithHead:
    """The medial or lateral :class:`~verticality.models.otolith_head.OtolithHead` value of a
    case."""
    if model not in MODELS:
        raise InputError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    if form not in FORMS:
        raise InputError(f"form must be one of {', '.join(FORMS)}, got {form!r}")
    pp = plant_params(params, r_m)
    pend = pp.pendulum if form == "full" else pp.pendulum.simplified()
    head = pp.head if form == "full" else pp.head._replace(gyroscopic=0.0)
    if model == "medial":
        return otolith_head.medial(pend, head)
    return otolith_head.lateral(pend, head, pp.r_m)


ORDERS = {"medial": 8, "lateral": 6}
"""Highest output derivative used per model: enough for full rank (⌈n/p⌉ with n ≤ 18 coordinates
and p = 2 outputs for the medial model, n ≤ 24 and p = 4 for the lateral one); every case is checked
to have stalled (its rank stopped growing) before that order."""


AMBIENT_ORDERS = {"medial": 15, "lateral": 11}
"""Orders for the free-entry (ambient) formulation: 24–30 (medial) or 36–42 (lateral)
coordinates."""


def axis_angles(model: otolith_head.OtolithHead, x: otolith_head.OtolithHeadState, u=None):
    """The otolith angles read from each pendulum's axis in the head frame (third *column* of
    ``R_HS``, ``−s_H``) instead of the third row as F 2.8–2.9 write them."""
    return jnp.concatenate([pendulum.otolith_angles(pendulum.R_H_S(xp, x.head.R_I_H).T)
                            for xp in x.pendula])


def _leaf_names(n_pendula: int) -> tuple[str, ...]:
    sides = ("S",) if n_pendula == 1 else ("L", "R")
    return tuple(name for k in sides for name in (f"R_I_{k}", f"omega_{k}")) + ("R_I_H", "omega_H")


def build_problem(model: str, *, params: str = "generic", form: str = "simplified",
                  r_m: float = LATERAL_R_M, output: str = "thesis") -> Problem:
    """The observability :class:`Problem` of one model, serving all eight motion/control cases.

    Unknown constants: ``a_H`` (head-frame acceleration), ``tau_H`` (constant unknown torque) and
    the switch ``stab`` (1 = feedback F 2.20 on); known input ``tau_u`` (known torque); they reach
    the model through its input (module docstring). ``output="thesis"``: the model's output, the
    otolith angles of F 2.8–2.9 as written (third *row* of ``R_HS``); ``output="axis"``:
    :func:`axis_angles`. A case fixes the constants that are not unknown in it and zeroes the
    unused input (:func:`case_settings`), so one compiled function serves the eight cases of a
    table.
    """
    if output not in OUTPUTS:
        raise InputError(f"output must be one of {', '.join(OUTPUTS)}, got {output!r}")
    plant = otolith_model(model, params=params, form=form, r_m=r_m)
    pp = plant_params(params, r_m)
    n = len(plant.pendula)

    def input_map(x, u, th):
        R_I_H, w_H = x.head.R_I_H, x.head.omega_H_rad_s
        tau = th["tau_H"] + u["tau_u"] + th["stab"] * global_stabilizer(R_I_H, w_H, pp.kp, pp.kd)
        return HeadInput(tau_H_Nm=tau, a_I_m_s2=R_I_H @ th["a_H"])

    def sample(rng):
        draws = [(random_rotation(rng), rng.standard_normal(3)) for _ in range(n + 1)]
        x = otolith_head.OtolithHeadState(
            pendula=tuple(pendulum.PendulumState(R, w) for R, w in draws[:n]),
            head=HeadState(*draws[n]))
        th = {"a_H": 2.0 * rng.standard_normal(3), "tau_H": rng.standard_normal(3), "stab": 0.0}
        return x, th

    rest = (jnp.eye(3), jnp.zeros(3))
    return Problem(
        model=plant,
        state=otolith_head.OtolithHeadState(
            pendula=tuple(pendulum.PendulumState(*rest) for _ in range(n)), head=HeadState(*rest)),
        unknowns={"a_H": (3,), "tau_H": (3,), "stab": ()}, inputs={"tau_u": (3,)},
        input_map=input_map, output=None if output == "thesis" else axis_angles,
        quantities={"tilt": lambda x, th: x.head.R_I_H.T @ E3,
                    "heading": lambda x, th: x.head.R_I_H[:, 0]},
        sample=sample, leaf_names=_leaf_names(n),
    )


def case_settings(motion: str, control: str) -> tuple[dict, tuple[str, ...]]:
    """``(fixed, zero_inputs)`` of :func:`analyze` for one motion/control case."""
    if motion not in MOTIONS:
        raise InputError(f"motion must be one of {', '.join(MOTIONS)}, got {motion!r}")
    if control not in CONTROLS:
        raise InputError(f"control must be one of {', '.join(CONTROLS)}, got {control!r}")
    fixed: dict = {"stab": 1.0 if control == "stabilized" else 0.0}
    if motion == "rot":
        fixed["a_H"] = 0.0
    if control != "unknown":
        fixed["tau_H"] = 0.0
    zero_inputs = () if control == "known" else ("tau_u",)
    return fixed, zero_inputs


_PROBLEMS: dict = {}


def problem_for(model: str, params: str = "generic", form: str = "simplified",
                r_m: float = LATERAL_R_M, output: str = "thesis") -> Problem:
    key = (model, params, form, float(r_m), output)
    if key not in _PROBLEMS:
        _PROBLEMS[key] = build_problem(model, params=params, form=form, r_m=r_m, output=output)
    return _PROBLEMS[key]


@dataclass(frozen=True)
class CaseResult:
    model: str
    motion: str
    control: str
    orientation_observable: bool
    acceleration_identifiable: bool | None
    published_orientation: bool
    published_acceleration: bool | None
    result: ObservabilityResult
    params: str = "generic"
    output: str = "thesis"
    problem: Problem | None = None  # the problem the result was computed on

    @property
    def agrees(self) -> bool:
        return (self.orientation_observable == self.published_orientation
                and self.acceleration_identifiable == self.published_acceleration)


def analyze_case(model: str, motion: str, control: str, *, chart: str = "tangent",
                 params: str = "generic", form: str = "simplified", points: int = 2,
                 order: int | None = None, seed: int = 0, r_m: float = LATERAL_R_M,
                 output: str = "thesis") -> CaseResult:
    """One row of F Table 3.1/3.2: the generic-rank test of the tilt and of the acceleration."""
    fixed, zero_inputs = case_settings(motion, control)
    prob = problem_for(model, params, form, r_m, output)
    res = analyze(prob, chart=chart, points=points, order=order or ORDERS[model], seed=seed,
                  fixed=fixed, zero_inputs=zero_inputs)
    acc = res.quantities["theta:a_H"].observable if motion == "rot+trans" else None
    pub = PUBLISHED[(model, motion, control)]
    return CaseResult(model, motion, control, res.quantities["tilt"].observable, acc, pub[0],
                      pub[1], res, params, output, prob)


def _turn_pendula(x, Rz):
    return tuple(p._replace(R_I_S=Rz @ p.R_I_S) for p in x.pendula)


def global_yaw(model, x, th, eps):
    """Every frame turned about gravity: ``R_IX → Rz(ε) R_IX``."""
    Rz = so3.rot_z(eps)
    return x._replace(pendula=_turn_pendula(x, Rz),
                      head=x.head._replace(R_I_H=Rz @ x.head.R_I_H)), {}


def head_yaw(model, x, th, eps):
    """The head turned about its own z axis, ``R_IH → R_IH Rz(ε)``, with ``ω_H``, ``a_H`` and
    ``τ`` counter-rotated (``τ → J_H Rz(ε)ᵀ J_H⁻¹ τ``)."""
    Rz = so3.rot_z(eps)
    J = model.head.params.resolved().J_H
    head = HeadState(x.head.R_I_H @ Rz, Rz.T @ x.head.omega_H_rad_s)
    return x._replace(head=head), {"a_H": Rz.T @ th["a_H"], "tau_H": J * (Rz.T @ (th["tau_H"] / J))}


def yaw_conjugation(model, x, th, eps):
    """``R_IH → Rz R_IH Rzᵀ``, ``ω_H → Rz ω_H``, ``a_H → Rz a_H``, pendula ``R_IX → Rz R_IX``."""
    Rz = so3.rot_z(eps)
    head = HeadState(Rz @ x.head.R_I_H @ Rz.T, Rz @ x.head.omega_H_rad_s)
    return x._replace(pendula=_turn_pendula(x, Rz), head=head), {"a_H": Rz @ th["a_H"]}


SYMMETRIES = {"global_yaw": global_yaw, "head_yaw": head_yaw, "yaw_conjugation": yaw_conjugation}


def symmetry_directions(case: CaseResult) -> dict[str, np.ndarray]:
    """The continuous symmetries of the otolith models (:data:`SYMMETRIES`, Rz(ε) the rotation by
    ε about the vertical e3), as directions at the case's test point
    (:func:`~verticality.analysis.observability.curve_directions`).

    ``global_yaw``: every frame turned about gravity.
    ``head_yaw``: the head turned about its own z axis with its angular velocity, torque and
    acceleration counter-rotated (``τ → J_H Rz(ε)ᵀ J_H⁻¹ τ`` so that ω̇_H = J_H⁻¹τ turns with ω_H):
    the inertial angular velocity ``R_IH ω_H``, the head's z axis and ``R_IH a_H`` do not change, so
    neither do the pendulum dynamics nor the otolith angles of F 2.8–2.9 (third row of ``R_HS``),
    but the gravity direction in the head frame turns about the head's z axis.
    ``yaw_conjugation``: global yaw composed with the inverse head yaw. The feedback F 2.20 is
    equivariant under it when ``J_H`` is isotropic and the gains scalar (the P13 head), and so is
    the medial model: the stabilized medial model then hides the direction of the tilt too.
    """
    return curve_directions(case.problem, case.result, SYMMETRIES)


FREE_ENTRY_NOTE = (
    "[1] A known torque cannot counter-rotate with the head, so the head-yaw symmetry is broken "
    "and only global yaw stays hidden. The published 'No' is what one gets with the rotation-"
    "matrix entries as free variables: then R_IH -> L R_IH, R_IS -> L^-T R_IS with L e3 = e3 "
    "(six dimensions) leaves the model and outputs unchanged and moves the third row of R_IH."
)


def explain(case: CaseResult) -> str:
    """A short reason for the row, read from the null space of the observability matrix."""
    r = case.result
    dims = r.n_coords - r.rank
    if dims == 0:
        return "full rank: the feedback breaks both yaw symmetries"
    if r.chart != "tangent":
        return f"{dims} hidden directions (matrix entries as free variables)"
    sym = symmetry_directions(case)
    found = [name.replace("_", " ") for name, v in sym.items() if r.in_null_space(v)]
    if "global yaw" in found and "head yaw" in found and "yaw conjugation" in found:
        found.remove("yaw conjugation")  # their composition
    if case.output != "thesis":
        other = dims - len(found)
        return "hidden: " + ", ".join(found + ([f"{other} other"] if other else []))
    text = "hidden: " + (", ".join(found) if found else "no yaw symmetry")
    if dims > len(found):
        text += f" + {dims - len(found)} other"
    if "yaw conjugation" in found and len(found) == 1:
        text += " (isotropic J_H: feedback is equivariant)"
    elif "head yaw" not in found:
        if case.control == "known":
            text += " (known τ breaks head yaw)"
        elif case.model == "lateral":
            text += " (±r pivots break head yaw)"
    if not case.agrees and case.control == "known":
        text += " [1]"
    return text


def run_table(*, chart: str = "tangent", params: str = "generic", output: str = "thesis",
              points: int = 2, orders: dict | None = None, cases=None) -> list[CaseResult]:
    """All (or the given) ``(model, motion, control)`` cases, one compile per model."""
    orders = orders or ORDERS
    cases = cases or [(m, mo, c) for m in MODELS for mo in MOTIONS for c in CONTROLS]
    return [analyze_case(m, mo, c, chart=chart, params=params, output=output, points=points,
                         order=orders[m]) for m, mo, c in cases]


def row_dict(case: CaseResult) -> dict:
    """The docs/reproduction.md row plus the evidence behind it."""
    r = case.result
    tilt = r.quantities["tilt"]
    return {
        "model": case.model, "motion": case.motion, "control": case.control,
        "orientation_observable": case.orientation_observable,
        "acceleration_identifiable": case.acceleration_identifiable,
        "published_orientation_observable": case.published_orientation,
        "published_acceleration_identifiable": case.published_acceleration,
        "agrees": case.agrees,
        "rank": r.rank, "n_coords": r.n_coords, "gap": r.gap,
        "tilt_derivatives_needed": tilt.derivatives_needed,
        "tilt_residual": tilt.residual,
        "heading_observable": r.quantities["heading"].observable,
        "unobservable_directions": r.describe_null_space(),
        "stalled": r.stalled,
        "why": explain(case),
    }


def table(*, model: str | None = None, motion: str | None = None, control: str | None = None,
          chart: str = "tangent", params: str = "generic", output: str = "thesis",
          points: int = 2) -> dict:
    """The rows (:func:`row_dict`) of the cases selected by ``model``/``motion``/``control`` (None:
    all), with the orders of the chart, and how many agree with F: ``{"rows", "agreement",
    "cases", "wall_s"}`` (what ``verticality observability`` prints)."""
    if points < 1:
        raise InputError(f"points must be >= 1, got {points}")
    for name, value, allowed in (("model", model, MODELS), ("motion", motion, MOTIONS),
                                 ("control", control, CONTROLS)):
        if value is not None and value not in allowed:
            raise InputError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
    cases = [(m, mo, c) for m in MODELS for mo in MOTIONS for c in CONTROLS
             if model in (None, m) and motion in (None, mo) and control in (None, c)]
    t0 = time.perf_counter()
    results = run_table(chart=chart, params=params, output=output, points=points,
                        orders=AMBIENT_ORDERS if chart == "ambient" else ORDERS, cases=cases)
    rows = [row_dict(c) for c in results]
    return {"rows": rows, "agreement": sum(r["agrees"] for r in rows), "cases": len(rows),
            "wall_s": time.perf_counter() - t0}
