"""The model checks: invariants of the physics models, measured on the model values.

Pure functions that run the package's model values (:class:`~verticality.models.pendulum.Pendulum`,
:class:`~verticality.models.otolith_head.OtolithHead` and ``Otoliths``,
:class:`~verticality.models.head.FreeHead`, the planar models) and return what they measure; the
``model-checks`` experiment builds its table from them, and the tests assert the tolerances
(:data:`TOL`) on the same functions. Plant: the P13 otolith pendulum (m = 50 g, l = 0.06 m,
J_S = m·diag(l², l², l²/20) about the pivot, β = 0.001 N·m·s; ζ ≈ 0.22, ω_n = √(m g l / J_xx) =
√(g/l) ≈ 12.79 rad/s) and head (J_H = 0.125 kg·m² per axis), full Newton–Euler forms, fixed-step
RK4 at 1 ms (:func:`run_model`: the input at the RK4 stage times) with rotation matrices
re-orthonormalized each step by the model's ``project``.

The checks and the readings they fix:

* small-oscillation frequency (:func:`oscillation_frequency_rad_s`): undamped pendulum (β = 0) in a
  still, level head, released at rest from 0.01 rad about x (resp. y); frequency from the mean
  period between interpolated downward zero crossings of φ over 10 s, against
  ``√(m g l / J_xx)``. Tolerance 0.5 % (the finite-amplitude shift at 0.01 rad is θ₀²/16 ≈ 6e-6).
* steady deflection (:func:`steady_deflection_errors_rad`): still, level head whose centre
  accelerates at a constant 3 m/s² along x (resp. y); the damped pendulum starts hanging straight
  down; after 10 s (≈ 28 decay time constants) the angle between the pendulum axis and the
  vertical against ``atan(a/g)``, and the angle between the axis and ``(a − g)`` reversed.
* energy (:func:`energy_drift_rel`, :func:`energy_rate_identity_rel`, :func:`energy_balance_rel`):
  undamped, still head, 3-D release (0.5 rad, 0.3 rad tilt and a 5 rad/s spin about the arm plus
  1 rad/s across it, so gravity and the gyroscopic term both act): max over the 10 s at 1 ms of
  ``|E(t) − E(0)|``, relative to the energy of the motion above the minimum, ``E(0) − (−m g l)``.
  Damped, same release: along the trajectory, ``dE/dt`` (forward-mode derivative of E along the
  model's vector field) against ``−β |ω_S|²``, max error relative to the max of ``β |ω_S|²``; and
  ``E(10 s) − E(0)`` against ``−∫ β |ω_S|² dt`` (Simpson on the 1 ms samples), relative to the
  dissipated energy.
* SO(3) drift (:func:`so3_drift_medial`, :func:`so3_drift_lateral_free_head`): the pendulum driven
  kinematically by the P13 impact motion (:func:`verticality.simulation.trajectories.impact`, 60 s;
  the trunk stops after ~6 s), max over the run of ``‖R_ISᵀ R_IS − I‖_F`` with and without the
  projection; the lateral model with a free head under the global stabilizer (F 2.20) and the
  impact's acceleration, 60 s, max over R_IL, R_IR, R_IH.
* planar vs 3-D (:func:`planar_vs_3d_max_error_rad`): the 3-D models with a free head (full
  Newton–Euler) restricted to the coronal y–z plane against the planar medial model
  (:mod:`verticality.models.planar`, F p. 36) and the planar lateral model (F 2.19 plus the Euler
  term), 10 s, torque ``τ_x = 0.05 sin 2t + 0.02 cos 5t`` N·m, pivot acceleration
  ``(a_y, a_z) = (2 sin 3t, 1.5 cos 2t)`` m/s², released off-rest; max error over the pendulum and
  head angles.
* lateral r = 0 vs medial (:func:`lateral_vs_medial`): the lateral pendula with r = 0 against the
  medial pendulum under 10 s of the impact motion: max entry-wise difference of R_IS; and the
  otolith angles of the lateral model (r = 0.05 m) against the medial ones (information). On the
  same run, P13 eq. 3's inclinometer outputs (arcsin of the cross products' norms,
  :func:`~verticality.models.pendulum.p13_inclinometer_angles`) against |φ| of F 2.8–2.9
  (:func:`p13_outputs_minus_abs_f_max_rad`, information).
* still head tilted (:func:`still_tilt_errors_rad`): still head tilted by 0.3 rad about x, about y,
  and by R_x(0.2) R_y(0.3); the pendulum starts aligned with the head (0.3 rad off its rest); after
  10 s the otolith angles against ``φ = −Θ`` (single-axis; docs/conventions.md), the pendulum axis
  against the vertical, and the pendulum-to-head angle against the tilt magnitude.
* stabilizers (:func:`global_stabilizer_final_angle_rad`, :func:`pd_poles_error`): a free head
  (J_H = 0.125, gyroscopic term on) released at rest from a 2.5 rad rotation about
  (1, 1, 0.3)/‖·‖, under F 2.20 with K_p = 16, K_d = 4 (critically damped at upright:
  J θ̈ = −2K_p θ − K_d θ̇), rotation angle of R_IH after 5 s; closed-loop poles of the head under
  the linearized tilt PD (F 4.8–4.9;
  :func:`verticality.simulation.control.tilt_pd_closed_loop_matrix`) against the eigenvalues of the
  ``jacfwd`` linearization (:func:`nonlinear_loop_jacobian`, in exponential coordinates) of the
  nonlinear loop with F 4.6–4.7, and against the analytic roots of ``J s² + k_d s + k_p``; k_p = 32,
  k_d = 5, k_{d,z} = 1.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.compiling import jit_evaluated_once
from verticality.core.constants import G_M_S2
from verticality.core.integrate import rk4_step
from verticality.models import otolith_head, planar
from verticality.models.head import FreeHead, HeadInput, HeadState
from verticality.models.kinematics import RigidMotion, tabulate
from verticality.models.params import LATERAL_R_M, P13_HEAD, P13_PENDULUM, lateral_pendulums
from verticality.models.pendulum import (
    R_H_S,
    Pendulum,
    PendulumState,
    p13_inclinometer_angles,
)
from verticality.simulation.control import (
    global_stabilizer,
    tilt_pd,
    tilt_pd_closed_loop_matrix,
    tilt_pd_linearized,
)

DT_S = 1e-3
T_SHORT_S = 10.0
T_LONG_S = 60.0
A_STEADY_M_S2 = 3.0
TILT_RAD = 0.3
OSC_AMPLITUDE_RAD = 0.01
GLOBAL_KP, GLOBAL_KD = 16.0, 4.0
GLOBAL_T_S = 5.0
PD_KP, PD_KD, PD_KD_Z = 32.0, 5.0, 1.0
EVERY_SO3 = 100
EVERY_LM = 10
EVERY_GLOBAL = 10

TOL = {
    "oscillation": 5e-3,
    "steady": 1e-6,
    "energy": 1e-6,
    "energy_rate": 1e-9,
    "energy_balance": 1e-6,
    "so3": 1e-9,
    "planar": 1e-7,
    "lateral_r0": 1e-12,
    "still_tilt": 1e-6,
    "global": 1e-6,
    "poles": 1e-8,
}
"""The tolerance of each check (docs/models.md)."""


def _steps(duration_s: float) -> int:
    return int(round(duration_s / DT_S))


# ----------------------------------------------------------------------------------- helpers
def run_model(model, x0, u: Callable, dt_s: float, n_steps: int, *, t0_s: float = 0.0,
              project: Callable | None = None, output: Callable | None = None, every: int = 1):
    """Integrate ``model.dynamics`` with fixed-step RK4 under ``lax.scan``, the input
    ``u(t, x)`` evaluated at each RK4 stage (time-varying inputs and state feedback), the state
    put back on its manifold by ``model.project`` (or ``project``) after each step, ``t_k = t0 +
    k·dt`` (no accumulated time).

    Returns ``(x_final, outs)``: ``outs`` stacks ``output(t, x)`` (default: the state) at
    ``t0 + k·every·dt`` for ``k = 0 … n_steps // every − 1`` (the initial state first).
    """
    if n_steps % every:
        raise ValueError("n_steps must be a multiple of every")
    out_fn = output if output is not None else (lambda t, x: x)
    proj = model.project if project is None else project

    def f(t, x):
        return model.dynamics(x, u(t, x))

    def step(x, k):
        return rk4_step(f, t0_s + k * dt_s, x, dt_s, project=proj), None

    def block(x, kb):
        y = out_fn(t0_s + kb * every * dt_s, x)
        x, _ = jax.lax.scan(step, x, kb * every + jnp.arange(every))
        return x, y

    return jax.lax.scan(block, x0, jnp.arange(n_steps // every))


def zero_crossing_frequency(y, dt) -> float:
    """Angular frequency (rad/s) from the mean period between interpolated downward zero
    crossings of the samples ``y`` (step ``dt``)."""
    s = np.where((y[:-1] > 0) & (y[1:] <= 0))[0]
    tc = (s + y[s] / (y[s] - y[s + 1])) * dt
    return 2.0 * np.pi / np.mean(np.diff(tc))


def simpson(y, dt) -> float:
    """Composite Simpson rule over the samples ``y`` (an even number of intervals)."""
    n = len(y) - 1
    return dt / 3.0 * (y[0] + y[n] + 4.0 * y[1:n:2].sum() + 2.0 * y[2:n - 1:2].sum())


def angle_about_x(R):
    """The rotation angle about x of a rotation in the y–z plane."""
    return jnp.arctan2(R[2, 1], R[1, 1])


def _max_wrapped(d) -> float:
    return float(np.max(np.abs(d - 2.0 * np.pi * np.round(d / (2.0 * np.pi)))))


# ------------------------------------------------------------- still head (one compiled batch)
STILL_CASES = ("osc_x", "osc_y", "energy", "damped", "accel_x", "accel_y", "tilt_x", "tilt_y",
               "tilt_xy")


def still_case(name: str):
    """``(R_IH, a_I, R_IS0, ω_S0, β)`` of one still-head run (:data:`STILL_CASES`)."""
    p = P13_PENDULUM
    eye, z = jnp.eye(3), jnp.zeros(3)
    R_xy = so3.rot_x(0.2) @ so3.rot_y(0.3)
    R3d, w3d = so3.exp(jnp.array([0.5, 0.3, 0.0])), jnp.array([1.0, 0.0, 5.0])
    a = A_STEADY_M_S2
    return {
        "osc_x": (eye, z, so3.rot_x(OSC_AMPLITUDE_RAD), z, 0.0),
        "osc_y": (eye, z, so3.rot_y(OSC_AMPLITUDE_RAD), z, 0.0),
        "energy": (eye, z, R3d, w3d, 0.0),
        "damped": (eye, z, R3d, w3d, p.beta_Nms),
        "accel_x": (eye, jnp.array([a, 0.0, 0.0]), eye, z, p.beta_Nms),
        "accel_y": (eye, jnp.array([0.0, a, 0.0]), eye, z, p.beta_Nms),
        "tilt_x": (so3.rot_x(TILT_RAD), z, so3.rot_x(TILT_RAD), z, p.beta_Nms),
        "tilt_y": (so3.rot_y(TILT_RAD), z, so3.rot_y(TILT_RAD), z, p.beta_Nms),
        "tilt_xy": (R_xy, z, R_xy, z, p.beta_Nms),
    }[name]


@jit_evaluated_once
def _run_still(R_I_H, a_I, R_I_S0, omega_S0, beta):
    model = Pendulum(P13_PENDULUM._replace(beta_Nms=beta))
    zero = jnp.zeros(3)
    head = RigidMotion(R_I_H, zero, zero, a_I)
    xf, xs = run_model(model, PendulumState(R_I_S0, omega_S0), lambda t, x: head, DT_S,
                       _steps(T_SHORT_S))
    xs = jax.tree_util.tree_map(lambda a, b: jnp.concatenate([a, b[None]]), xs, xf)

    def per_sample(x):
        E, dE = jax.jvp(model.energy_J, (x,), (model.dynamics(x, head),))
        w = x.omega_S_rad_s
        return {"phi": model.output(x, head), "E": E, "dE": dE, "diss": beta * (w @ w),
                "axis_I": x.R_I_S[:, 2]}

    return jax.vmap(per_sample)(xs)


@functools.lru_cache(maxsize=1)
def still_runs() -> dict[str, dict[str, np.ndarray]]:
    """The nine still-head runs of 10 s (:data:`STILL_CASES`, one vmapped compile): per case and
    per sample (10 001, the initial state first) the otolith angles ``phi``, the energy ``E``, its
    rate ``dE`` along the model's vector field, the dissipation ``diss`` = β|ω_S|² and the
    pendulum axis ``axis_I`` in frame I."""
    stack = [jnp.stack([still_case(n)[i] for n in STILL_CASES]) for i in range(5)]
    out = jax.tree_util.tree_map(np.asarray, jax.vmap(_run_still)(*stack))
    return {name: {k: v[i] for k, v in out.items()} for i, name in enumerate(STILL_CASES)}


def analytic_frequency_rad_s() -> float:
    """``√(m g l / J_xx)`` of the P13 pendulum."""
    p = P13_PENDULUM
    return float(np.sqrt(p.m_kg * G_M_S2 * p.l_m / p.J_pivot_S[0]))


def oscillation_frequency_rad_s(axis: str) -> float:
    """The undamped small oscillation's frequency about ``axis`` ("x" or "y")."""
    k = "xy".index(axis)
    return float(zero_crossing_frequency(still_runs()[f"osc_{axis}"]["phi"][:, k], DT_S))


