"""Medial and lateral otolith models (F §2.1: eq. 2.3–2.19) in 3-D, and the planar lateral form.

Both models are a head H carrying damped spherical pendula (the otoliths); the pendulum physics is
:mod:`verticality.models.pendulum` (full Newton–Euler, F 2.5 / 2.11), written once and reused here.

* **Medial model** (F 2.5–2.9): one pendulum pivoting at the head centre.
* **Lateral model** (F 2.11–2.16): two pendula with pivots at ``±r`` along the head's y axis (left
  ``+r``, right ``−r``; ``r = 0.05 m`` by default). Their pivots see the Euler (``ω̇_H × r``) and
  centripetal (``ω_H × (ω_H × r)``) accelerations, with opposite signs on the two sides. (F writes
  ``H r = (0, 0, r)`` in the text while its figure puts the organs on the interaural axis; we follow
  the figure and the issue: the pivots lie on the head's y axis.)

**Full and simplified forms.** The defaults keep every term. ``PendulumParams.simplified()`` drops the
pendulum's gyroscopic and Euler terms (F 2.7 and F 2.12 keep gravity, damping, head acceleration and,
for the lateral model, the centripetal term); ``HeadParams(gyroscopic=0.0)`` drops the head's
gyroscopic term (F 2.7's ``J_H ω̇_H = τ``).

**The head** is either

* driven kinematically: pass a :class:`~verticality.models.kinematics.RigidMotion` (``R_IH``, ``ω_H``,
  ``ω̇_H`` and the acceleration of the head centre in frame I, gravity excluded) as ``drive``; the
  state's ``head`` field is ``None``;
* or a free rigid body (F 2.3–2.4): ``J_H ω̇_H = τ_H − γ ω_H × J_H ω_H``, ``Ṙ_IH = R_IH [ω_H]×``, with
  the state's ``head`` a :class:`HeadState` and ``drive`` a :class:`HeadInput` ``(τ_H, a_I)``.
  F's input is ``u = (τ_H, H a)``; we take the centre's acceleration in frame I (``a_H = R_IHᵀ a_I``),
  which is what a trajectory gives, and it stays valid while the head turns.

The influence of the pendula on the head is neglected (F §2.1.1: their mass is negligible).

**Outputs**: the otolith angles of F 2.8–2.9 (medial) and F 2.13–2.16 (lateral),
``φ_x = atan2([R_HS]_32, [R_HS]_33)``, ``φ_y = atan2([R_HS]_31, [R_HS]_33)``; for a still head tilted
about one axis by Θ they settle at ``φ = −Θ`` (docs/conventions.md).

**Planar lateral form (F 2.19).** In the coronal plane (rotations about the head's x axis, the plane
that contains both pivots) the two pendula see different accelerations; in the sagittal plane the
lateral model equals the medial one (``ω_H ∥ y ∥ r`` makes both transport terms vanish). F 2.19 writes
the coronal case with its own axis labels (``ω_{h,y}``, ``a_x``); here it is in our frames: the y–z
plane of :mod:`verticality.models.planar`, angles about x. F 2.19 keeps only the centripetal term
(the simplified form); ``euler=1`` adds the Euler term so that the planar form equals the full 3-D
model restricted to the plane.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality import so3
from verticality.integrate import rk4_step
from verticality.models import pendulum, planar
from verticality.models.kinematics import RigidMotion
from verticality.models.pendulum import PendulumState
from verticality.params import LATERAL_R_M, HeadParams, PendulumParams


# --------------------------------------------------------------------------------------- head
class HeadState(NamedTuple):
    """Free rigid head (F 2.3–2.4)."""

    R_I_H: jnp.ndarray  # (3, 3)
    omega_H_rad_s: jnp.ndarray  # (3,) head angular velocity w.r.t. I, in H


class HeadInput(NamedTuple):
    """Input of the free-head models (F 2.10's ``u``)."""

    tau_H_Nm: jnp.ndarray  # (3,) torque on the head, head frame (neck muscles / motors)
    a_I_m_s2: jnp.ndarray  # (3,) acceleration of the head centre, frame I, gravity excluded


def head_angular_acceleration(h: HeadState, tau_H_Nm, hp: HeadParams):
    """F 2.3: ``ω̇_H = J_H⁻¹ (τ_H − γ ω_H × J_H ω_H)`` (γ = ``hp.gyroscopic``)."""
    J = hp.J_H
    w = h.omega_H_rad_s
    return (tau_H_Nm - hp.gyroscopic * jnp.cross(w, J * w)) / J


def head_dynamics(h: HeadState, tau_H_Nm, hp: HeadParams) -> HeadState:
    """F 2.3–2.4: time derivative of the free head's state."""
    return HeadState(
        R_I_H=h.R_I_H @ so3.hat(h.omega_H_rad_s),
        omega_H_rad_s=head_angular_acceleration(h, tau_H_Nm, hp),
    )


def free_head_motion(h: HeadState, u: HeadInput, hp: HeadParams) -> RigidMotion:
    """The kinematics (RigidMotion) of a free head in state ``h`` under input ``u``."""
    return RigidMotion(
        R_I_B=h.R_I_H,
        omega_B_rad_s=h.omega_H_rad_s,
        omegadot_B_rad_s2=head_angular_acceleration(h, u.tau_H_Nm, hp),
        a_I_m_s2=jnp.asarray(u.a_I_m_s2, dtype=float),
    )


def head_state_from_motion(head: RigidMotion) -> HeadState:
    return HeadState(R_I_H=head.R_I_B, omega_H_rad_s=head.omega_B_rad_s)


def _project_head(h: HeadState | None) -> HeadState | None:
    return None if h is None else h._replace(R_I_H=so3.orthonormalize(h.R_I_H))


def _head_motion_and_rate(head_state, drive, hp):
    """(head RigidMotion, derivative of the head state or None) for either kind of drive."""
    if isinstance(drive, HeadInput):
        if head_state is None:
            raise ValueError("a HeadInput drive needs a state with a free head (head=HeadState)")
        if hp is None:
            raise ValueError("a free head needs HeadParams (hp)")
        return free_head_motion(head_state, drive, hp), head_dynamics(head_state, drive.tau_H_Nm, hp)
    if not isinstance(drive, RigidMotion):
        raise TypeError(f"drive must be a RigidMotion or a HeadInput, not {type(drive).__name__}")
    if head_state is not None:
        raise ValueError("a kinematic drive (RigidMotion) needs a state with head=None")
    return drive, None


# ------------------------------------------------------------------------------------- medial
class MedialState(NamedTuple):
    """Medial model (F 2.10's x₁): the pendulum, and the head when it is a free body."""

    pendulum: PendulumState
    head: HeadState | None = None


def medial_dynamics(x: MedialState, drive, p: PendulumParams, hp: HeadParams | None = None):
    """Time derivative of the medial model (F 2.5–2.7).

    ``drive`` is a head :class:`RigidMotion` (kinematic head, ``x.head is None``) or a
    :class:`HeadInput` (free head F 2.3, ``x.head`` a :class:`HeadState`, ``hp`` required).
    ``p`` is used as given (its pivot is the head centre unless you moved it).
    """
    head, head_rate = _head_motion_and_rate(x.head, drive, hp)
    return MedialState(pendulum=pendulum.dynamics(x.pendulum, head, p), head=head_rate)


def medial_project(x: MedialState) -> MedialState:
    """Put every rotation matrix of the state back on SO(3) (the RK4 ``project`` callback)."""
    return MedialState(pendulum=pendulum.project(x.pendulum), head=_project_head(x.head))


def medial_rest_state(head: RigidMotion, p: PendulumParams, free_head: bool = False) -> MedialState:
    """Pendulum at rest relative to ``head``, along its gravito-inertial vertical."""
    return MedialState(
        pendulum=pendulum.rest_state(head, p),
        head=head_state_from_motion(head) if free_head else None,
    )


def otolith_angles(x_pendulum: PendulumState, R_I_H):
    """(φ_x, φ_y) of one pendulum (F 2.8–2.9 / 2.13–2.16), ``R_HS = R_IHᵀ R_IS``."""
    return pendulum.otolith_angles(pendulum.R_H_S(x_pendulum, R_I_H))


def medial_outputs(x: MedialState, R_I_H=None):
    """Otolith angles (φ_x, φ_y) of the medial model (F 2.8–2.9), rad, shape (2,).

    ``R_I_H`` comes from the free head's state when there is one, else it must be given.
    """
    R = x.head.R_I_H if x.head is not None else R_I_H
    return otolith_angles(x.pendulum, R)


# ------------------------------------------------------------------------------------ lateral
class LateralState(NamedTuple):
    """Lateral model (F 2.17's x₂): left and right pendula, and the head when it is a free body."""

    left: PendulumState
    right: PendulumState
    head: HeadState | None = None


def lateral_params(p: PendulumParams, r_m=LATERAL_R_M) -> tuple[PendulumParams, PendulumParams]:
    """The left and right pendulum parameters: pivots at ``(0, +r, 0)`` and ``(0, −r, 0)`` in H."""
    p = p.resolved() if p.J_pivot_S is None or p.pivot_H_m is None else p
    ey = jnp.array([0.0, 1.0, 0.0])
    return p._replace(pivot_H_m=ey * r_m), p._replace(pivot_H_m=-ey * r_m)


def lateral_dynamics(x: LateralState, drive, p: PendulumParams, r_m=LATERAL_R_M,
                     hp: HeadParams | None = None):
    """Time derivative of the lateral model (F 2.11–2.12), pivots at ±``r_m`` along head y.

    ``drive`` as in :func:`medial_dynamics`. ``p.pivot_H_m`` is ignored (set from ``r_m``).
    """
    head, head_rate = _head_motion_and_rate(x.head, drive, hp)
    p_left, p_right = lateral_params(p, r_m)
    return LateralState(
        left=pendulum.dynamics(x.left, head, p_left),
        right=pendulum.dynamics(x.right, head, p_right),
        head=head_rate,
    )


def lateral_project(x: LateralState) -> LateralState:
    return LateralState(
        left=pendulum.project(x.left), right=pendulum.project(x.right), head=_project_head(x.head)
    )


def lateral_rest_state(head: RigidMotion, p: PendulumParams, r_m=LATERAL_R_M,
                       free_head: bool = False) -> LateralState:
    """Both pendula at rest relative to ``head``, each along its own pivot's gravito-inertial vertical."""
    p_left, p_right = lateral_params(p, r_m)
    return LateralState(
        left=pendulum.rest_state(head, p_left),
        right=pendulum.rest_state(head, p_right),
        head=head_state_from_motion(head) if free_head else None,
    )


def lateral_outputs(x: LateralState, R_I_H=None):
    """(φ_x^L, φ_y^L, φ_x^R, φ_y^R) of F 2.13–2.16, rad, shape (4,)."""
    R = x.head.R_I_H if x.head is not None else R_I_H
    return jnp.concatenate([otolith_angles(x.left, R), otolith_angles(x.right, R)])


# ------------------------------------------------------------------- planar lateral (F 2.19)
class PlanarLateralState(NamedTuple):
    """Coronal-plane lateral model: angles about the head's x axis, 0 = hanging / upright."""

    theta_L_rad: jnp.ndarray
    omega_L_rad_s: jnp.ndarray
    theta_R_rad: jnp.ndarray
    omega_R_rad_s: jnp.ndarray
    theta_H_rad: jnp.ndarray
    omega_H_rad_s: jnp.ndarray


def _planar_pivot_acceleration_I(side, x: PlanarLateralState, u: planar.PlanarInput,
                                 omegadot_H, r_m, euler, centripetal):
    """Pivot acceleration (h, z) in I for the pivot at ``side·r`` on the head's y axis."""
    w = x.omega_H_rad_s
    # Head frame: ω × (ω × r) = (0, −r ω², 0)·side, ω̇ × r = (0, 0, r ω̇)·side, for ω = (ω, 0, 0).
    t_h = -centripetal * side * r_m * w * w
    t_z = euler * side * r_m * omegadot_H
    dh, dz = planar.head_frame_to_inertial(t_h, t_z, x.theta_H_rad)
    return u.a_h_I_m_s2 + dh, u.a_z_I_m_s2 + dz


def planar_lateral_dynamics(x: PlanarLateralState, u: planar.PlanarInput, p: planar.PlanarParams,
                            r_m=LATERAL_R_M, euler=1.0, centripetal=1.0) -> PlanarLateralState:
    """F 2.19 (coronal plane) in our frames: head driven by torque ``u.tau_Nm`` about x.

    ``J θ̈_{L,R} = −m l ((g + a_z^P) sin θ + a_h^P cos θ) − β (θ̇ − θ̇_H)``, ``K θ̈_H = τ``, with
    (a_h^P, a_z^P) the pivot's acceleration in I: the centre's plus, for the left (+r) / right (−r)
    pivot, ``R_IH (0, ∓ κ r ω_H², ± ε r ω̇_H)``. F 2.19 is ``euler=0`` (its ``± r ω_{h,y}²``).
    """
    omegadot_H = u.tau_Nm / p.K_kg_m2
    a_L = _planar_pivot_acceleration_I(1.0, x, u, omegadot_H, r_m, euler, centripetal)
    a_R = _planar_pivot_acceleration_I(-1.0, x, u, omegadot_H, r_m, euler, centripetal)
    w_H = x.omega_H_rad_s
    return PlanarLateralState(
        theta_L_rad=x.omega_L_rad_s,
        omega_L_rad_s=planar.pendulum_angular_acceleration(
            x.theta_L_rad, x.omega_L_rad_s, w_H, a_L[0], a_L[1], p),
        theta_R_rad=x.omega_R_rad_s,
        omega_R_rad_s=planar.pendulum_angular_acceleration(
            x.theta_R_rad, x.omega_R_rad_s, w_H, a_R[0], a_R[1], p),
        theta_H_rad=w_H,
        omega_H_rad_s=omegadot_H,
    )


def planar_lateral_outputs(x: PlanarLateralState):
    """Coronal otolith angles (φ_x^L, φ_x^R): each pendulum's angle relative to the head."""
    return jnp.stack([x.theta_L_rad - x.theta_H_rad, x.theta_R_rad - x.theta_H_rad])


# ------------------------------------------------------------------------------- simulation
def simulate(f: Callable, x0, dt_s: float, n_steps: int, *, t0_s: float = 0.0,
             project: Callable | None = None, output: Callable | None = None, every: int = 1):
    """Integrate ``ẋ = f(t, x)`` with fixed-step RK4 under ``lax.scan``.

    Returns ``(x_final, outs)`` where ``outs`` stacks ``output(t, x)`` (default: the state) at
    ``t0 + k·every·dt`` for ``k = 0 … n_steps // every − 1`` (the initial state first).
    ``n_steps`` must be a multiple of ``every``. Call it inside ``jax.jit`` (or let the caller jit).
    """
    if n_steps % every:
        raise ValueError("n_steps must be a multiple of every")
    out_fn = output if output is not None else (lambda t, x: x)

    def step(x, k):
        t = t0_s + k * dt_s
        return rk4_step(f, t, x, dt_s, project=project), None

    def block(x, kb):
        y = out_fn(t0_s + kb * every * dt_s, x)
        x, _ = jax.lax.scan(step, x, kb * every + jnp.arange(every))
        return x, y

    return jax.lax.scan(block, x0, jnp.arange(n_steps // every))


class TabulatedMotion(NamedTuple):
    """A head (or trunk) motion sampled at the stage times of a fixed-step RK4 run.

    ``samples`` is a :class:`RigidMotion` whose leaves have a leading axis over
    ``t0_s + k·step_s`` (``step_s`` = half the integration step, so every RK4 stage time is a
    sample). Evaluating a trajectory once per sample and looking it up inside the time loop keeps
    the (autodiff-heavy) trajectory out of the integrator's compiled program and lets several runs
    share one evaluation. Pass it to jitted functions as an argument (not as a closure constant).
    """

    samples: RigidMotion
    t0_s: jnp.ndarray
    step_s: jnp.ndarray

    def motion(self, t) -> RigidMotion:
        n = self.samples.a_I_m_s2.shape[0]
        k = jnp.clip(jnp.round((t - self.t0_s) / self.step_s).astype(jnp.int32), 0, n - 1)
        return jax.tree_util.tree_map(lambda a: a[k], self.samples)


def tabulate(motion: Callable, dt_s: float, n_steps: int, t0_s: float = 0.0,
             chunk: int = 1000) -> TabulatedMotion:
    """Sample ``motion(t) -> RigidMotion`` at ``t0 + k·dt/2``, ``k = 0 … 2·n_steps`` (jitted, chunked)."""
    n = 2 * n_steps + 1
    n_pad = -(-n // chunk) * chunk
    step = 0.5 * dt_s

    @jax.jit
    def sample(k):
        return jax.lax.map(jax.vmap(lambda kk: motion(t0_s + kk * step)), k.reshape(-1, chunk))

    out = sample(jnp.arange(n_pad, dtype=jnp.float64))
    samples = jax.tree_util.tree_map(lambda a: a.reshape((n_pad,) + a.shape[2:])[:n], out)
    return TabulatedMotion(samples, jnp.asarray(t0_s, dtype=float), jnp.asarray(step, dtype=float))


def driven(dynamics: Callable, motion: Callable, *params) -> Callable:
    """``f(t, x)`` for a model driven kinematically by ``motion(t) -> RigidMotion``.

    ``dynamics`` is :func:`medial_dynamics` or :func:`lateral_dynamics`; ``params`` follow ``drive``.
    """
    return lambda t, x: dynamics(x, motion(t), *params)
