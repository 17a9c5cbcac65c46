"""Frozen parameter sets and the named presets of the papers.

Parameters are NamedTuples of floats (JAX pytrees): they can be passed into jitted functions,
differentiated (for identification or observability) and batched with ``vmap``. Switches that select
a simplified form of a model are floats too (1.0 = term on, 0.0 = term off), so that one compiled
function serves both forms.

Sources: P13 §5 (EKF plant), P11 §V (planar Newton-observer plant), docs/reproduction.md.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

# Gravity lives in core.constants; re-exported here for the modules that read it beside the
# parameter sets.
from verticality.core.constants import G_M_S2, gravity_I  # noqa: F401


class PendulumParams(NamedTuple):
    """Damped spherical pendulum (otolith / liquid inclinometer) pivoting on the head.

    ``J_pivot_S`` holds the principal moments of inertia about the pivot, in the pendulum frame S
    (x, y across the arm, z along it). The pivot sits at ``pivot_H_m`` in the head frame (zero for
    the medial model). The switches select the simplified forms of the thesis:
    ``gyroscopic`` (the -w x Jw term, dropped in F 2.7), ``euler`` (the -w_dot x r transport term,
    dropped in F 2.12), ``centripetal`` (the w x (w x r) transport term, kept in F 2.12).
    """

    m_kg: float = 0.05
    l_m: float = 0.06
    J_pivot_S: jnp.ndarray = None  # (3,) kg m^2; None means m * (l^2, l^2, l^2 / 20)
    beta_Nms: float = 0.001
    pivot_H_m: jnp.ndarray = None  # (3,) m; None means the head centre
    gyroscopic: float = 1.0
    euler: float = 1.0
    centripetal: float = 1.0

    def resolved(self) -> PendulumParams:
        """The same parameters with the ``None`` defaults filled in as arrays."""
        J = self.J_pivot_S
        if J is None:
            J = self.m_kg * jnp.array([self.l_m**2, self.l_m**2, self.l_m**2 / 20.0])
        r = self.pivot_H_m
        if r is None:
            r = jnp.zeros(3)
        return self._replace(J_pivot_S=jnp.asarray(J, dtype=float), pivot_H_m=jnp.asarray(r, float))

    def simplified(self) -> PendulumParams:
        """The simplified form of F 2.7 / 2.12: no gyroscopic and no Euler term."""
        return self._replace(gyroscopic=0.0, euler=0.0)


class HeadParams(NamedTuple):
    """Rigid head: principal inertia about its centre (head frame), and the gyroscopic switch."""

    J_H: jnp.ndarray = None  # (3,) kg m^2; None means P13's 0.125 each
    gyroscopic: float = 1.0

    def resolved(self) -> HeadParams:
        J = self.J_H if self.J_H is not None else jnp.array([0.125, 0.125, 0.125])
        return self._replace(J_H=jnp.asarray(J, dtype=float))


# P13 §5 (docs/reproduction.md, `ekf-*`): the plant.
P13_PENDULUM = PendulumParams(m_kg=0.05, l_m=0.06, beta_Nms=0.001).resolved()
P13_HEAD = HeadParams(J_H=jnp.array([0.125, 0.125, 0.125])).resolved()
# P13 §5: the parameters known to the EKF (deliberately wrong).
P13_EKF_PENDULUM = PendulumParams(m_kg=0.06, l_m=0.04, beta_Nms=0.0005).resolved()
P13_EKF_HEAD = HeadParams(J_H=jnp.array([0.15, 0.15, 0.15])).resolved()
P13_KP_NM_RAD = 32.0
P13_KD_NMS_RAD = 5.0

# F §4.5.2 (the tilt–translation ambiguity experiments): "critically damped dynamic behavior of
# otoliths with natural frequency of about 300 Hz" and "the head's moment of inertia was about
# 0.0174 kg·m²" (F's sources for both are biomechanical and vestibular studies it cites).
F452_OTOLITH_NATURAL_HZ = 300.0
F452_OTOLITH_DAMPING_RATIO = 1.0  # critically damped
F452_HEAD_INERTIA_KG_M2 = 0.0174

# Lateral model default: pivots at +-r along head y (F Fig. 2.3).
LATERAL_R_M = 0.05


def lateral_pendulums(p: PendulumParams, r_m=LATERAL_R_M) -> tuple[PendulumParams, PendulumParams]:
    """The lateral model's (left, right) pendulum parameters: ``p`` with its pivot at ``(0, +r, 0)``
    and at ``(0, −r, 0)`` in the head frame (F Fig. 2.3: the organs on the interaural axis; F's
    text writes ``H r = (0, 0, r)``). The one place where the lateral pivots are placed."""
    p = p.resolved()
    return (p._replace(pivot_H_m=jnp.array([0.0, r_m, 0.0])),
            p._replace(pivot_H_m=jnp.array([0.0, -r_m, 0.0])))
