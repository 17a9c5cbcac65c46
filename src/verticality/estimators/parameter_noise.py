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
only the model value's own parameters and the relative uncertainties.

The derivative is taken through the model value itself: its parameter leaves are scaled
(:func:`scaled`) and its ``dynamics`` called. The pendulum's inertia about the pivot scales as
m l² (a geometrically similar pendulum: the default ``J = m l² (1, 1, 1/20)`` of
:class:`PendulumParams` stays that of the scaled m and l).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from verticality.estimators import ekf
from verticality.models.head import HeadInput
from verticality.models.otolith_head import OtolithHead, OtolithHeadState, replace_params

# relative (1 σ) uncertainty of the EKF's m, l, β, J_H: "known to within about a half"
SIGMA_RELATIVE = (0.5, 0.5, 0.5, 0.5)


def scaled(model: OtolithHead, log_scale) -> OtolithHead:
    """``model`` with every pendulum's m, l, β scaled by exp(log_scale[0:3]) (J_S by m l²) and the
    head's J_H by exp(log_scale[3])."""
    m, l, b, J = jnp.exp(log_scale)
    return replace_params(
        model,
        pendulum=lambda p: p._replace(m_kg=p.m_kg * m, l_m=p.l_m * l, beta_Nms=p.beta_Nms * b,
                                      J_pivot_S=p.J_pivot_S * (m * l * l)),
        head=lambda h: h._replace(J_H=h.J_H * J))


def _rates(log_scale, model: OtolithHead, x: OtolithHeadState, u: HeadInput):
    d = scaled(model, log_scale).dynamics(x, u)
    return jnp.concatenate([p.omega_S_rad_s for p in d.pendula] + [d.head.omega_H_rad_s])


def medial_parameter_noise(model: OtolithHead, x: OtolithHeadState, u_blocks: HeadInput, dt,
                           sigma_relative=SIGMA_RELATIVE) -> jnp.ndarray:
    """Q_param (12, 12) of the medial error state (δθ_S, δω_S, δθ_H, δω_H) for one step of ``dt``
    from the prior ``x`` with input blocks ``u_blocks`` (a :class:`HeadInput` whose leaves have a
    leading axis over the blocks, in frame I): non-zero on the two rate blocks and their cross
    terms."""
    sig = jnp.asarray(sigma_relative, dtype=jnp.float64)
    S = jax.vmap(lambda u: jax.jacfwd(_rates)(jnp.zeros(4), model, x, u))(u_blocks)  # (n, 6, 4)
    Ss = S * sig
    Q6 = dt**2 * jnp.mean(jnp.einsum("bip,bjp->bij", Ss, Ss), axis=0)
    idx = jnp.concatenate([jnp.arange(3, 6), jnp.arange(9, 12)])
    return jnp.zeros((ekf.N_ERR, ekf.N_ERR)).at[jnp.ix_(idx, idx)].set(Q6)
