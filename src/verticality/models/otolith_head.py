"""The head carrying its otolith pendula (F §2.1: the medial model F 2.5–2.10, the lateral model
F 2.11–2.17) as model values, composed of :class:`~verticality.models.head.FreeHead` and
:class:`~verticality.models.pendulum.Pendulum` values (their equations are written there, once).

* :class:`Otoliths` — pendula on a head whose motion is prescribed (``u`` the head's
  :class:`RigidMotion`): a recorded head motion, the simulator's gimbal head.
* :class:`OtolithHead` — pendula on a free head (F 2.3–2.4) driven by ``u =``
  :class:`~verticality.models.head.HeadInput` ``(τ_H, a_I)``; state :class:`OtolithHeadState`
  ``(pendula, head)`` (the pendula first: the EKF's error state is δθ_S, δω_S, δθ_H, δω_H).
  Output: the otolith angles (φ_x, φ_y) of F 2.8–2.9 / 2.13–2.16 of each pendulum, then the head's
  gyro ω_H when ``gyro`` (P13 eq. 4).
* :func:`medial` — one pendulum pivoting at the head centre (F 2.5–2.9; P13 §3);
  :func:`lateral` — two pendula at ``±r`` along the head's y axis (left ``+r``, right ``−r``;
  :func:`verticality.models.params.lateral_pendulums`): their pivots see the Euler (``ω̇_H × r``)
  and centripetal (``ω_H × (ω_H × r)``) accelerations with opposite signs.
* :class:`HeadFrameAcceleration` — an input adapter: the same model driven by F §4.2.1's
  ``u = (ᴴτ, ᴴa)``, rotated into ``ᴵa = R_IH ᴴa`` with the state's own R_IH.

Full and simplified forms: the defaults keep every term; ``PendulumParams.simplified()`` drops the
pendulum's gyroscopic and Euler terms (F 2.7 and F 2.12 keep gravity, damping, head acceleration
and, for the lateral model, the centripetal term); ``HeadParams(gyroscopic=0.0)`` drops the head's
(F 2.7's ``J_H ω̇_H = τ``). The pendula do not act on the head (F §2.1.1: negligible mass).

* :class:`PlanarLateral` — the lateral model in the coronal plane (F 2.19), a planar value.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax.numpy as jnp

from verticality.models import planar
from verticality.models.base import EuclideanState, OnModel, model_dataclass, static_field
from verticality.models.head import FreeHead, HeadInput, HeadState, state_from_motion
from verticality.models.kinematics import RigidMotion
from verticality.models.params import LATERAL_R_M, HeadParams, PendulumParams, lateral_pendulums
from verticality.models.pendulum import Pendulum

PENDULUM_DIM = 6
"""Tangent dimension of one pendulum (δθ, δω) and of the head."""


def _split(dx, n):
    return [dx[PENDULUM_DIM * i:PENDULUM_DIM * (i + 1)] for i in range(n)]


@model_dataclass
class Otoliths:
    """Pendula on a head moving as ``u`` (a :class:`RigidMotion`); state: a tuple of
    :class:`PendulumState`, one per pendulum; output: their (φ_x, φ_y), concatenated."""

    pendula: tuple  # of Pendulum

    def dynamics(self, x: tuple, u: RigidMotion) -> tuple:
        return tuple(p.dynamics(xp, u) for p, xp in zip(self.pendula, x, strict=True))

    def angles(self, x: tuple, R_I_H):
        """(P, 2): each pendulum's (φ_x, φ_y) seen from the head at ``R_I_H``."""
        return jnp.stack([p.angles(xp, R_I_H) for p, xp in zip(self.pendula, x, strict=True)])

    def output(self, x: tuple, u: RigidMotion):
        return self.angles(x, u.R_I_B).reshape(-1)

    def retract(self, x: tuple, dx) -> tuple:
        return tuple(p.retract(xp, d) for p, xp, d in
                     zip(self.pendula, x, _split(dx, len(self.pendula)), strict=True))

    def difference(self, x1: tuple, x0: tuple):
        return jnp.concatenate([p.difference(a, b) for p, a, b in
                                zip(self.pendula, x1, x0, strict=True)])

    def project(self, x: tuple) -> tuple:
        return tuple(p.project(xp) for p, xp in zip(self.pendula, x, strict=True))

    def rest_state(self, u: RigidMotion) -> tuple:
        """Every pendulum at rest relative to the head, along its own pivot's gravito-inertial
        vertical."""
        return tuple(p.rest_state(u) for p in self.pendula)


