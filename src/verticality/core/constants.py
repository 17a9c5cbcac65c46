"""Physical constants written once for the whole package."""

from __future__ import annotations

import jax.numpy as jnp

G_M_S2 = 9.81
"""Magnitude of gravity used throughout, m/s²: gravity in frame I is g_I = (0, 0, −9.81)
(z up; docs/conventions.md). Every model, sensor, estimator, reading of recordings in units of g
and report takes it from here."""


def gravity_I():
    """Gravity vector in the inertial frame I (z up), m/s²."""
    return jnp.array([0.0, 0.0, -G_M_S2])