def energy_drift_rel() -> np.ndarray:
    """``|E(t) − E(0)| / (E(0) − E_min)`` of the undamped 3-D release, per sample."""
    p = P13_PENDULUM
    E = still_runs()["energy"]["E"]
    return np.abs(E - E[0]) / (E[0] - (-p.m_kg * G_M_S2 * p.l_m))


def energy_rate_identity_rel() -> float:
    """max |dE/dt + β|ω_S|²| / max β|ω_S|² along the damped release."""
    run = still_runs()["damped"]
    return float(np.max(np.abs(run["dE"] + run["diss"])) / np.max(run["diss"]))


def energy_balance_rel() -> float:
    """|E(10 s) − E(0) + ∫ β|ω_S|² dt| / ∫ β|ω_S|² dt along the damped release."""
    run = still_runs()["damped"]
    dissipated = simpson(run["diss"], DT_S)
    return float(abs((run["E"][-1] - run["E"][0]) + dissipated) / dissipated)


def deflection_rad(axis: str) -> np.ndarray:
    """The pendulum axis' angle from the vertical under the steady acceleration along ``axis``."""
    a = still_runs()[f"accel_{axis}"]["axis_I"]
    return np.arctan2(np.linalg.norm(a[:, :2], axis=1), a[:, 2])