class OtolithHeadState(NamedTuple):
    """The pendula (F 2.10's x₁ / F 2.17's x₂, one or two) and the free head."""

    pendula: tuple  # of PendulumState
    head: HeadState


@model_dataclass
class OtolithHead:
    """Pendula on a free head (see the module doc)."""

    head: FreeHead
    pendula: tuple  # of Pendulum
    gyro: bool = static_field(False)

    @property
    def otoliths(self) -> Otoliths:
        return Otoliths(self.pendula)

    def head_motion(self, x: OtolithHeadState, u: HeadInput) -> RigidMotion:
        return self.head.motion(x.head, u)

    def dynamics(self, x: OtolithHeadState, u: HeadInput) -> OtolithHeadState:
        head_rate, motion = self.head.rate_and_motion(x.head, u)
        return OtolithHeadState(pendula=self.otoliths.dynamics(x.pendula, motion), head=head_rate)

    def angles(self, x: OtolithHeadState):
        """(P, 2): each pendulum's otolith angles (φ_x, φ_y), rad."""
        return self.otoliths.angles(x.pendula, x.head.R_I_H)

    def output(self, x: OtolithHeadState, u: Any = None):
        """(φ_x, φ_y) of each pendulum, then ω_H when ``gyro``."""
        y = [self.angles(x).reshape(-1)]
        if self.gyro:
            y.append(self.head.output(x.head))
        return jnp.concatenate(y)

    @property
    def angle_outputs(self) -> tuple[int, ...]:
        """Indices of the outputs that are angles (an estimator wraps their residuals)."""
        return tuple(range(2 * len(self.pendula)))

    def retract(self, x: OtolithHeadState, dx) -> OtolithHeadState:
        n = PENDULUM_DIM * len(self.pendula)
        return OtolithHeadState(self.otoliths.retract(x.pendula, dx[:n]),
                                self.head.retract(x.head, dx[n:n + PENDULUM_DIM]))

    def difference(self, x1: OtolithHeadState, x0: OtolithHeadState):
        return jnp.concatenate([self.otoliths.difference(x1.pendula, x0.pendula),
                                self.head.difference(x1.head, x0.head)])

    def project(self, x: OtolithHeadState) -> OtolithHeadState:
        return OtolithHeadState(self.otoliths.project(x.pendula), self.head.project(x.head))

    def rest_state(self, head: RigidMotion) -> OtolithHeadState:
        """The head in the state of ``head``, the pendula at rest relative to it."""
        return OtolithHeadState(self.otoliths.rest_state(head), state_from_motion(head))


def medial(pendulum: PendulumParams, head: HeadParams, gyro: bool = False) -> OtolithHead:
    """F 2.5–2.9 (P13 §3): one pendulum on the free head (its pivot as ``pendulum`` says: the head
    centre by default)."""
    return OtolithHead(FreeHead(head.resolved()), (Pendulum(pendulum.resolved()),), gyro)


def lateral(pendulum: PendulumParams, head: HeadParams, r_m=LATERAL_R_M,
            gyro: bool = False) -> OtolithHead:
    """F 2.11–2.17: the left and right pendula at ``(0, ±r_m, 0)`` on the free head
    (``pendulum.pivot_H_m`` is replaced)."""
    left, right = lateral_pendulums(pendulum, r_m)
    return OtolithHead(FreeHead(head.resolved()), (Pendulum(left), Pendulum(right)), gyro)


class HeadFrameInput(NamedTuple):
    """F §4.2.1's input ``u = (ᴴτ, ᴴa)``: the centre's acceleration in the head frame."""

    tau_H_Nm: jnp.ndarray  # (3,) torque on the head, head frame
    a_H_m_s2: jnp.ndarray  # (3,) acceleration of the head centre, head frame, gravity excluded


