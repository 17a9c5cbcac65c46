"""Observability of the head's tilt from the otoliths: the 16 cases of F Tables 3.1 and 3.2.

Models (composed from :mod:`verticality.models.pendulum`, not from ``models/vestibular.py``):

- ``medial`` (F 2.7): one damped spherical pendulum pivoting at the head centre;
- ``lateral`` (F 2.12): two pendula pivoting at ``±r`` along the head's y axis (``r = 0.05`` m; the
  thesis writes ``H r = (0, 0, r)``, but its Fig. 2.3 and planar form 2.19 put the ears to the side);
- head: ``J_H ω̇_H = τ`` and ``Ṙ_IH = R_IH [ω_H]×`` (F 2.7: the head's gyroscopic term dropped).

The pendulum is the simplified one of F 2.7 / 2.12 (``PendulumParams.simplified()``: no gyroscopic
and no Euler term; the centripetal term of the lateral model kept). ``form="full"`` keeps every term
(gyroscopic head and pendula, Euler transport acceleration).

Outputs: the otolith angles only, ``pendulum.otolith_angles(R_HS)`` (F 2.8–2.9, 2.13–2.16).

Motion ``rot``: ``a = 0``; ``rot+trans``: ``H a`` a constant unknown (F §3.1.2 defines the head-frame
acceleration as a symbolic parameter). Control: ``zero`` (τ = 0), ``unknown`` (τ a constant unknown
parameter), ``known`` (τ a known input with free derivatives, not stabilized), ``stabilized`` (the
feedback of F 2.20–2.21 substituted into the head dynamics). For the feedback we use the stabilizing
sign, ``τ = K_p Σ_i e_i × (R_IHᵀ e_i) − K_d ω_H`` (the thesis' ``Ω`` with ``R_HI``; with ``R_IH`` the law
would push away from upright; the sign does not change the generic rank).

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

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from verticality import so3
from verticality.analysis.observability import (
    SO3,
    ObservabilityResult,
    Problem,
    analyze,
    random_rotation,
)
from verticality.errors import InputError
from verticality.models import pendulum
from verticality.models.kinematics import RigidMotion
from verticality.params import (
    LATERAL_R_M,
    P13_HEAD,
    P13_KD_NMS_RAD,
    P13_KP_NM_RAD,
    P13_PENDULUM,
    PendulumParams,
)

MODELS = ("medial", "lateral")
MOTIONS = ("rot", "rot+trans")
CONTROLS = ("zero", "unknown", "known", "stabilized")

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
    J_H: jnp.ndarray
    kp: float
    kd: float
    r_m: float = LATERAL_R_M


def plant_params(which: str = "generic", r_m: float = LATERAL_R_M) -> PlantParams:
    if which == "generic":
        pend = PendulumParams(m_kg=1.0, l_m=1.0, J_pivot_S=jnp.array([1.0, 1.0, 0.3]),
                              beta_Nms=1.5).resolved()
        return PlantParams(pend, jnp.array([1.0, 1.2, 0.9]), 2.0, 1.5, r_m)
    if which == "p13":
        return PlantParams(P13_PENDULUM, P13_HEAD.J_H, P13_KP_NM_RAD, P13_KD_NMS_RAD, r_m)
    raise InputError(f"params must be 'generic' or 'p13', got {which!r}")


def stabilizing_torque(R_I_H, omega_H, kp, kd):
    """F 2.20–2.21 with the stabilizing sign: ``τ = K_p Ω − K_d ω_H``, ``Ω = Σ_i e_i × (R_IHᵀ e_i)``.

    ``Ω = vee(R_IHᵀ − R_IH) ≈ −2θ`` for a small rotation vector θ of the head: a restoring torque.
    """
    Omega = 2.0 * so3.vee(R_I_H.T)
    return kp * Omega - kd * omega_H


ORDERS = {"medial": 8, "lateral": 6}
"""Highest output derivative used per model: enough for full rank (⌈n/p⌉ with n ≤ 18 coordinates
and p = 2 outputs for the medial model, n ≤ 24 and p = 4 for the lateral one); every case is checked
to have stalled (its rank stopped growing) before that order."""


AMBIENT_ORDERS = {"medial": 15, "lateral": 11}
"""Orders for the free-entry (ambient) formulation: 24–30 (medial) or 36–42 (lateral) coordinates."""


def build_problem(model: str, *, params: str = "generic", form: str = "simplified",
                  r_m: float = LATERAL_R_M, output: str = "thesis") -> Problem:
    """The observability :class:`Problem` of one model, serving all eight motion/control cases.

    Unknown constants: ``a_H`` (head-frame acceleration), ``tau_H`` (constant unknown torque) and the
    switch ``stab`` (1 = feedback F 2.20 on); known input ``tau_u`` (known torque).
    ``output="thesis"``: the otolith angles of F 2.8–2.9 as written, from the third *row* of
    ``R_HS`` (the head's z axis seen in the pendulum frame); ``output="axis"``: the same angles
    from the third *column* (the pendulum's axis seen in the head frame, ``−s_H``). A case fixes
    the constants that are not unknown in it and zeroes the unused input (:func:`case_settings`),
    so one compiled function serves the eight cases of a table.
    """
    if model not in MODELS:
        raise InputError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    if form not in ("simplified", "full"):
        raise InputError(f"form must be 'simplified' or 'full', got {form!r}")
    if output not in ("thesis", "axis"):
        raise InputError(f"output must be 'thesis' or 'axis', got {output!r}")
    pp = plant_params(params, r_m)
    base = pp.pendulum if form == "full" else pp.pendulum.simplified()
    head_gyro = 1.0 if form == "full" else 0.0
    if model == "medial":
        pends = {"S": base._replace(pivot_H_m=jnp.zeros(3))}
    else:
        pends = {
            "L": base._replace(pivot_H_m=jnp.array([0.0, pp.r_m, 0.0])),
            "R": base._replace(pivot_H_m=jnp.array([0.0, -pp.r_m, 0.0])),
        }
    J_H = pp.J_H

    states = {}
    for k in pends:
        states[f"R_I_{k}"] = SO3
        states[f"omega_{k}"] = (3,)
    states["R_I_H"] = SO3
    states["omega_H"] = (3,)
    unknowns = {"a_H": (3,), "tau_H": (3,), "stab": ()}
    inputs = {"tau_u": (3,)}

    def f(x, u, th):
        R_I_H, w_H = x["R_I_H"], x["omega_H"]
        tau = th["tau_H"] + u["tau_u"] + th["stab"] * stabilizing_torque(R_I_H, w_H, pp.kp, pp.kd)
        wdot_H = (tau - head_gyro * jnp.cross(w_H, J_H * w_H)) / J_H
        head = RigidMotion(R_I_B=R_I_H, omega_B_rad_s=w_H, omegadot_B_rad_s2=wdot_H,
                           a_I_m_s2=R_I_H @ th["a_H"])
        dx = {"R_I_H": R_I_H @ so3.hat(w_H), "omega_H": wdot_H}
        for k, p in pends.items():
            d = pendulum.dynamics(pendulum.PendulumState(x[f"R_I_{k}"], x[f"omega_{k}"]), head, p)
            dx[f"R_I_{k}"] = d.R_I_S
            dx[f"omega_{k}"] = d.omega_S_rad_s
        return dx

    def h(x, u, th):
        angles = []
        for k in pends:
            R_HS = pendulum.R_H_S(pendulum.PendulumState(x[f"R_I_{k}"], None), x["R_I_H"])
            angles.append(pendulum.otolith_angles(R_HS if output == "thesis" else R_HS.T))
        return jnp.concatenate(angles)

    quantities = {
        "tilt": lambda x, th: x["R_I_H"].T @ E3,
        "heading": lambda x, th: x["R_I_H"][:, 0],
    }

    def sample(rng):
        x = {name: random_rotation(rng) if spec == SO3 else rng.standard_normal(3)
             for name, spec in states.items()}
        th = {"a_H": 2.0 * rng.standard_normal(3), "tau_H": rng.standard_normal(3), "stab": 0.0}
        return x, th

    return Problem(f=f, h=h, states=states, unknowns=unknowns, inputs=inputs,
                   quantities=quantities, sample=sample)


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
                      pub[1], res, params, output)


def _direction(result: ObservabilityResult, parts: dict[str, np.ndarray]) -> np.ndarray:
    """A vector in the result's coordinates from ``{label prefix: components}``."""
    v = np.zeros(len(result.labels))
    for name, comps in parts.items():
        for i, c in enumerate(np.ravel(comps)):
            lab = f"{name}.δ{'xyz'[i]}" if f"{name}.δx" in result.labels else f"{name}[{i}]"
            if lab in result.labels:
                v[result.labels.index(lab)] = c
    return v


def symmetry_directions(result: ObservabilityResult, J_H) -> dict[str, np.ndarray]:
    """The two continuous symmetries of the otolith models, as tangent vectors at the test point.

    ``global_yaw``: every frame turned about gravity, ``R_IX → Rz(ε) R_IX``, i.e. ``δ_X = R_IXᵀ e3``.
    ``head_yaw``: the head turned about its own z axis with its angular velocity, torque and
    acceleration counter-rotated, ``R_IH → R_IH Rz(ε)``, ``v → Rz(ε)ᵀ v`` (v = ω_H, a_H;
    ``τ → J_H Rz(ε)ᵀ J_H⁻¹ τ`` so that ω̇_H = J_H⁻¹τ turns with ω_H): the
    inertial angular velocity ``R_IH ω_H``, the head's z axis and ``R_IH a_H`` do not change, so neither
    do the pendulum dynamics nor the otolith angles of F 2.8–2.9 (third row of ``R_HS``), but the
    gravity direction in the head frame turns about the head's z axis.
    ``yaw_conjugation``: ``R_IH → Rz R_IH Rzᵀ``, ``ω_H → Rz ω_H``, ``a_H → Rz a_H``, pendula
    ``R_IX → Rz R_IX`` (global yaw composed with the inverse head yaw). The feedback F 2.20 is
    equivariant under it when ``J_H`` is isotropic and the gains scalar (the P13 head), and so is the
    medial model: the stabilized medial model then hides the direction of the tilt too.
    """
    x, th = result.point
    e3 = np.array([0.0, 0.0, 1.0])
    g1 = {name: np.asarray(R).T @ e3 for name, R in x.items() if name.startswith("R_I_")}
    g3 = dict(g1)
    g3["R_I_H"] = g1["R_I_H"] - e3
    g3["omega_H"] = np.cross(e3, x["omega_H"])
    if "a_H" in th:
        g3["a_H"] = np.cross(e3, th["a_H"])
    g2 = {"R_I_H": e3, "omega_H": -np.cross(e3, x["omega_H"])}
    J = np.asarray(J_H)
    if "tau_H" in th:
        g2["tau_H"] = -J * np.cross(e3, th["tau_H"] / J)
    if "a_H" in th:
        g2["a_H"] = -np.cross(e3, th["a_H"])
    return {"global_yaw": _direction(result, g1), "head_yaw": _direction(result, g2),
            "yaw_conjugation": _direction(result, g3)}


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
    sym = symmetry_directions(r, plant_params(case.params).J_H)
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