def steady_deflection_errors_rad(axis: str) -> tuple[float, float]:
    """(|deflection − atan(a/g)|, angle between the axis and the gravito-inertial up) at 10 s."""
    err = float(abs(deflection_rad(axis)[-1] - np.arctan(A_STEADY_M_S2 / G_M_S2)))
    up = np.array([A_STEADY_M_S2 if axis == "x" else 0.0, A_STEADY_M_S2 if axis == "y" else 0.0,
                   G_M_S2])
    up /= np.linalg.norm(up)
    a = still_runs()[f"accel_{axis}"]["axis_I"][-1]
    return err, float(np.arctan2(np.linalg.norm(np.cross(a, up)), a @ up))


class StillTilt(NamedTuple):
    """The still, tilted head after 10 s (rad)."""

    phi_error: float  # single-axis tilt: max |φ − (−Θ e_k)|; two-axis: max |φ − Θ(R_IHᵀ)|
    axis_error: float  # the pendulum axis against the vertical
    magnitude_error: float  # the pendulum-to-head angle against the head's tilt magnitude


def still_tilt_errors_rad(axis: str) -> StillTilt:
    """The still head tilted about ``axis`` ("x", "y" or "xy"). For "xy" the φ error is against
    the tilt angles of ``R_IHᵀ`` (F 2.8–2.9 read row 3 of R_HS, which depends on the pendulum's
    turn about its own arm; for a two-axis tilt that turn is not fixed by the statics, so that
    number is information only)."""
    run = still_runs()[f"tilt_{axis}"]
    R_I_H = np.asarray(still_case(f"tilt_{axis}")[0])
    phi_end, axis_I = run["phi"][-1], run["axis_I"][-1]
    axis_err = float(np.arctan2(np.linalg.norm(axis_I[:2]), axis_I[2]))
    head_tilt = float(np.arccos(np.clip(R_I_H[2, 2], -1.0, 1.0)))
    axis_H = R_I_H.T @ axis_I
    mag = abs(float(np.arctan2(np.linalg.norm(axis_H[:2]), axis_H[2])) - head_tilt)
    if axis == "xy":
        phi_err = float(np.max(np.abs(phi_end - np.asarray(so3.tilt_angles(R_I_H.T)))))
        return StillTilt(phi_err, axis_err, mag)
    k = "xy".index(axis)
    theta = float(np.asarray(so3.tilt_angles(R_I_H))[k])
    phi_err = float(np.max(np.abs(phi_end - np.eye(2)[k] * (-theta))))  # φ = −Θ, the other 0
    return StillTilt(phi_err, axis_err, max(mag, abs(abs(phi_end[k]) - TILT_RAD)))