@model_dataclass
class HeadFrameAcceleration(OnModel):
    """``model`` (an :class:`OtolithHead`) driven by a :class:`HeadFrameInput`: ``ᴵa = R_IH ᴴa``
    with the state's own ``R_IH`` (for an estimator, its estimate). Everything else is the
    model's."""

    model: OtolithHead

    def inertial_input(self, x: OtolithHeadState, u: HeadFrameInput) -> HeadInput:
        """``(τ_H, ᴵa = R_IH ᴴa)``."""
        return HeadInput(tau_H_Nm=u.tau_H_Nm, a_I_m_s2=x.head.R_I_H @ u.a_H_m_s2)

    def dynamics(self, x, u: HeadFrameInput):
        return self.model.dynamics(x, self.inertial_input(x, u))

    def output(self, x, u=None):
        return self.model.output(x)

    @property
    def angle_outputs(self) -> tuple[int, ...]:
        return self.model.angle_outputs


def replace_params(model: OtolithHead, pendulum=None, head=None) -> OtolithHead:
    """``model`` with every pendulum's parameters mapped by ``pendulum(params)`` and the head's by
    ``head(params)`` (either may be None: unchanged)."""
    pend = tuple(p if pendulum is None else dataclasses.replace(p, params=pendulum(p.params))
                 for p in model.pendula)
    h = (model.head if head is None
         else dataclasses.replace(model.head, params=head(model.head.params)))
    return dataclasses.replace(model, head=h, pendula=pend)


# ------------------------------------------------------------------- planar lateral (F 2.19)
class PlanarLateralState(NamedTuple):
    """Coronal-plane lateral model: angles about the head's x axis, 0 = hanging / upright."""

    theta_L_rad: jnp.ndarray
    omega_L_rad_s: jnp.ndarray
    theta_R_rad: jnp.ndarray
    omega_R_rad_s: jnp.ndarray
    theta_H_rad: jnp.ndarray
    omega_H_rad_s: jnp.ndarray


@model_dataclass
class PlanarLateral(EuclideanState):
    """F 2.19, the lateral model in the coronal plane, in our frames (the y–z plane of
    :mod:`verticality.models.planar`, angles about x): the head driven by the torque ``u.tau_Nm``
    about x (input :class:`verticality.models.planar.PlanarInput`, the centre's acceleration in I),
    the two pendula at ``±r_m`` on the head's y axis; output (φ_x^L, φ_x^R), each pendulum's angle
    relative to the head.

    ``J θ̈_{L,R} = −m l ((g + a_z^P) sin θ + a_h^P cos θ) − β (θ̇ − θ̇_H)``, ``K θ̈_H = τ``, with
    (a_h^P, a_z^P) the pivot's acceleration in I: the centre's plus, for the left (+r) / right (−r)
    pivot, ``R_IH (0, ∓ κ r ω_H², ± ε r ω̇_H)``. F 2.19 keeps only the centripetal term
    (``euler=0``, its ``± r ω_{h,y}²``); ``euler=1`` adds the Euler term, so that the planar form
    equals the full 3-D :func:`lateral` model restricted to the plane (in the sagittal plane the
    lateral model equals the medial one: ``ω_H ∥ y ∥ r`` makes both transport terms vanish)."""

    params: planar.PlanarHead
    r_m: float = LATERAL_R_M
    euler: float = 1.0
    centripetal: float = 1.0

    def pivot_acceleration_I(self, side, x: PlanarLateralState, u: planar.PlanarInput, omegadot_H):
        """Pivot acceleration (h, z) in I for the pivot at ``side·r`` on the head's y axis."""
        w = x.omega_H_rad_s
        # Head frame: ω × (ω × r) = (0, −r ω², 0)·side, ω̇ × r = (0, 0, r ω̇)·side,
        # for ω = (ω, 0, 0).
        t_h = -self.centripetal * side * self.r_m * w * w
        t_z = self.euler * side * self.r_m * omegadot_H
        dh, dz = planar.head_frame_to_inertial(t_h, t_z, x.theta_H_rad)
        return u.a_h_I_m_s2 + dh, u.a_z_I_m_s2 + dz

    def dynamics(self, x: PlanarLateralState, u: planar.PlanarInput) -> PlanarLateralState:
        p = self.params
        omegadot_H = u.tau_Nm / p.K_kg_m2
        a_L = self.pivot_acceleration_I(1.0, x, u, omegadot_H)
        a_R = self.pivot_acceleration_I(-1.0, x, u, omegadot_H)
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

    def output(self, x: PlanarLateralState, u=None):
        """Coronal otolith angles (φ_x^L, φ_x^R): each pendulum's angle relative to the head."""
        return jnp.stack([x.theta_L_rad - x.theta_H_rad, x.theta_R_rad - x.theta_H_rad])
