"""The former function API of the medial and lateral models, kept as thin adapters onto the model
values for :mod:`verticality.experiments.model_checks` until it consumes them directly; nothing
here writes an equation. New code uses the values:

* :class:`verticality.models.otolith_head.OtolithHead` (``medial``, ``lateral``): pendula on a free
  head (F 2.3–2.17); :class:`~verticality.models.otolith_head.Otoliths`: pendula on a head whose
  motion is given (a :class:`RigidMotion`); :class:`~verticality.models.otolith_head.PlanarLateral`:
  F 2.19;
* :class:`verticality.models.head.FreeHead`, :class:`verticality.models.pendulum.Pendulum`;
* :func:`verticality.models.base.simulate`; :func:`verticality.models.kinematics.tabulate`.

The states here are ``MedialState(pendulum, head=None)`` and ``LateralState(left, right,
head=None)``: ``head=None`` with a kinematic drive (a :class:`RigidMotion`), a :class:`HeadState`
with a :class:`HeadInput` drive.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.integrate import rk4_step
from verticality.models import otolith_head as oh
from verticality.models.head import FreeHead, HeadInput, HeadState, state_from_motion
from verticality.models.kinematics import RigidMotion, TabulatedMotion, tabulate
from verticality.models.pendulum import Pendulum, PendulumState
from verticality.params import LATERAL_R_M, HeadParams, PendulumParams, lateral_pendulums

__all__ = [
    "HeadInput", "HeadState", "LateralState", "MedialState", "PlanarLateralState", "TabulatedMotion",
    "driven", "head_angular_acceleration", "head_dynamics", "lateral_dynamics", "lateral_outputs",
    "lateral_project", "lateral_rest_state", "medial_dynamics", "medial_outputs", "medial_project",
    "medial_rest_state", "planar_lateral_dynamics", "simulate", "tabulate",
]

PlanarLateralState = oh.PlanarLateralState


class MedialState(NamedTuple):
    pendulum: PendulumState
    head: HeadState | None = None


class LateralState(NamedTuple):
    left: PendulumState
    right: PendulumState
    head: HeadState | None = None


def head_angular_acceleration(h: HeadState, tau_H_Nm, hp: HeadParams):
    return FreeHead(hp).angular_acceleration(h.omega_H_rad_s, tau_H_Nm)


def head_dynamics(h: HeadState, tau_H_Nm, hp: HeadParams) -> HeadState:
    return FreeHead(hp).dynamics(h, HeadInput(tau_H_Nm, jnp.zeros(3)))


def _rates(params: tuple, states: tuple, head_state, drive, hp):
    """(the pendula's rates, the head's rate or None) from the values, for either kind of drive."""
    pendula = tuple(Pendulum(p) for p in params)
    if isinstance(drive, HeadInput):
        if head_state is None:
            raise ValueError("a HeadInput drive needs a state with a free head (head=HeadState)")
        if hp is None:
            raise ValueError("a free head needs HeadParams (hp)")
        d = oh.OtolithHead(FreeHead(hp), pendula).dynamics(oh.OtolithHeadState(states, head_state),
                                                             drive)
        return d.pendula, d.head
    if not isinstance(drive, RigidMotion):
        raise TypeError(f"drive must be a RigidMotion or a HeadInput, not {type(drive).__name__}")
    if head_state is not None:
        raise ValueError("a kinematic drive (RigidMotion) needs a state with head=None")
    return oh.Otoliths(pendula).dynamics(states, drive), None


def _project_head(h: HeadState | None) -> HeadState | None:
    return None if h is None else FreeHead(HeadParams()).project(h)


def medial_dynamics(x: MedialState, drive, p: PendulumParams, hp: HeadParams | None = None):
    (rate,), head_rate = _rates((p,), (x.pendulum,), x.head, drive, hp)
    return MedialState(rate, head_rate)


def medial_project(x: MedialState) -> MedialState:
    return MedialState(Pendulum(PendulumParams()).project(x.pendulum), _project_head(x.head))


def medial_rest_state(head: RigidMotion, p: PendulumParams, free_head: bool = False) -> MedialState:
    return MedialState(Pendulum(p).rest_state(head), state_from_motion(head) if free_head else None)


def medial_outputs(x: MedialState, R_I_H=None):
    R = x.head.R_I_H if x.head is not None else R_I_H
    return Pendulum(PendulumParams()).angles(x.pendulum, R)


def lateral_dynamics(x: LateralState, drive, p: PendulumParams, r_m=LATERAL_R_M,
                     hp: HeadParams | None = None):
    (left, right), head_rate = _rates(lateral_pendulums(p, r_m), (x.left, x.right), x.head, drive,
                                      hp)
    return LateralState(left, right, head_rate)


def lateral_project(x: LateralState) -> LateralState:
    pend = Pendulum(PendulumParams())
    return LateralState(pend.project(x.left), pend.project(x.right), _project_head(x.head))


def lateral_rest_state(head: RigidMotion, p: PendulumParams, r_m=LATERAL_R_M,
                       free_head: bool = False) -> LateralState:
    left, right = (Pendulum(q).rest_state(head) for q in lateral_pendulums(p, r_m))
    return LateralState(left, right, state_from_motion(head) if free_head else None)


def lateral_outputs(x: LateralState, R_I_H=None):
    R = x.head.R_I_H if x.head is not None else R_I_H
    pend = Pendulum(PendulumParams())
    return jnp.concatenate([pend.angles(x.left, R), pend.angles(x.right, R)])


def planar_lateral_dynamics(x: PlanarLateralState, u, p, r_m=LATERAL_R_M, euler=1.0,
                            centripetal=1.0) -> PlanarLateralState:
    return oh.PlanarLateral(p, r_m, euler, centripetal).dynamics(x, u)


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


def driven(dynamics: Callable, motion: Callable, *params) -> Callable:
    """``f(t, x)`` for a model driven kinematically by ``motion(t) -> RigidMotion``."""
    return lambda t, x: dynamics(x, motion(t), *params)