# ------------------------------------------------------------------ the impact motion (60 s)
@functools.lru_cache(maxsize=1)
def impact_table():
    """The P13 impact motion (60 s) sampled at every RK4 stage time, shared by the impact runs."""
    from verticality.simulation import trajectories

    return tabulate(trajectories.impact(duration_s=T_LONG_S).motion, DT_S, _steps(T_LONG_S))


@jit_evaluated_once(static_argnames=("n",))
def _so3_medial(table, n):
    model = Pendulum(P13_PENDULUM)

    def one(flag):
        def proj(x):
            return jax.tree_util.tree_map(lambda a, b: jnp.where(flag > 0, a, b),
                                          model.project(x), x)

        xf, err = run_model(model, model.rest_state(table.motion(0.0)),
                            lambda t, x: table.motion(t), DT_S, n, project=proj, every=EVERY_SO3,
                            output=lambda t, x: so3.orthonormality_error(x.R_I_S))
        return jnp.concatenate([err, so3.orthonormality_error(xf.R_I_S)[None]])

    return jax.vmap(one)(jnp.array([1.0, 0.0]))


@functools.lru_cache(maxsize=1)
def so3_drift_medial() -> tuple[np.ndarray, np.ndarray]:
    """``‖R_ISᵀR_IS − I‖`` every 0.1 s over the 60 s impact run, with and without the projection."""
    err = np.asarray(_so3_medial(impact_table(), _steps(T_LONG_S)))
    return err[0], err[1]


