"""`model-checks` — validation of the physics models (F §2.1–2.2, P13 §3, F §4.4).

Every check is a metric ``{"value", "tolerance", "pass"}``. Plant: the P13 otolith pendulum
(m = 50 g, l = 0.06 m, J_S = m·diag(l², l², l²/20) about the pivot, β = 0.001 N·m·s; ζ ≈ 0.22,
ω_n = √(m g l / J_xx) = √(g/l) ≈ 12.79 rad/s) and head (J_H = 0.125 kg·m² per axis), full
Newton–Euler forms, fixed-step RK4 at 1 ms with rotation matrices re-orthonormalized each step.

Checks and the readings they fix:

* ``oscillation_frequency_rel_error.{x,y}``: undamped pendulum (β = 0) in a still, level head,
  released at rest from 0.01 rad about x (resp. y); frequency from the mean period between
  interpolated downward zero crossings of φ over 10 s, against ``√(m g l / J_xx)``. Tolerance 0.5 %
  (the finite-amplitude shift at 0.01 rad is θ₀²/16 ≈ 6e-6).
* ``steady_deflection_error_rad.{x,y}``: still, level head whose centre accelerates at a constant
  3 m/s² along x (resp. y); the damped pendulum starts hanging straight down; after 10 s (≈ 28 decay
  time constants) the angle between the pendulum axis and the vertical against ``atan(a/g)``, and
  ``steady_deflection_direction_error_rad`` the angle between the axis and ``(a − g)`` reversed.
* ``energy_drift_rel``: undamped, still head, 3-D release (0.5 rad, 0.3 rad tilt and a 5 rad/s spin
  about the arm plus 1 rad/s across it, so gravity and the gyroscopic term both act): max over the
  10 s at 1 ms of ``|E(t) − E(0)|``, relative to the energy of the motion above the minimum,
  ``E(0) − (−m g l)`` (relative to |E| itself would depend on where the potential's zero is).
* ``energy_rate_identity_rel``: damped, same release: along the trajectory, ``dE/dt`` (forward-mode
  derivative of E along the model's vector field) against ``−β |ω_S|²``, max error relative to the
  max of ``β |ω_S|²``. ``energy_balance_rel``: ``E(10 s) − E(0)`` against ``−∫ β |ω_S|² dt``
  (Simpson on the 1 ms samples), relative to the dissipated energy.
* ``so3_orthonormality``: medial model driven kinematically by the P13 impact motion
  (:func:`verticality.trajectories.impact`, 60 s; the trunk stops after ~6 s), max over the run of
  ``‖R_ISᵀ R_IS − I‖_F``, tolerance 1e-9. ``so3_orthonormality_free_head_lateral``: the lateral model
  with a free head under the global stabilizer (F 2.20) and the impact's acceleration, 60 s, max over
  R_IL, R_IR, R_IH. ``so3_orthonormality_unprojected`` (information): the same medial run without the
  projection, to show what it is for.
* ``planar_vs_3d_max_error_rad.{medial,lateral}``: the 3-D models with a free head (full Newton–Euler)
  restricted to the coronal y–z plane against :mod:`verticality.models.planar` (medial, F p. 36) and
  :func:`verticality.models.vestibular.planar_lateral_dynamics` (F 2.19 plus the Euler term), 10 s,
  torque ``τ_x = 0.05 sin 2t + 0.02 cos 5t`` N·m, pivot acceleration ``(a_y, a_z) = (2 sin 3t,
  1.5 cos 2t)`` m/s², released off-rest; max error over the pendulum and head angles, tolerance 1e-7.
* ``lateral_r0_vs_medial_max_error``: lateral model with r = 0 against the medial model under 10 s
  of the impact motion: max entry-wise difference of R_IS, tolerance 1e-12.
* ``still_tilt_error_rad.{x,y,xy}``: still head tilted by 0.3 rad about x, about y, and by
  R_x(0.2) R_y(0.3); the pendulum starts aligned with the head (0.3 rad off its rest); after 10 s the
  otolith angles against ``φ = −Θ`` (single-axis; docs/conventions.md) and, for the two-axis tilt,
  against the tilt angles of ``R_IHᵀ``. ``still_tilt_magnitude_error_rad``: the pendulum-to-head angle
  against the tilt magnitude θ (single axis).
* ``global_stabilizer_final_angle_rad``: a free head (J_H = 0.125, gyroscopic term on) released at
  rest from a 2.5 rad rotation about (1, 1, 0.3)/‖·‖, under F 2.20 with K_p = 16, K_d = 4 (critically
  damped at upright: J θ̈ = −2K_p θ − K_d θ̇), rotation angle of R_IH after 5 s.
* ``pd_poles_max_error``: closed-loop poles of the head under the linearized tilt PD (F 4.8–4.9;
  :func:`verticality.control.tilt_pd_closed_loop_matrix`) against the eigenvalues of the ``jacfwd``
  linearization (in exponential coordinates) of the nonlinear loop with F 4.6–4.7, and against the
  analytic roots of ``J s² + k_d s + k_p``; k_p = 32, k_d = 5, k_{d,z} = 1.

``quick`` runs the same checks (their durations are the checks' definitions and cost little after
compilation) but skips the two information/extra 60 s runs (free-head lateral and unprojected).
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from verticality import so3
from verticality.control import (
    global_stabilizer,
    tilt_pd,
    tilt_pd_closed_loop_matrix,
    tilt_pd_linearized,
)
from verticality.experiments import Result, check, register
from verticality.models import pendulum, planar
from verticality.models import vestibular as V
from verticality.models.kinematics import RigidMotion
from verticality.params import G_M_S2, LATERAL_R_M, P13_HEAD, P13_PENDULUM

DT_S = 1e-3
T_SHORT_S = 10.0
T_LONG_S = 60.0
A_STEADY_M_S2 = 3.0
TILT_RAD = 0.3
OSC_AMPLITUDE_RAD = 0.01
GLOBAL_KP, GLOBAL_KD = 16.0, 4.0
PD_KP, PD_KD, PD_KD_Z = 32.0, 5.0, 1.0

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


# ---------------------------------------------------------------- still-head batch (one compile)
def _still_cases():
    """Nine runs of the medial model under a constant head motion, batched for one compile."""
    p = P13_PENDULUM
    R3d = so3.exp(jnp.array([0.5, 0.3, 0.0]))
    w3d = jnp.array([1.0, 0.0, 5.0])
    eye, z = jnp.eye(3), jnp.zeros(3)
    R_xy = so3.rot_x(0.2) @ so3.rot_y(0.3)
    cases = [  # name, R_IH, a_I, R_IS0, omega_S0, beta
        ("osc_x", eye, z, so3.rot_x(OSC_AMPLITUDE_RAD), z, 0.0),
        ("osc_y", eye, z, so3.rot_y(OSC_AMPLITUDE_RAD), z, 0.0),
        ("energy", eye, z, R3d, w3d, 0.0),
        ("damped", eye, z, R3d, w3d, p.beta_Nms),
        ("accel_x", eye, jnp.array([A_STEADY_M_S2, 0.0, 0.0]), eye, z, p.beta_Nms),
        ("accel_y", eye, jnp.array([0.0, A_STEADY_M_S2, 0.0]), eye, z, p.beta_Nms),
        ("tilt_x", so3.rot_x(TILT_RAD), z, so3.rot_x(TILT_RAD), z, p.beta_Nms),
        ("tilt_y", so3.rot_y(TILT_RAD), z, so3.rot_y(TILT_RAD), z, p.beta_Nms),
        ("tilt_xy", R_xy, z, R_xy, z, p.beta_Nms),
    ]
    names = [c[0] for c in cases]
    stack = [jnp.stack([c[i] for c in cases]) for i in range(1, 6)]
    return names, stack


@jax.jit
def _run_still(R_I_H, a_I, R_I_S0, omega_S0, beta):
    p = P13_PENDULUM._replace(beta_Nms=beta)
    zero = jnp.zeros(3)
    head = RigidMotion(R_I_H, zero, zero, a_I)
    x0 = V.MedialState(pendulum.PendulumState(R_I_S0, omega_S0))
    n = int(round(T_SHORT_S / DT_S))
    xf, xs = V.simulate(V.driven(V.medial_dynamics, lambda t: head, p), x0, DT_S, n,
                        project=V.medial_project)
    xs = jax.tree_util.tree_map(lambda a, b: jnp.concatenate([a, b[None]]), xs, xf)

    def per_sample(x):
        dx = V.medial_dynamics(x, head, p)
        E, dE = jax.jvp(lambda y: pendulum.energy_J(y.pendulum, p), (x,), (dx,))
        w = x.pendulum.omega_S_rad_s
        return {"phi": V.medial_outputs(x, R_I_H), "E": E, "dE": dE, "diss": beta * (w @ w),
                "axis_I": x.pendulum.R_I_S[:, 2]}

    return jax.vmap(per_sample)(xs)


def _zero_crossing_frequency(y, dt):
    s = np.where((y[:-1] > 0) & (y[1:] <= 0))[0]
    tc = (s + y[s] / (y[s] - y[s + 1])) * dt
    return 2.0 * np.pi / np.mean(np.diff(tc))


def _simpson(y, dt):
    n = len(y) - 1  # even number of intervals required
    return dt / 3.0 * (y[0] + y[n] + 4.0 * y[1:n:2].sum() + 2.0 * y[2:n - 1:2].sum())


def _check_still():
    names, stack = _still_cases()
    out = jax.tree_util.tree_map(np.asarray, jax.vmap(_run_still)(*stack))
    idx = {n: i for i, n in enumerate(names)}
    p = P13_PENDULUM
    t = np.arange(out["E"].shape[1]) * DT_S
    m, series = {}, {"t": t}

    w_analytic = float(np.sqrt(p.m_kg * G_M_S2 * p.l_m / p.J_pivot_S[0]))
    freq = {}
    for ax, k in (("x", 0), ("y", 1)):
        w = _zero_crossing_frequency(out["phi"][idx[f"osc_{ax}"], :, k], DT_S)
        rel = abs(w / w_analytic - 1.0)
        freq[ax] = check(rel, TOL["oscillation"], rel <= TOL["oscillation"])
        m[f"oscillation_frequency_rad_s_{ax}"] = w
    m["oscillation_frequency_rel_error"] = freq
    m["oscillation_frequency_analytic_rad_s"] = w_analytic
    series["osc_phi_x"] = out["phi"][idx["osc_x"], :, 0]
    series["omega_analytic"] = w_analytic

    E = out["E"][idx["energy"]]
    scale = E[0] - (-p.m_kg * G_M_S2 * p.l_m)
    drift = np.abs(E - E[0]) / scale
    m["energy_drift_rel"] = check(drift.max(), TOL["energy"], drift.max() <= TOL["energy"])
    series["energy_drift_rel"] = drift

    d = idx["damped"]
    dE, diss = out["dE"][d], out["diss"][d]
    rate_err = np.max(np.abs(dE + diss)) / np.max(diss)
    m["energy_rate_identity_rel"] = check(rate_err, TOL["energy_rate"], rate_err <= TOL["energy_rate"])
    Ed = out["E"][d]
    dissipated = _simpson(diss, DT_S)
    bal = abs((Ed[-1] - Ed[0]) + dissipated) / dissipated
    m["energy_balance_rel"] = check(bal, TOL["energy_balance"], bal <= TOL["energy_balance"])
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (diss[1:] + diss[:-1])) * DT_S])
    series["damped_E_change"] = Ed - Ed[0]
    series["damped_minus_dissipated"] = -cum

    expected = float(np.arctan(A_STEADY_M_S2 / G_M_S2))
    steady, direction = {}, {}
    for ax, a_vec in (("x", [A_STEADY_M_S2, 0, 0]), ("y", [0, A_STEADY_M_S2, 0])):
        axis = out["axis_I"][idx[f"accel_{ax}"]]
        ang = np.arctan2(np.linalg.norm(axis[:, :2], axis=1), axis[:, 2])
        err = abs(ang[-1] - expected)
        steady[ax] = check(err, TOL["steady"], err <= TOL["steady"])
        up = np.array(a_vec, float) + np.array([0.0, 0.0, G_M_S2])
        up /= np.linalg.norm(up)
        derr = float(np.arctan2(np.linalg.norm(np.cross(axis[-1], up)), axis[-1] @ up))
        direction[ax] = check(derr, TOL["steady"], derr <= TOL["steady"])
        series[f"deflection_{ax}"] = ang
    m["steady_deflection_error_rad"] = steady
    m["steady_deflection_direction_error_rad"] = direction
    series["deflection_expected"] = expected

    tilt, mag, axis_err = {}, {}, {}
    R_I_H_all = stack[0]
    for name in ("tilt_x", "tilt_y", "tilt_xy"):
        i = idx[name]
        ax = name.split("_")[1]
        phi_end = out["phi"][i, -1]
        R_I_H = np.asarray(R_I_H_all[i])
        expected_phi = np.asarray(so3.tilt_angles(R_I_H.T))
        series[f"still_phi_{ax}"] = out["phi"][i]
        series[f"still_expected_{ax}"] = expected_phi
        axis_I = out["axis_I"][i, -1]  # pendulum axis (mass -> pivot) in I: should be vertical
        aerr = float(np.arctan2(np.linalg.norm(axis_I[:2]), axis_I[2]))
        axis_err[ax] = check(aerr, TOL["still_tilt"], aerr <= TOL["still_tilt"])
        # magnitude: angle between the pendulum axis and the head's z axis vs the head's tilt
        head_tilt = float(np.arccos(np.clip(R_I_H[2, 2], -1.0, 1.0)))
        axis_H = R_I_H.T @ axis_I
        rel = float(np.arctan2(np.linalg.norm(axis_H[:2]), axis_H[2]))
        merr = abs(rel - head_tilt)
        if ax == "xy":
            # F 2.8-2.9 read row 3 of R_HS, which depends on the pendulum's turn about its own
            # arm; for a two-axis tilt that turn is not fixed by the statics (information only).
            m["still_tilt_phi_xy_minus_tilt_of_R_HI_rad"] = float(np.max(np.abs(phi_end - expected_phi)))
            mag[ax] = check(merr, TOL["still_tilt"], merr <= TOL["still_tilt"])
            continue
        k = 0 if ax == "x" else 1
        theta = float(np.asarray(so3.tilt_angles(R_I_H))[k])
        err = float(np.max(np.abs(phi_end - np.eye(2)[k] * (-theta))))  # phi = -Theta, other 0
        tilt[ax] = check(err, TOL["still_tilt"], err <= TOL["still_tilt"])
        merr = max(merr, abs(abs(phi_end[k]) - TILT_RAD))
        mag[ax] = check(merr, TOL["still_tilt"], merr <= TOL["still_tilt"])
    m["still_tilt_error_rad"] = tilt
    m["still_tilt_axis_error_rad"] = axis_err
    m["still_tilt_magnitude_error_rad"] = mag
    return m, series


# ---------------------------------------------------------------------- SO(3) over 60 s of impact
@functools.lru_cache(maxsize=1)
def _impact_table():
    """The P13 impact motion (60 s) sampled at every RK4 stage time, shared by the impact runs."""
    from verticality import trajectories

    traj = trajectories.impact(duration_s=T_LONG_S)
    return V.tabulate(traj.motion, DT_S, int(round(T_LONG_S / DT_S)))


EVERY_SO3 = 100


@functools.partial(jax.jit, static_argnames=("n",))
def _so3_medial(table, n):
    """Medial model driven by the table, with (flag 1) and without (flag 0) the SO(3) projection."""
    p = P13_PENDULUM

    def one(flag):
        def proj(x):
            return jax.tree_util.tree_map(lambda a, b: jnp.where(flag > 0, a, b),
                                          V.medial_project(x), x)

        x0 = V.medial_rest_state(table.motion(0.0), p)
        f = V.driven(V.medial_dynamics, table.motion, p)
        xf, err = V.simulate(f, x0, DT_S, n, project=proj, every=EVERY_SO3,
                             output=lambda t, x: so3.orthonormality_error(x.pendulum.R_I_S))
        return jnp.concatenate([err, so3.orthonormality_error(xf.pendulum.R_I_S)[None]])

    return jax.vmap(one)(jnp.array([1.0, 0.0]))


@functools.partial(jax.jit, static_argnames=("n",))
def _so3_lateral_free_head(table, n):
    p, hp = P13_PENDULUM, P13_HEAD
    head0 = table.motion(0.0)._replace(R_I_B=so3.exp(jnp.array([0.6, -0.4, 0.2])))
    x0 = V.lateral_rest_state(head0, p, free_head=True)

    def f(t, x):
        tau = global_stabilizer(x.head.R_I_H, x.head.omega_H_rad_s, GLOBAL_KP, GLOBAL_KD)
        return V.lateral_dynamics(x, V.HeadInput(tau, table.motion(t).a_I_m_s2), p, hp=hp)

    def err(t, x):
        return jnp.max(jnp.stack([so3.orthonormality_error(R) for R in
                                  (x.left.R_I_S, x.right.R_I_S, x.head.R_I_H)]))

    xf, e = V.simulate(f, x0, DT_S, n, project=V.lateral_project, every=EVERY_SO3, output=err)
    return jnp.concatenate([e, err(0.0, xf)[None]])


# ------------------------------------------------------------------------ planar vs 3-D (10 s)
def _planar_inputs(t):
    tau = 0.05 * jnp.sin(2.0 * t) + 0.02 * jnp.cos(5.0 * t)
    return tau, 2.0 * jnp.sin(3.0 * t), 1.5 * jnp.cos(2.0 * t)


def _planar_params():
    p = P13_PENDULUM
    return planar.PlanarParams(m_kg=p.m_kg, l_m=p.l_m, J_kg_m2=p.J_pivot_S[0], beta_Nms=p.beta_Nms,
                               K_kg_m2=P13_HEAD.J_H[0], g_m_s2=G_M_S2)


def _angle_about_x(R):
    return jnp.arctan2(R[2, 1], R[1, 1])


TH_S0, W_S0, TH_H0, W_H0 = 0.3, -0.5, 0.1, 0.05
TH_R0 = -0.2


def _head_input_3d(t):
    tau, ah, az = _planar_inputs(t)
    return V.HeadInput(jnp.stack([tau, 0.0, 0.0]), jnp.stack([0.0, ah, az]))


@functools.partial(jax.jit, static_argnames=("n",))
def _run_planar_medial(n):
    """(planar, 3-D) angles (θ_S, θ_H) over ``n`` steps of the coronal-plane test input."""
    pp, p, hp = _planar_params(), P13_PENDULUM, P13_HEAD
    ex = jnp.array([1.0, 0.0, 0.0])

    def f_planar(t, x):
        tau, ah, az = _planar_inputs(t)
        return planar.dynamics(x, planar.PlanarInput(tau, ah, az), pp)

    x0p = planar.PlanarState(jnp.asarray(TH_S0), jnp.asarray(W_S0), jnp.asarray(TH_H0),
                             jnp.asarray(W_H0))
    _, yp = V.simulate(f_planar, x0p, DT_S, n,
                       output=lambda t, x: jnp.stack([x.theta_S_rad, x.theta_H_rad]))
    x03 = V.MedialState(pendulum.PendulumState(so3.rot_x(TH_S0), W_S0 * ex),
                        V.HeadState(so3.rot_x(TH_H0), W_H0 * ex))
    _, y3 = V.simulate(lambda t, x: V.medial_dynamics(x, _head_input_3d(t), p, hp), x03, DT_S, n,
                       project=V.medial_project,
                       output=lambda t, x: jnp.stack([_angle_about_x(x.pendulum.R_I_S),
                                                      _angle_about_x(x.head.R_I_H)]))
    return yp, y3


@functools.partial(jax.jit, static_argnames=("n",))
def _run_planar_lateral(n):
    """(planar F 2.19, 3-D) angles (θ_L, θ_R, θ_H) over ``n`` steps of the coronal-plane input."""
    pp, p, hp = _planar_params(), P13_PENDULUM, P13_HEAD
    ex = jnp.array([1.0, 0.0, 0.0])

    def f_planar(t, x):
        tau, ah, az = _planar_inputs(t)
        return V.planar_lateral_dynamics(x, planar.PlanarInput(tau, ah, az), pp)

    s = [jnp.asarray(v) for v in (TH_S0, W_S0, TH_R0, -W_S0, TH_H0, W_H0)]
    _, yp = V.simulate(f_planar, V.PlanarLateralState(*s), DT_S, n,
                       output=lambda t, x: jnp.stack([x.theta_L_rad, x.theta_R_rad, x.theta_H_rad]))
    x03 = V.LateralState(pendulum.PendulumState(so3.rot_x(TH_S0), W_S0 * ex),
                         pendulum.PendulumState(so3.rot_x(TH_R0), -W_S0 * ex),
                         V.HeadState(so3.rot_x(TH_H0), W_H0 * ex))
    _, y3 = V.simulate(lambda t, x: V.lateral_dynamics(x, _head_input_3d(t), p, hp=hp), x03, DT_S,
                       n, project=V.lateral_project,
                       output=lambda t, x: jnp.stack([_angle_about_x(x.left.R_I_S),
                                                      _angle_about_x(x.right.R_I_S),
                                                      _angle_about_x(x.head.R_I_H)]))
    return yp, y3


def _check_planar():
    m, series = {}, {}
    out = {}
    for name, fn in (("medial", _run_planar_medial), ("lateral", _run_planar_lateral)):
        yp, y3 = (np.asarray(a) for a in fn(int(round(T_SHORT_S / DT_S))))
        d = yp - y3
        err = float(np.max(np.abs(d - 2.0 * np.pi * np.round(d / (2.0 * np.pi)))))
        out[name] = check(err, TOL["planar"], err <= TOL["planar"])
        series[f"planar_{name}"] = yp
        series[f"planar3d_{name}"] = y3
    m["planar_vs_3d_max_error_rad"] = out
    return m, series


# ------------------------------------------------------------------ lateral (r = 0) vs medial
EVERY_LM = 10


@functools.partial(jax.jit, static_argnames=("n",))
def _run_lateral_vs_medial(table, n):
    p = P13_PENDULUM
    head0 = table.motion(0.0)
    _, med = V.simulate(
        V.driven(V.medial_dynamics, table.motion, p), V.medial_rest_state(head0, p), DT_S, n,
        project=V.medial_project, every=EVERY_LM,
        output=lambda t, x: (x.pendulum.R_I_S, V.medial_outputs(x, table.motion(t).R_I_B)))

    def lateral(r):
        return V.simulate(
            V.driven(V.lateral_dynamics, table.motion, p, r), V.lateral_rest_state(head0, p, r),
            DT_S, n, project=V.lateral_project, every=EVERY_LM,
            output=lambda t, x: (x.left.R_I_S, x.right.R_I_S,
                                 V.lateral_outputs(x, table.motion(t).R_I_B)))[1]

    return med, jax.vmap(lateral)(jnp.array([0.0, LATERAL_R_M]))


def _check_lateral_vs_medial():
    out = _run_lateral_vs_medial(_impact_table(), int(round(T_SHORT_S / DT_S)))
    (R_med, phi_med), (R_L, R_R, phi_lat) = jax.tree_util.tree_map(np.asarray, out)
    err = max(np.max(np.abs(R_L[0] - R_med)), np.max(np.abs(R_R[0] - R_med)))
    m = {"lateral_r0_vs_medial_max_error": check(err, TOL["lateral_r0"], err <= TOL["lateral_r0"]),
         "lateral_minus_medial_max_rad": float(np.max(np.abs(phi_lat[1] - np.tile(phi_med, 2))))}
    series = {"lm_t": np.arange(phi_med.shape[0]) * DT_S * EVERY_LM, "lm_medial": phi_med,
              "lm_lateral": phi_lat[1]}
    return m, series


# ------------------------------------------------------------------------------- controllers
def _check_controllers():
    hp = P13_HEAD
    axis = jnp.array([1.0, 1.0, 0.3])
    R0 = so3.exp(2.5 * axis / jnp.linalg.norm(axis))
    n = 5000

    @jax.jit
    def run():
        def f(t, h):
            return V.head_dynamics(
                h, global_stabilizer(h.R_I_H, h.omega_H_rad_s, GLOBAL_KP, GLOBAL_KD), hp)

        proj = lambda h: h._replace(R_I_H=so3.orthonormalize(h.R_I_H))  # noqa: E731
        hf, ang = V.simulate(f, V.HeadState(R0, jnp.zeros(3)), DT_S, n, project=proj, every=10,
                             output=lambda t, h: jnp.linalg.norm(so3.log(h.R_I_H)))
        return ang, jnp.linalg.norm(so3.log(hf.R_I_H))

    ang, final = (np.asarray(a) for a in run())
    m = {"global_stabilizer_final_angle_rad": check(final, TOL["global"], final <= TOL["global"])}

    J = hp.J_H
    poles_lin = np.sort_complex(np.linalg.eigvals(np.asarray(
        tilt_pd_closed_loop_matrix(J, PD_KP, PD_KD, PD_KD_Z))))
    worst = 0.0
    for law in (tilt_pd, tilt_pd_linearized):
        A = np.asarray(jax.jit(nonlinear_loop_jacobian, static_argnums=0)(
            law, J, PD_KP, PD_KD, PD_KD_Z))
        poles = np.sort_complex(np.linalg.eigvals(A))
        worst = max(worst, float(np.max(np.abs(poles - poles_lin))))
    roots = []
    for Ji in np.asarray(J)[:2]:
        roots.extend(np.roots([float(Ji), PD_KD, PD_KP]))
    roots.extend([0.0, -PD_KD_Z / float(J[2])])
    roots = np.sort_complex(np.asarray(roots, complex))
    worst = max(worst, float(np.max(np.abs(roots - poles_lin))))
    scale = float(np.max(np.abs(roots)))
    m["pd_poles_max_error"] = check(worst / scale, TOL["poles"], worst / scale <= TOL["poles"])
    m["pd_poles"] = [[float(z.real), float(z.imag)] for z in poles_lin]
    return m, {"global_angle": ang, "global_t": np.arange(ang.shape[0]) * DT_S * 10}


def nonlinear_loop_jacobian(law, J_H, kp, kd, kd_z):
    """``jacfwd`` of the free head under ``law`` (F 4.6–4.7 or 4.8–4.9) at upright, in exponential
    coordinates ``R_IH = exp([δ]×)``: state ``(δ, ω_H)``, ``δ̇ = d/dt log(R_IH)``."""
    hp = P13_HEAD._replace(J_H=jnp.asarray(J_H))

    def F(z):
        delta, w = z[:3], z[3:]
        R = so3.exp(delta)
        tau = law(R, w, kp, kd, kd_z=kd_z)
        wdot = V.head_angular_acceleration(V.HeadState(R, w), tau, hp)
        ddelta = jax.jvp(lambda s: so3.log(R @ so3.exp(s * w)), (0.0,), (1.0,))[1]
        return jnp.concatenate([ddelta, wdot])

    return jax.jacfwd(F)(jnp.zeros(6))


# ------------------------------------------------------------------------------------- run
@register("model-checks", "Validation of the pendulum, medial/lateral, planar models and stabilizers",
          source="F §2.1–2.2, F §4.4 (4.6–4.9), P13 §3",
          figures=lambda result, out_dir: figures(result, out_dir))
def run(quick: bool = False) -> Result:
    metrics, series = {}, {}
    simulated = 0.0
    for fn, sim_s in ((_check_still, 9 * T_SHORT_S), (_check_planar, 4 * T_SHORT_S),
                      (_check_lateral_vs_medial, 3 * T_SHORT_S), (_check_controllers, 5.0)):
        m, s = fn()
        metrics.update(m)
        series.update(s)
        simulated += sim_s
    table = _impact_table()
    n_long = int(round(T_LONG_S / DT_S))
    err_both = np.asarray(_so3_medial(table, n_long))
    err = err_both[0]
    metrics["so3_orthonormality"] = check(err.max(), TOL["so3"], err.max() <= TOL["so3"])
    metrics["so3_orthonormality_unprojected"] = float(err_both[1].max())
    series["so3_t"] = np.arange(err.shape[0]) * DT_S * EVERY_SO3
    series["so3_err"] = err
    series["so3_err_unprojected"] = err_both[1]
    simulated += 2 * T_LONG_S
    if not quick:
        e2 = np.asarray(_so3_lateral_free_head(table, n_long))
        metrics["so3_orthonormality_free_head_lateral"] = check(e2.max(), TOL["so3"],
                                                                e2.max() <= TOL["so3"])
        series["so3_err_lateral"] = e2
        simulated += T_LONG_S
    paper = {"oscillation_frequency_analytic_rad_s": metrics["oscillation_frequency_analytic_rad_s"]}
    return Result(metrics=metrics, paper=paper, series=series, simulated_s=simulated,
                  notes="tolerances: docs/models.md")


# ---------------------------------------------------------------------------------- figures
def figures(result: Result, out_dir: Path) -> list[Path]:
    from verticality import plots

    s, m = result.series, result.metrics
    out_dir = Path(out_dir)
    paths = []
    t = s["t"]

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4, sharex=False)
    k = t <= 2.0
    analytic = OSC_AMPLITUDE_RAD * np.cos(s["omega_analytic"] * t)
    ax[0, 0].plot(t[k], s["osc_phi_x"][k], label="3-D model φx")
    ax[0, 0].plot(t[k], analytic[k], "--", label="0.01 cos(√(mgl/Jxx) t)")
    ax[0, 0].set_ylabel("rad")
    ax[0, 0].set_title("Small oscillation, still head (β = 0): "
                       f"ω = {m['oscillation_frequency_rad_s_x']:.5f} vs "
                       f"{s['omega_analytic']:.5f} rad/s")
    ax[0, 0].legend(loc="upper right", fontsize=8)
    ax[1, 0].plot(t, s["osc_phi_x"] - analytic)
    ax[0, 0].set_xlabel("t (s), first 2 s")
    ax[1, 0].set_ylabel("model − analytic (rad)")
    ax[1, 0].set_xlabel("t (s): phase drift from the amplitude shift θ0²/16")
    paths.append(plots.save(fig, out_dir / "oscillation.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    ax[0, 0].semilogy(t[1:], np.maximum(s["energy_drift_rel"][1:], 1e-18))
    plots.published_line(ax[0, 0], TOL["energy"], label="tolerance 1e-6")
    ax[0, 0].set_ylabel("|E−E0| / (E0 − Emin)")
    ax[0, 0].set_title("Undamped pendulum: energy drift (RK4, 1 ms)")
    ax[0, 0].legend(fontsize=8)
    ax[1, 0].plot(t, s["damped_E_change"], label="E(t) − E(0)")
    ax[1, 0].plot(t, s["damped_minus_dissipated"], "--", label="−∫ β|ωS|² dt")
    ax[1, 0].set_ylabel("J")
    ax[1, 0].set_xlabel("t (s)")
    ax[1, 0].set_title("Damped pendulum, still head: energy balance")
    ax[1, 0].legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "energy.png"))

    fig, ax = plots.new_figure(1, 1, height_per_row=3.0)
    a = ax[0, 0]
    a.semilogy(s["so3_t"], np.maximum(s["so3_err"], 1e-18), label="medial, projected (R_IS)")
    if "so3_err_lateral" in s:
        a.semilogy(s["so3_t"], np.maximum(s["so3_err_lateral"], 1e-18),
                   label="lateral + free head, projected (R_IL, R_IR, R_IH)")
    a.semilogy(s["so3_t"], np.maximum(s["so3_err_unprojected"], 1e-18),
               label="medial, no projection (information)")
    plots.published_line(a, TOL["so3"], label="tolerance 1e-9")
    a.set_xlabel("t (s)")
    a.set_ylabel("‖RᵀR − I‖")
    a.set_title("Rotation matrices on SO(3): 60 s of the P13 impact motion")
    a.legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "so3.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    for row, name in enumerate(("medial", "lateral")):
        yp, y3 = s[f"planar_{name}"], s[f"planar3d_{name}"]
        tp = np.arange(yp.shape[0]) * DT_S
        labels = ["θS", "θH"] if name == "medial" else ["θL", "θR", "θH"]
        for j, lab in enumerate(labels):
            ax[row, 0].plot(tp, yp[:, j], label=f"{lab} planar", lw=2, alpha=0.5)
            ax[row, 0].plot(tp, y3[:, j], "--", label=f"{lab} 3-D", lw=1)
        err = m["planar_vs_3d_max_error_rad"][name]["value"]
        ax[row, 0].set_title(f"{name}: planar vs 3-D in the coronal plane (max diff {err:.1e} rad)")
        ax[row, 0].set_ylabel("rad")
        ax[row, 0].legend(fontsize=7, ncol=3)
    ax[1, 0].set_xlabel("t (s)")
    paths.append(plots.save(fig, out_dir / "planar_vs_3d.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    tl = s["lm_t"]
    for j, comp in enumerate(("φx", "φy")):
        ax[j, 0].plot(tl, s["lm_medial"][:, j], label=f"medial {comp}", lw=2, alpha=0.5)
        ax[j, 0].plot(tl, s["lm_lateral"][:, j], "--", label=f"left {comp}", lw=1)
        ax[j, 0].plot(tl, s["lm_lateral"][:, 2 + j], ":", label=f"right {comp}", lw=1)
        ax[j, 0].set_ylabel("rad")
        ax[j, 0].legend(fontsize=8)
    ax[0, 0].set_title("Lateral (r = 0.05 m) vs medial otolith angles, P13 impact motion")
    ax[1, 0].set_xlabel("t (s)")
    paths.append(plots.save(fig, out_dir / "lateral_vs_medial.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    k = t <= 3.0
    for ax_name, col in (("x", 0), ("y", 1)):
        ax[0, 0].plot(t[k], s[f"still_phi_{ax_name}"][k, col], label=f"φ{ax_name}, tilt about {ax_name}")
        ax[0, 0].axhline(s[f"still_expected_{ax_name}"][col], color="0.3", ls="--", lw=1)
    ax[0, 0].set_title(f"Still head tilted by {TILT_RAD} rad: φ → −Θ (dashed)")
    ax[0, 0].set_ylabel("rad")
    ax[0, 0].legend(fontsize=8)
    for ax_name in ("x", "y"):
        ax[1, 0].plot(t[k], s[f"deflection_{ax_name}"][k], label=f"a along {ax_name}")
    plots.published_line(ax[1, 0], s["deflection_expected"], label="atan(a/g)")
    ax[1, 0].set_title(f"Constant horizontal acceleration {A_STEADY_M_S2} m/s²: pendulum deflection")
    ax[1, 0].set_ylabel("rad")
    ax[1, 0].set_xlabel("t (s)")
    ax[1, 0].legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "still_head.png"))
    return paths
