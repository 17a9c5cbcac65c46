"""The closed-loop simulator's plant as one model value: the head on its gimbal over the trunk
(:class:`~verticality.models.gimbal.GimbalHead`), carrying its otolith pendula
(:class:`~verticality.models.otolith_head.Otoliths`) driven by the head's motion (P13 §3, Fig. 1).

State :class:`GimbalPlantState` ``(gimbal, pendula)``, input
:class:`~verticality.models.gimbal.GimbalInput` ``(motor torques, trunk motion)``, output what the
head's sensors read without noise: the otolith angles (φ_x, φ_y) of each pendulum, then the
head's gyro ω_H.

``fixed=True`` is P13's ``fixed`` condition: the head is rigid on the trunk (ᵀR_H = I), so the head
moves as the trunk, the gimbal is locked (its state does not change; it may be ``None``) and the
motor torques are ignored.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.models.base import model_dataclass, static_field
from verticality.models.gimbal import GimbalHead, GimbalInput, GimbalState, head_motion
from verticality.models.head import FreeHead
from verticality.models.kinematics import RigidMotion
from verticality.models.otolith_head import Otoliths
from verticality.models.params import HeadParams, PendulumParams
from verticality.models.pendulum import Pendulum


class GimbalPlantState(NamedTuple):
    gimbal: GimbalState | None  # None: a locked gimbal kept out of the integration (fixed)
    pendula: tuple  # of PendulumState


@model_dataclass
class GimbalPlant:
    """Gimbal head plus otoliths (see the module doc)."""

    gimbal: GimbalHead
    otoliths: Otoliths
    fixed: bool = static_field(False)

    @property
    def head(self) -> FreeHead:
        return self.gimbal.head

    def head_motion(self, x: GimbalPlantState, u: GimbalInput):
        """(the head's RigidMotion, θ̈ or None when fixed)."""
        if self.fixed:
            return u.trunk, None
        return self.gimbal.head_motion(x.gimbal, u)

    def rate_and_motion(self, x: GimbalPlantState, u: GimbalInput):
        """(ẋ, the head's RigidMotion): the derivative and the motion the pendula see."""
        head, thetaddot = self.head_motion(x, u)
        if self.fixed:
            gimbal_rate = jax.tree_util.tree_map(jnp.zeros_like, x.gimbal)
        else:
            gimbal_rate = GimbalState(x.gimbal.thetadot_rad_s, thetaddot)
        return GimbalPlantState(gimbal_rate, self.otoliths.dynamics(x.pendula, head)), head

    def dynamics(self, x: GimbalPlantState, u: GimbalInput) -> GimbalPlantState:
        return self.rate_and_motion(x, u)[0]

    def head_orientation(self, x: GimbalPlantState, trunk: RigidMotion):
        """R_IH (the trunk's when fixed)."""
        return trunk.R_I_B if self.fixed else self.gimbal.head_orientation(x.gimbal, trunk)

    def head_angular_velocity(self, x: GimbalPlantState, trunk: RigidMotion):
        """ω_H (head frame; θ̈ does not enter it)."""
        return trunk.omega_B_rad_s if self.fixed else self.gimbal.head_angular_velocity(x.gimbal,
                                                                                        trunk)

    def otolith_angles(self, x: GimbalPlantState, trunk: RigidMotion):
        """(P, 2): each pendulum's (φ_x, φ_y) of F 2.8–2.9."""
        return self.otoliths.angles(x.pendula, self.head_orientation(x, trunk))

    def output(self, x: GimbalPlantState, u: GimbalInput):
        return jnp.concatenate([self.otolith_angles(x, u.trunk).reshape(-1),
                                self.head_angular_velocity(x, u.trunk)])

    def retract(self, x: GimbalPlantState, dx) -> GimbalPlantState:
        n = 0 if x.gimbal is None else 4
        g = None if x.gimbal is None else self.gimbal.retract(x.gimbal, dx[:4])
        return GimbalPlantState(g, self.otoliths.retract(x.pendula, dx[n:]))

    def difference(self, x1: GimbalPlantState, x0: GimbalPlantState):
        parts = [] if x1.gimbal is None else [self.gimbal.difference(x1.gimbal, x0.gimbal)]
        return jnp.concatenate(parts + [self.otoliths.difference(x1.pendula, x0.pendula)])

    def project(self, x: GimbalPlantState) -> GimbalPlantState:
        return GimbalPlantState(x.gimbal, self.otoliths.project(x.pendula))

    def rest_state(self, trunk: RigidMotion, theta_rad) -> GimbalPlantState:
        """The gimbal at ``theta_rad`` at rest relative to the trunk (θ̇ = 0, θ̈ = 0: the motors hold
        it; 0 and ignored when fixed), the pendula at rest relative to the head along the
        gravito-inertial vertical."""
        theta = jnp.zeros(2) if self.fixed else jnp.asarray(theta_rad, float)
        g0 = GimbalState(theta, jnp.zeros(2))
        head = trunk if self.fixed else head_motion(g0, jnp.zeros(2), trunk)
        return GimbalPlantState(g0, self.otoliths.rest_state(head))


def gimbal_plant(head: HeadParams, pendula: tuple[PendulumParams, ...],
                 fixed: bool = False) -> GimbalPlant:
    """The plant with a head of ``head`` parameters carrying pendula of ``pendula`` parameters
    (one at the centre: the medial plant of P13; :func:`verticality.models.params.lateral_pendulums`
    for the lateral one)."""
    return GimbalPlant(GimbalHead(FreeHead(head.resolved())),
                       Otoliths(tuple(Pendulum(p.resolved()) for p in pendula)), fixed)