@jit_evaluated_once(static_argnames=("n",))
def _so3_lateral_free_head(table, n):
    model = otolith_head.lateral(P13_PENDULUM, P13_HEAD)
    x0 = model.rest_state(table.motion(0.0)._replace(R_I_B=so3.exp(jnp.array([0.6, -0.4, 0.2]))))

    def u(t, x):
        tau = global_stabilizer(x.head.R_I_H, x.head.omega_H_rad_s, GLOBAL_KP, GLOBAL_KD)
        return HeadInput(tau, table.motion(t).a_I_m_s2)

    def err(t, x):
        return jnp.max(jnp.stack([so3.orthonormality_error(R) for R in
                                  [p.R_I_S for p in x.pendula] + [x.head.R_I_H]]))

    xf, e = run_model(model, x0, u, DT_S, n, every=EVERY_SO3, output=err)
    return jnp.concatenate([e, err(0.0, xf)[None]])


def so3_drift_lateral_free_head() -> np.ndarray:
    """max over R_IL, R_IR, R_IH of ``‖RᵀR − I‖`` every 0.1 s: the lateral model with a free head
    under the global stabilizer and the impact's acceleration, 60 s, projected."""
    return np.asarray(_so3_lateral_free_head(impact_table(), _steps(T_LONG_S)))


