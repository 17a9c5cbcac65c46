"""The otolith pendula of the `otolith` command and the upright-assumption replay: the P13 plant,
medial (one pendulum at the head centre) or lateral (two, at ±r along the head's y), with
parameter values given by name (SI units), checked here so that every caller gets the same
refusals."""

from __future__ import annotations

import math
from collections.abc import Mapping

import jax.numpy as jnp

from verticality.core.errors import InputError
from verticality.models.params import (
    LATERAL_R_M,
    P13_PENDULUM,
    PendulumParams,
    lateral_pendulums,
)
from verticality.models.pendulum import Pendulum

OTOLITH_PARAM_NAMES = ("m", "l", "beta", "Jxx", "Jyy", "Jzz", "r")
"""m (kg), l (m), beta (N·m·s), Jxx, Jyy, Jzz (kg·m², about the pivot, z along the arm; default
from the final m and l: m·diag(l², l², l²/20)), r (m, the lateral model's pivot offset)."""
OTOLITH_MODELS = ("medial", "lateral")


def check_otolith_values(values: Mapping[str, float], model: str = "medial") -> None:
    """Refuse (:class:`verticality.core.errors.InputError`, one line each) a name outside
    :data:`OTOLITH_PARAM_NAMES`, a value that is not finite, a non-positive m, l or J, a negative
    β, and r for any model but the lateral one."""
    if model not in OTOLITH_MODELS:
        raise InputError(f"model must be one of {', '.join(OTOLITH_MODELS)}, not {model!r}")
    for name, v in values.items():
        if name not in OTOLITH_PARAM_NAMES:
            raise InputError(f"otolith parameter {name}: unknown name; choose from "
                             f"{', '.join(OTOLITH_PARAM_NAMES)}")
        if not math.isfinite(v):
            raise InputError(f"otolith parameter {name}: {v} is not finite")
        if name in ("m", "l", "Jxx", "Jyy", "Jzz") and v <= 0.0:
            raise InputError(f"otolith parameter {name}: must be positive, not {v:g}")
        if name == "beta" and v < 0.0:
            raise InputError(f"otolith parameter beta: must not be negative, not {v:g}")
        if name == "r" and model != "lateral":
            raise InputError("otolith parameter r applies to the lateral model only")


def otolith_pendula(model: str = "medial", values: Mapping[str, float] | None = None
                    ) -> tuple[tuple, tuple[str, ...]]:
    """The :class:`~verticality.models.pendulum.Pendulum` values of the ``medial`` (one, at the head
    centre) or ``lateral`` model (two, :func:`~verticality.models.params.lateral_pendulums`) from
    the P13 plant with the parameter ``values`` given by name (:data:`OTOLITH_PARAM_NAMES`,
    checked by :func:`check_otolith_values`), with the names of their output columns' suffixes
    (``""``; ``"_left"``, ``"_right"``)."""
    o = dict(values or {})
    check_otolith_values(o, model)
    m = o.get("m", P13_PENDULUM.m_kg)
    l = o.get("l", P13_PENDULUM.l_m)  # noqa: E741
    J = jnp.array([o.get("Jxx", m * l * l), o.get("Jyy", m * l * l),
                   o.get("Jzz", m * l * l / 20.0)])
    base = PendulumParams(m_kg=m, l_m=l, J_pivot_S=J, beta_Nms=o.get("beta", P13_PENDULUM.beta_Nms))
    if model == "medial":
        return (Pendulum(base.resolved()),), ("",)
    left, right = lateral_pendulums(base, o.get("r", LATERAL_R_M))
    return (Pendulum(left), Pendulum(right)), ("_left", "_right")
