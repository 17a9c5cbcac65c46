"""The P11 platform/inclinometer plant driven through the Lissajous trajectory (P11 §VI, F §4.3.2).

Nothing here is a new model. The plant is the planar head + pendulum of
:mod:`verticality.models.planar` (:class:`~verticality.models.planar.PlanarHead`) with P11's
parameters (:func:`p11_head`), driven through the head-frame input adapter
(:class:`~verticality.models.planar.WithHeadFrameInput`): the pivot acceleration is given in
head-frame components (what an IMU on the head provides, F's medial model input ``ᴴa``, gravity
excluded) and rotated into frame I with the head angle of the state, so the observer's model uses
its own estimate of the head tilt to do it.

- :func:`plant` — that model value; the simulator integrates it by RK4 at 1 ms with the input
  held (:func:`verticality.models.base.step_rk4`).
- :func:`observer_model` — the Newton observer's discrete model F_T of F eq. 4.1 over one observer
  interval: the same model value, discretized by
  :class:`~verticality.models.ramp_discretized.RampDiscretized` (RK4 sub-steps fed the recorded
  fast-rate inputs as ramps).
- :func:`trunk` — the trunk's motion for the planar plant, derived (by autodiff) from the one
  Lissajous definition, :func:`verticality.models.lissajous.lissajous_trunk`.

State: :class:`~verticality.models.planar.PlanarState` (θ_S, ω_S, θ_H, ω_H), angles from the
vertical. Input: :class:`~verticality.models.planar.HeadInput`. Output: the reading θ_S − θ_H.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.models.lissajous import LISSAJOUS_AMPLITUDE, lissajous_trunk
from verticality.models.planar import PlanarHead, WithHeadFrameInput
from verticality.models.ramp_discretized import RampDiscretized


def p11_head(scale: float = 1.0) -> PlanarHead:
    """P11 §VI plant (m = 50 g, l = 0.1 m, J = m l², b = 0.005, K = 100 J), masses scaled by
    ``scale``.

    ``scale = 1.1`` gives P11's perturbed observer model (m̂ = 0.055 kg, b̂ = 0.0055, Ĵ = m̂ l²,
    K̂ = 100 Ĵ; l and g unchanged).
    """
    m = 0.05 * scale
    l_m = 0.1
    J = m * l_m**2
    return PlanarHead(m_kg=m, l_m=l_m, J_kg_m2=J, beta_Nms=0.005 * scale, K_kg_m2=100.0 * J)


def plant(head: PlanarHead) -> WithHeadFrameInput:
    """The P11 plant: ``head`` driven by torque and head-frame pivot acceleration."""
    return WithHeadFrameInput(head)


def observer_model(head: PlanarHead, substeps: int) -> RampDiscretized:
    """F_T of F eq. 4.1: the plant over one observer interval (``transition(x, u_block, dt)``,
    ``u_block`` the interval's fast-rate :class:`~verticality.models.planar.HeadInput` samples,
    a multiple of ``substeps``), by ``substeps`` RK4 sub-steps with ramp inputs."""
    return RampDiscretized(plant(head), substeps)


class TrunkSample(NamedTuple):
    a_h_I_m_s2: jnp.ndarray
    a_z_I_m_s2: jnp.ndarray
    Theta_rad: jnp.ndarray
    Theta_dot_rad_s: jnp.ndarray
    Theta_ddot_rad_s2: jnp.ndarray


def trunk(t_s, amplitude=LISSAJOUS_AMPLITUDE, frequency_scale=1.0) -> TrunkSample:
    """The trunk's horizontal and vertical acceleration and its tilt Θ with two derivatives at the
    times ``t_s`` (any shape): the derivatives of
    :func:`verticality.models.lissajous.lissajous_trunk`
    by forward-mode autodiff.

    ``amplitude`` is the motion's A (default P11's 0.25; x, z and Θ all scale with it);
    ``frequency_scale`` is its time scale: the motion at time t is the published one at
    ``frequency_scale · t`` (so velocities scale by ``frequency_scale``, accelerations by its
    square, by the chain rule of the autodiff). Both may be traced values. At the defaults the
    samples are the published motion's to the bit (the products by 1.0 are exact)."""
    t = jnp.asarray(t_s, dtype=jnp.float64)

    def pos(s):
        return lissajous_trunk(frequency_scale * s, amplitude)

    def vel(s):
        return jax.jvp(pos, (s,), (jnp.ones_like(s),))

    (p, v), (_, a) = jax.jvp(vel, (t,), (jnp.ones_like(t),))
    return TrunkSample(a_h_I_m_s2=a[0], a_z_I_m_s2=a[1], Theta_rad=p[2], Theta_dot_rad_s=v[2],
                       Theta_ddot_rad_s2=a[2])