# ------------------------------------------------------------------------ planar vs 3-D (10 s)
TH_S0, W_S0, TH_H0, W_H0 = 0.3, -0.5, 0.1, 0.05
TH_R0 = -0.2


def planar_inputs(t):
    """The coronal-plane test input: torque about x, pivot acceleration (a_y, a_z) in I."""
    tau = 0.05 * jnp.sin(2.0 * t) + 0.02 * jnp.cos(5.0 * t)
    return tau, 2.0 * jnp.sin(3.0 * t), 1.5 * jnp.cos(2.0 * t)


def planar_params() -> planar.PlanarHead:
    """The P13 plant in the plane (about x)."""
    p = P13_PENDULUM
    return planar.PlanarHead(m_kg=p.m_kg, l_m=p.l_m, J_kg_m2=p.J_pivot_S[0], beta_Nms=p.beta_Nms,
                               K_kg_m2=P13_HEAD.J_H[0], g_m_s2=G_M_S2)


def _planar_input(t, x):
    return planar.PlanarInput(*planar_inputs(t))


def _head_input_3d(t, x):
    tau, ah, az = planar_inputs(t)
    return HeadInput(jnp.stack([tau, 0.0, 0.0]), jnp.stack([0.0, ah, az]))


def _in_plane(R, w):
    return R, w * jnp.array([1.0, 0.0, 0.0])


@jit_evaluated_once(static_argnames=("n",))
def _planar_medial(n):
    x0p = planar.PlanarState(*(jnp.asarray(v) for v in (TH_S0, W_S0, TH_H0, W_H0)))
    _, yp = run_model(planar_params(), x0p, _planar_input, DT_S, n,
                      output=lambda t, x: jnp.stack([x.theta_S_rad, x.theta_H_rad]))
    model = otolith_head.medial(P13_PENDULUM, P13_HEAD)
    x03 = otolith_head.OtolithHeadState(
        (PendulumState(*_in_plane(so3.rot_x(TH_S0), W_S0)),),
        HeadState(*_in_plane(so3.rot_x(TH_H0), W_H0)))
    _, y3 = run_model(model, x03, _head_input_3d, DT_S, n,
                      output=lambda t, x: jnp.stack([angle_about_x(x.pendula[0].R_I_S),
                                                     angle_about_x(x.head.R_I_H)]))
    return yp, y3


@jit_evaluated_once(static_argnames=("n",))
def _planar_lateral(n):
    s = [jnp.asarray(v) for v in (TH_S0, W_S0, TH_R0, -W_S0, TH_H0, W_H0)]
    _, yp = run_model(otolith_head.PlanarLateral(planar_params()),
                      otolith_head.PlanarLateralState(*s), _planar_input, DT_S, n,
                      output=lambda t, x: jnp.stack([x.theta_L_rad, x.theta_R_rad, x.theta_H_rad]))
    model = otolith_head.lateral(P13_PENDULUM, P13_HEAD)
    x03 = otolith_head.OtolithHeadState(
        (PendulumState(*_in_plane(so3.rot_x(TH_S0), W_S0)),
         PendulumState(*_in_plane(so3.rot_x(TH_R0), -W_S0))),
        HeadState(*_in_plane(so3.rot_x(TH_H0), W_H0)))
    _, y3 = run_model(model, x03, _head_input_3d, DT_S, n,
                      output=lambda t, x: jnp.stack([angle_about_x(x.pendula[0].R_I_S),
                                                     angle_about_x(x.pendula[1].R_I_S),
                                                     angle_about_x(x.head.R_I_H)]))
    return yp, y3


