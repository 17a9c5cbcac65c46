"""Parameter presets of the vestibular perception models, with their sources.

Merfeld & Zupan 2002 observer (:mod:`verticality.perception.merfeld`)
    ``k_omega`` (kω, canal error → angular velocity), ``k_a`` (ka, GIF difference → acceleration),
    ``k_f`` (kf, GIF rotation error → gravity), ``k_f_omega`` (kfω, GIF rotation error → angular
    velocity); canal time constant ``tau_s``, adaptation ``tau_a_s`` (inf: none), the leak of
    the perceived-velocity integrator ``tau_v_s`` (inf: a pure integrator), and ``canal_direct``
    (0 in every preset): the gain of a direct path of the canal afferent into the rotation estimate,
    ``ω̂ = canal_direct·α + kω (α − α̂) + kfω e_f`` (:mod:`verticality.perception.merfeld`). With 0
    (Merfeld & Zupan 2002 as we read it) the rotation percept at mid frequencies is kω/(1 + kω) of
    the true rotation; with 1 it is about the true one, the reading under which the roll swing's
    rotation and y-velocity percepts match the Observer model's in Rader et al. 2009, Table 4.

    Naming: Merfeld & Zupan 2002 write the fourth gain k_fω ("f to ω"); Rader et al. 2009 (Table 4)
    and the later Observer tool label the same gain K_ωf ("GIFω gain"). They are one number:
    ``k_f_omega`` here.

    * ``human`` — Merfeld & Zupan 2002, human: kω = 3, ka = −2, kf = 2, kfω = 2, τ = 5.7 s,
      no adaptation, no velocity leak. (The same four gains and τ are reprinted in Rader et al.
      2009, Table 4.)
    * ``observer`` — the Observer tool's default set as printed in Rader et al. 2009, Table 4:
      the same gains, τ = 5.7 s and canal adaptation τ_a = 80 s; plus the tool's leaky integration
      of the acceleration estimate into a perceived velocity. Reading: the leak's time constant is
      not printed in the sources available to us; ``tau_v_s = 20 s`` is our choice, a parameter
      (``--param tau_v_s=...``).

Laurens & Angelaki 2017 Kalman model (:mod:`verticality.perception.laurens`)
    ``dt_s`` (δt = 0.01 s), canal time constant ``tau_c_s`` (τc = 4 s), the standard deviations of
    the rotation perturbation ``sigma_omega_rad_s`` (σΩ), the acceleration perturbation
    ``sigma_a_g`` (σA, in g), the canal noise ``sigma_v_rad_s`` (σV) and the otolith noise
    ``sigma_f_g`` (σF, in g).

    * ``default`` — δt = 0.01 s, τc = 4 s, σΩ = 40°/s, σV = 10°/s, σA = 0.3 g, σF = 0.002 g:
      the published parameter set (the list that accompanies the model, Laurens & Angelaki 2017
      code). With them the filter's post-rotatory time constant is 16.5 s, its peak gain 0.94
      and its somatogravic time constant ≈ 1.1–1.3 s: none of these is set by hand.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

from verticality.core.errors import InputError


class MerfeldParams(NamedTuple):
    k_omega: float
    k_a: float
    k_f: float
    k_f_omega: float
    tau_s: float
    tau_a_s: float = math.inf
    tau_v_s: float = math.inf
    canal_direct: float = 0.0


class LaurensParams(NamedTuple):
    dt_s: float
    tau_c_s: float
    sigma_omega_rad_s: float
    sigma_v_rad_s: float
    sigma_a_g: float
    sigma_f_g: float


MERFELD_PRESETS: dict[str, MerfeldParams] = {
    "human": MerfeldParams(k_omega=3.0, k_a=-2.0, k_f=2.0, k_f_omega=2.0, tau_s=5.7),
    "observer": MerfeldParams(k_omega=3.0, k_a=-2.0, k_f=2.0, k_f_omega=2.0, tau_s=5.7,
                              tau_a_s=80.0, tau_v_s=20.0),
}

LAURENS_PRESETS: dict[str, LaurensParams] = {
    "default": LaurensParams(dt_s=0.01, tau_c_s=4.0, sigma_omega_rad_s=math.radians(40.0),
                             sigma_v_rad_s=math.radians(10.0), sigma_a_g=0.3, sigma_f_g=0.002),
}

PRESETS = {"merfeld": MERFELD_PRESETS, "laurens": LAURENS_PRESETS}

# The values each parameter may take (least, greatest, whether inf is allowed): wide around the
# published ones, narrow enough that the models' arithmetic stays finite (a gain of 1e308 makes
# the observer's state overflow, a σ of 1e-308 the Riccati equation singular). Not a claim about
# physiology: an option outside it is refused in one line instead of giving NaN percepts.
PARAM_DOMAIN: dict[str, tuple[float, float, bool]] = {
    "k_omega": (0.0, 1e3, False), "k_a": (-1e3, 0.999, False), "k_f": (0.0, 1e3, False),
    "k_f_omega": (0.0, 1e3, False), "tau_s": (1e-2, 1e4, False), "tau_a_s": (1e-2, 1e6, True),
    "tau_v_s": (1e-2, 1e6, True), "canal_direct": (0.0, 1.0, False),
    "dt_s": (1e-4, 0.1, False), "tau_c_s": (1e-2, 1e4, False),
    "sigma_omega_rad_s": (1e-6, 1e3, False), "sigma_v_rad_s": (1e-6, 1e3, False),
    "sigma_a_g": (1e-6, 1e3, False), "sigma_f_g": (1e-6, 1e3, False),
}
DEFAULT_PRESET = {"merfeld": "human", "laurens": "default"}


def model_name(params) -> str:
    """``"merfeld"`` or ``"laurens"``: the model a parameter value belongs to."""
    if isinstance(params, MerfeldParams):
        return "merfeld"
    if isinstance(params, LaurensParams):
        return "laurens"
    raise InputError(f"not the parameters of a perception model: {params!r}")


def check_params(params) -> None:
    """Refuse (:class:`InputError`, one line) parameters outside :data:`PARAM_DOMAIN`, or Merfeld–
    Zupan gains that break the observer's algebraic loops."""
    model = model_name(params)
    p = params
    if isinstance(p, MerfeldParams) and not (p.k_omega >= 0.0 and p.k_a < 1.0 and p.k_f >= 0.0
                                             and p.k_f_omega >= 0.0):
        raise InputError(f"merfeld: need k_omega, k_f, k_f_omega >= 0 and k_a < 1 (the observer's "
                         f"algebraic loops), got {p}")
    for key in p._fields:
        lo, hi, inf_ok = PARAM_DOMAIN[key]
        v = getattr(p, key)
        if not (lo <= v <= hi or (inf_ok and v == math.inf)):
            raise InputError(f"{model}: {key} = {v:g} is outside [{lo:g}, {hi:g}]"
                             f"{' (or inf)' if inf_ok else ''}, where the model stays finite")


def perception_params(model: str, preset: str | None = None,
                      values: Mapping[str, float] | None = None):
    """The parameters of ``model`` (``merfeld`` or ``laurens``): ``preset`` (its default when None)
    with the ``values`` given by name replacing the preset's (the field names above, SI units,
    angles in rad), checked (:func:`check_params`)."""
    if model not in PRESETS:
        raise InputError(f"unknown perception model {model!r}; known: {', '.join(PRESETS)}")
    presets = PRESETS[model]
    name = DEFAULT_PRESET[model] if preset is None else preset
    if name not in presets:
        raise InputError(f"unknown preset {name!r} for {model}; known: {', '.join(presets)}")
    p = presets[name]
    values = dict(values or {})
    unknown = sorted(set(values) - set(p._fields))
    if unknown:
        raise InputError(f"{model}: unknown parameter {unknown[0]}; choose from "
                         f"{', '.join(p._fields)}")
    p = p._replace(**values)
    check_params(p)
    return p
