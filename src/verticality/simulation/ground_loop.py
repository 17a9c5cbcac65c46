"""The closed loop of T's two-segment body on moving ground (`ground-*`): the nonlinear body,
an LQR on the joint states (T eq. 16's linearization at upright) tracking a self-motion
reference, the ground's inclination a sum of sines; 100 Hz samples, the torque held over each and
the body integrated by 10 RK4 sub-steps with the ground motion at every stage. The readings of T
behind it are in :mod:`verticality.experiments.ground`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from verticality.models.body import HUMAN_TWO_SEGMENT, GroundInput, TwoSegmentBody, upright
from verticality.models.linearize import LinearModel, linearize, select_inputs
from verticality.simulation import loop

FS_HZ = 100.0
SUBSTEPS = 10

_DEG = np.pi / 180.0


def ground_motion(t):
    """``F_d = (θ1, θ̇1, θ̈1)`` at time t."""
    w1, w2 = 2 * np.pi * 0.1, 2 * np.pi * 0.35
    a1, a2 = 1.8 * _DEG, 1.2 * _DEG
    return jnp.array([
        a1 * jnp.sin(w1 * t) + a2 * jnp.sin(w2 * t + 1.0),
        a1 * w1 * jnp.cos(w1 * t) + a2 * w2 * jnp.cos(w2 * t + 1.0),
        -a1 * w1**2 * jnp.sin(w1 * t) - a2 * w2**2 * jnp.sin(w2 * t + 1.0),
    ])


def joint_reference(t):
    """Self-motion ``(θ2, θ3, θ̇2, θ̇3)`` reference."""
    w2, w3 = 2 * np.pi * 0.2, 2 * np.pi * 0.5
    a2, a3 = 2.0 * _DEG, 5.0 * _DEG
    return jnp.array([a2 * jnp.sin(w2 * t), a3 * jnp.sin(w3 * t + 0.5),
                      a2 * w2 * jnp.cos(w2 * t), a3 * w3 * jnp.cos(w3 * t + 0.5)])


def linear_body(body: TwoSegmentBody = HUMAN_TWO_SEGMENT) -> LinearModel:
    """T eq. 16: the body linearized at upright, inputs ``(τ2, τ3, θ1, θ̇1, θ̈1)``."""
    return linearize(body, *upright())


def lqr_gain(body: TwoSegmentBody = HUMAN_TWO_SEGMENT) -> np.ndarray:
    import control

    lin = select_inputs(linear_body(body), [0, 1])  # the joint torques
    K, _, _ = control.lqr(np.asarray(lin.A), np.asarray(lin.B), np.diag([1e4, 1e4, 1e2, 1e2]),
                          np.eye(2) * 1e-2)
    return np.asarray(K)


def simulate_truth(n: int, body: TwoSegmentBody = HUMAN_TWO_SEGMENT):
    """Nonlinear trial (:func:`verticality.simulation.loop.run`, the LQR fed the true joint
    state, no estimator in the loop): per 100 Hz sample, ``(t, x, u, F_d, y_e)`` (torque held
    over the sample, the ground motion evaluated at every RK4 stage)."""
    K = jnp.asarray(lqr_gain(body))
    h = 1.0 / (FS_HZ * SUBSTEPS)

    def f(w, x):
        return body.dynamics(x, w), None

    def control(est, x, k):
        return -K @ (x - joint_reference(k / FS_HZ))

    def advance(x, u, k):
        t = k / FS_HZ

        def stages(i):
            ts = t + i * h
            return GroundInput(jnp.broadcast_to(u, (3, 2)), jnp.stack(
                [ground_motion(ts), ground_motion(ts + 0.5 * h), ground_motion(ts + h)]))

        return loop.rk4_staged_substeps(f, stages, x, h, SUBSTEPS)

    def record(x, est, y, u, k):
        d = ground_motion(k / FS_HZ)
        return x, u, d, body.output(x, GroundInput(u, d))

    parts = loop.LoopParts(lambda x, k: x, loop.unchanged, control, loop.unchanged, advance,
                           record)
    _, (xs, us, ds, ys) = jax.jit(lambda: loop.run(parts, jnp.zeros(4), (), n))()
    return np.arange(n) / FS_HZ, xs, us, ds, ys