@functools.lru_cache(maxsize=2)
def planar_vs_3d(which: str) -> tuple[np.ndarray, np.ndarray]:
    """(planar, 3-D) angles over the 10 s coronal-plane run, every 1 ms: (θ_S, θ_H) for
    ``which="medial"``, (θ_L, θ_R, θ_H) for ``"lateral"``."""
    fn = {"medial": _planar_medial, "lateral": _planar_lateral}[which]
    yp, y3 = fn(_steps(T_SHORT_S))
    return np.asarray(yp), np.asarray(y3)


def planar_vs_3d_max_error_rad(which: str) -> float:
    """max |planar − 3-D| over the angles and the run (angles wrapped)."""
    yp, y3 = planar_vs_3d(which)
    return _max_wrapped(yp - y3)


# ------------------------------------------------------------------ lateral (r = 0) vs medial
@jit_evaluated_once(static_argnames=("n",))
def _lateral_vs_medial(table, n):
    medial = Pendulum(P13_PENDULUM)
    head0 = table.motion(0.0)
    _, med = run_model(medial, medial.rest_state(head0), lambda t, x: table.motion(t), DT_S, n,
                       every=EVERY_LM,
                       output=lambda t, x: (x.R_I_S, medial.output(x, table.motion(t)),
                                            p13_inclinometer_angles(
                                                R_H_S(x, table.motion(t).R_I_B))))

    def lateral(r):
        model = otolith_head.Otoliths(tuple(Pendulum(p)
                                            for p in lateral_pendulums(P13_PENDULUM, r)))
        return run_model(model, model.rest_state(head0), lambda t, x: table.motion(t), DT_S, n,
                         every=EVERY_LM,
                         output=lambda t, x: (x[0].R_I_S, x[1].R_I_S,
                                              model.output(x, table.motion(t))))[1]

    return med, jax.vmap(lateral)(jnp.array([0.0, LATERAL_R_M]))


class LateralVsMedial(NamedTuple):
    t_s: np.ndarray  # every 10 ms
    R_I_S_medial: np.ndarray
    phi_medial: np.ndarray  # (n, 2)
    R_I_S_lateral_r0: tuple[np.ndarray, np.ndarray]  # left, right with r = 0
    phi_lateral: np.ndarray  # (n, 4): left (φx, φy), right (φx, φy) with r = 0.05 m
    p13_medial: np.ndarray  # (n, 2): P13 eq. 3's (y1, y2) of the medial pendulum


@functools.lru_cache(maxsize=1)
def lateral_vs_medial() -> LateralVsMedial:
    """10 s of the impact motion: the medial pendulum and the lateral pendula (r = 0, 0.05 m)."""
    out = _lateral_vs_medial(impact_table(), _steps(T_SHORT_S))
    (R_med, phi_med, p13), (R_L, R_R, phi_lat) = jax.tree_util.tree_map(np.asarray, out)
    t = np.arange(phi_med.shape[0]) * DT_S * EVERY_LM
    return LateralVsMedial(t, R_med, phi_med, (R_L[0], R_R[0]), phi_lat[1], p13)


def lateral_r0_vs_medial_max_error() -> float:
    """max entry-wise |R_IS(lateral, r = 0) − R_IS(medial)| over both sides and the run."""
    run = lateral_vs_medial()
    return float(max(np.max(np.abs(R - run.R_I_S_medial)) for R in run.R_I_S_lateral_r0))


def lateral_minus_medial_max_rad() -> float:
    """max |φ(lateral, r = 0.05 m) − φ(medial)| (information: what the pivots' offset does)."""
    run = lateral_vs_medial()
    return float(np.max(np.abs(run.phi_lateral - np.tile(run.phi_medial, 2))))


