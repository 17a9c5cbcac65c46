"""Process noise from parameter uncertainty ("consider" noise) for the medial EKF.

The EKF's model parameters are wrong on purpose (P13 §5: m̃ = 60 g, l̃ = 0.04 m, β̃ = 0.0005,
J̃_H = 0.15 I against the plant's 50 g, 0.06 m, 0.001, 0.125 I). A wrong parameter p̃ = p (1 + ε)
changes the model's angular accelerations by (∂ω̇/∂ log p) ε. Over one EKF step of Δt that is a
rate error of Δt (∂ω̇/∂ log p) ε, so with independent relative uncertainties σ_p the rates'
process noise gains

    Q_param = Δt² S diag(σ_p²) Sᵀ,    S = ∂(ω̇_S, ω̇_H)/∂ log(m, l, β, J_H)   (jax.jacfwd)

evaluated at the prior state and each input block (averaged over the blocks). It is state- and
input-dependent where a constant Q is not: a pendulum hanging at rest in a still head gives S = 0
(its equilibrium does not depend on m, l or β), so the filter trusts the model there; a pendulum
swinging after a change of the acceleration, or a head driven by a large torque, gives a large S.
This is the standard treatment of uncertain parameters that are not estimated (Schmidt's
"consider" states, linearized into the process noise). Nothing here knows the true parameters:
only the model's own values and the relative uncertainties.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from verticality.estimators import ekf
from verticality.params import HeadParams, PendulumParams

# relative (1 σ) uncertainty of the EKF's m, l, β, J_H: "known to within about a half"
SIGMA_RELATIVE = (0.5, 0.5, 0.5, 0.5)


def _rates(log_scale, x: ekf.MedialState, u, p_pend: PendulumParams, p_head: HeadParams):
    m, l, b, J = jnp.exp(log_scale)
    pp = p_pend._replace(m_kg=p_pend.m_kg * m, l_m=p_pend.l_m * l, beta_Nms=p_pend.beta_Nms * b,
                         J_pivot_S=None).resolved()  # J = m l² (1, 1, 1/20) of the scaled m, l
    ph = p_head._replace(J_H=p_head.J_H * J)
    d = ekf.medial_dynamics(x, u, pp, ph)
    return jnp.concatenate([d.omega_S_rad_s, d.omega_H_rad_s])


def medial_parameter_noise(x: ekf.MedialState, u_blocks, dt, p_pend: PendulumParams,
                           p_head: HeadParams, sigma_relative=SIGMA_RELATIVE) -> jnp.ndarray:
    """Q_param (12, 12) of the medial error state (δθ_S, δω_S, δθ_H, δω_H) for one step of ``dt``
    from the prior ``x`` with input blocks ``u_blocks`` (n, 6): non-zero on the two rate blocks and
    their cross terms. The pendulum's inertia follows m and l (J = m l² (1, 1, 1/20), the default
    of :class:`PendulumParams`)."""
    p_pend, p_head = p_pend.resolved(), p_head.resolved()
    sig = jnp.asarray(sigma_relative, dtype=jnp.float64)
    S = jax.vmap(lambda u: jax.jacfwd(_rates)(jnp.zeros(4), x, u, p_pend, p_head))(
        jnp.atleast_2d(u_blocks))  # (n, 6, 4)
    Ss = S * sig
    Q6 = dt**2 * jnp.mean(jnp.einsum("bip,bjp->bij", Ss, Ss), axis=0)
    idx = jnp.concatenate([jnp.arange(3, 6), jnp.arange(9, 12)])
    return jnp.zeros((ekf.N_ERR, ekf.N_ERR)).at[jnp.ix_(idx, idx)].set(Q6)
