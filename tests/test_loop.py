"""The one sampled closed loop (simulation/loop.py): its order per sample and its RK4 helpers."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from verticality.core.integrate import rk4_step
from verticality.simulation import loop


def test_a_sample_reads_corrects_controls_predicts_then_advances():
    # a scalar plant x' = −x + u; the estimator keeps the last reading and counts its corrections
    def f(t, x, u):
        return -x + u

    parts = loop.LoopParts(
        read=lambda x, k: 2.0 * x,
        correct=lambda est, y, k: (est[0], est[1] + 1.0),
        control=lambda est, y, k: -0.5 * est[0] + est[1],
        predict=lambda est, u, y, k: (y, est[1]),
        advance=lambda x, u, k: loop.rk4_held(f, k * 0.1, x, u, 0.05, 2),
        record=lambda x, est, y, u, k: (x, est[1], y, u))
    (x_end, est_end), (xs, counts, ys, us) = loop.run(parts, jnp.asarray(1.0), (0.0, 0.0), 5)

    x, last, count = 1.0, 0.0, 0.0
    for k in range(5):
        y = 2.0 * x
        count += 1.0
        u = -0.5 * last + count
        # the compiled loop may round the last bit otherwise than these eager steps
        np.testing.assert_allclose([xs[k], ys[k], us[k]], [x, y, u], rtol=1e-14)
        last = y
        for i in range(2):
            x = float(rk4_step(f, k * 0.1 + i * 0.05, jnp.asarray(x), 0.05, u))
    np.testing.assert_allclose([x_end, est_end[0]], [x, last], rtol=1e-14)
    assert np.all(np.asarray(counts) == np.arange(1, 6))


def test_staged_substeps_match_the_time_form_for_inputs_given_at_the_stages():
    def w_of(t):
        return jnp.sin(3.0 * t)

    def f_time(t, x, u):
        return -2.0 * x + u + w_of(t)

    def f_staged(w, x):
        return -2.0 * x + 0.3 + w, None

    h, t0 = 0.01, 0.2
    staged = loop.rk4_staged_substeps(
        f_staged, lambda i: jnp.stack([w_of(t0 + i * h), w_of(t0 + i * h + 0.5 * h),
                                       w_of(t0 + i * h + h)]), jnp.asarray(0.7), h, 4)
    held = loop.rk4_held(f_time, t0, jnp.asarray(0.7), 0.3, h, 4)
    np.testing.assert_allclose(float(staged), float(held), rtol=1e-14)