def p13_outputs_minus_abs_f_max_rad() -> tuple[float, float]:
    """``(max ‖(y1, y2) − (|φ_x|, |φ_y|)‖∞, max |φ|)`` over the medial pendulum's 10 s of the impact
    motion: P13 eq. 3 against F 2.8–2.9 where P13's own motion drives them."""
    run = lateral_vs_medial()
    return (float(np.max(np.abs(run.p13_medial - np.abs(run.phi_medial)))),
            float(np.max(np.abs(run.phi_medial))))


# ------------------------------------------------------------------------------- stabilizers
@jit_evaluated_once
def _global_stabilizer_run():
    head = FreeHead(P13_HEAD)
    axis = jnp.array([1.0, 1.0, 0.3])
    x0 = HeadState(so3.exp(2.5 * axis / jnp.linalg.norm(axis)), jnp.zeros(3))

    def u(t, h):
        return HeadInput(global_stabilizer(h.R_I_H, h.omega_H_rad_s, GLOBAL_KP, GLOBAL_KD),
                         jnp.zeros(3))

    hf, ang = run_model(head, x0, u, DT_S, _steps(GLOBAL_T_S), every=EVERY_GLOBAL,
                        output=lambda t, h: jnp.linalg.norm(so3.log(h.R_I_H)))
    return ang, jnp.linalg.norm(so3.log(hf.R_I_H))


@functools.lru_cache(maxsize=1)
def global_stabilizer_angle_rad() -> tuple[np.ndarray, float]:
    """The free head's rotation angle every 10 ms under F 2.20 from 2.5 rad, and after 5 s."""
    ang, final = _global_stabilizer_run()
    return np.asarray(ang), float(final)


def global_stabilizer_final_angle_rad() -> float:
    return global_stabilizer_angle_rad()[1]


def nonlinear_loop_jacobian(law, J_H, kp, kd, kd_z):
    """``jacfwd`` of the free head under ``law`` (F 4.6–4.7 or 4.8–4.9) at upright, in exponential
    coordinates ``R_IH = exp([δ]×)``: state ``(δ, ω_H)``, ``δ̇ = d/dt log(R_IH)``."""
    head = FreeHead(P13_HEAD._replace(J_H=jnp.asarray(J_H)))

    def F(z):
        delta, w = z[:3], z[3:]
        R = so3.exp(delta)
        wdot = head.angular_acceleration(w, law(R, w, kp, kd, kd_z=kd_z))
        ddelta = jax.jvp(lambda s: so3.log(R @ so3.exp(s * w)), (0.0,), (1.0,))[1]
        return jnp.concatenate([ddelta, wdot])

    return jax.jacfwd(F)(jnp.zeros(6))


def closed_loop_poles() -> np.ndarray:
    """Eigenvalues of the linearized tilt-PD loop (F 4.8–4.9), sorted."""
    return np.sort_complex(np.linalg.eigvals(np.asarray(
        tilt_pd_closed_loop_matrix(P13_HEAD.J_H, PD_KP, PD_KD, PD_KD_Z))))


def pd_poles_error() -> float:
    """max distance of the poles of :func:`closed_loop_poles` to those of the ``jacfwd``
    linearization of both nonlinear laws and to the analytic roots, relative to the largest root."""
    J = P13_HEAD.J_H
    poles_lin = closed_loop_poles()
    worst = 0.0
    for law in (tilt_pd, tilt_pd_linearized):
        A = np.asarray(jit_evaluated_once(nonlinear_loop_jacobian, static_argnums=0)(
            law, J, PD_KP, PD_KD, PD_KD_Z))
        worst = max(worst, float(np.max(np.abs(np.sort_complex(np.linalg.eigvals(A)) - poles_lin))))
    roots = []
    for Ji in np.asarray(J)[:2]:
        roots.extend(np.roots([float(Ji), PD_KD, PD_KP]))
    roots.extend([0.0, -PD_KD_Z / float(J[2])])
    roots = np.sort_complex(np.asarray(roots, complex))
    worst = max(worst, float(np.max(np.abs(roots - poles_lin))))
    return worst / float(np.max(np.abs(roots)))
