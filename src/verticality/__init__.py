"""verticality: estimating the gravitational vertical the way a vestibular system does.

Importing the package switches JAX to float64 before any module builds an array, so parameter
presets created at import time are double precision whatever is imported first.
"""

import jax as _jax

_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"
