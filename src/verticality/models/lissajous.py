"""P11's Lissajous trunk motion (P11 §VI, F §4.3.2), defined once.

The planar P11 plant (:mod:`verticality.models.lissajous_plant`) and the 3-D trajectory
(:func:`verticality.simulation.trajectories.lissajous`) are both views of it: it sits beside the
models so that a model never depends on the simulation layer.
"""

from __future__ import annotations

import jax.numpy as jnp

LISSAJOUS_AMPLITUDE = 0.25  # P11 §VI's A (m; the tilt's amplitude is A·π rad)


def lissajous_trunk(t_s, amplitude: float = LISSAJOUS_AMPLITUDE):
    """P11 §VI / F §4.3.2, the one definition of the Lissajous trunk motion:
    ``(x, z, Θ)(t) = A·(sin 0.5πt, sin πt, π sin 2πt)``, A = 0.25 — horizontal and vertical
    position (m) and tilt (rad, about the axis normal to the plane), stacked on a leading axis of
    3 (``t_s`` any shape). :func:`verticality.simulation.trajectories.lissajous` (3-D) and
    :func:`verticality.models.lissajous_plant.trunk` (planar, with derivatives) are views of it."""
    A = amplitude
    return jnp.stack([A * jnp.sin(0.5 * jnp.pi * t_s), A * jnp.sin(jnp.pi * t_s),
                      A * jnp.pi * jnp.sin(2.0 * jnp.pi * t_s)])
