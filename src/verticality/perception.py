"""What a vestibular perception model perceives for a head motion: sensors, then the model.

:func:`perceive` takes a head motion (a :class:`verticality.io.motion.MotionRecord`: MOTION.csv
rows, recorded or from :mod:`verticality.perception_paradigms`) and returns the perceived gravity
(tilt), angular velocity, linear acceleration and velocity on the same rows, beside the true ones.

Sensors (the options of the issue the models were built for):

* canals — ``high-pass``: the model's own first-order canal (τ and adaptation of the perception
  model's parameters: Merfeld–Zupan τ, τ_a; Laurens–Angelaki τc); ``torsion``: the torsion
  pendulum of F eq. 1.2 with the same long time constant and a 5 ms short one
  (:mod:`verticality.models.canal`). Integrated by RK4, ω_H held over each interval.
* otolith — ``unity``: the papers' sensor, the gravito-inertial force ``f_H = R_HI (g_I − a_I)/g₀``
  (in g); ``pendulum``: the project's damped otolith pendulum (medial, P13 parameters) under the
  same motion (:func:`verticality.simulation.otolith_replay`): its arm direction ``s_H`` (unit, from
  pivot to mass, i.e. along the GIF). Reading: the pendulum reports a direction only, so its
  signal has length 1 g.

Tilt angles (degrees) are the angles between the perceived (or true) gravity and the head's −z
axis; :func:`pitch_up_deg` is the pitch (nose up positive) that gravity implies.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality import so3
from verticality.errors import InputError
from verticality.estimators.laurens import laurens_angelaki
from verticality.estimators.merfeld import MerfeldZupan
from verticality.io.motion import MotionRecord
from verticality.models import canal as canal_models
from verticality.models.base import step_rk4
from verticality.params import G_M_S2, gravity_I
from verticality.perception_params import LaurensParams, MerfeldParams, perception_params

MODELS = ("merfeld", "laurens")
OTOLITHS = ("unity", "pendulum")
CANALS = ("high-pass", "torsion")


class Perception(NamedTuple):
    t_s: np.ndarray  # (N,)
    g_H_perceived: np.ndarray  # (N, 3) unit, head frame
    g_H_true: np.ndarray  # (N, 3) unit
    omega_H_perceived_rad_s: np.ndarray  # (N, 3)
    omega_H_true_rad_s: np.ndarray  # (N, 3)
    a_H_perceived_m_s2: np.ndarray  # (N, 3)
    a_H_true_m_s2: np.ndarray  # (N, 3)
    v_H_perceived_m_s: np.ndarray  # (N, 3)


def canal_model(model: str, params, canal: str = "high-pass"):
    """The sensor canal that goes with the perception model's parameters."""
    if canal not in CANALS:
        raise InputError(f"unknown canal {canal!r}; known: {', '.join(CANALS)}")
    tau = params.tau_s if isinstance(params, MerfeldParams) else params.tau_c_s
    if canal == "torsion":
        return canal_models.torsion_pendulum(tau, 0.005)
    tau_a = params.tau_a_s if isinstance(params, MerfeldParams) else float("inf")
    return canal_models.high_pass(tau, None if np.isinf(tau_a) else tau_a)


def estimator(model: str, params):
    if isinstance(params, MerfeldParams):
        return MerfeldZupan(params)
    if isinstance(params, LaurensParams):
        return laurens_angelaki(params)
    raise InputError(f"unknown perception model {model!r}")


@jax.jit
def _canal_signals(canal, omega, dts):
    def body(x, inp):
        w, dt = inp
        return step_rk4(canal, x, w, dt), canal.output(x, w)

    dts = jnp.concatenate([dts, dts[-1:]])
    return jax.lax.scan(body, canal.rest_state(), (omega, dts))[1]


def canal_signals(canal, omega_H_rad_s, t_s) -> np.ndarray:
    """The canal signals on the rows: ``y_k = output(x_k, ω_k)``, then ``x_{k+1}`` by RK4 with
    ``ω_k`` held (the torsion pendulum with sub-steps of at most 1 ms)."""
    omega = jnp.asarray(omega_H_rad_s, dtype=jnp.float64)
    dts = jnp.asarray(np.diff(np.asarray(t_s, float)))
    if isinstance(canal, canal_models.TorsionPendulumCanal):
        n = max(1, int(np.ceil(float(np.max(np.diff(t_s))) / 1e-3 - 1e-9)))
        fine = jnp.repeat(omega, n, axis=0)
        y = _canal_signals(canal, fine, jnp.repeat(dts / n, n))
        return np.asarray(y[::n])
    return np.asarray(_canal_signals(canal, omega, dts))


def otolith_signals(record: MotionRecord, otolith: str = "unity") -> np.ndarray:
    """The otolith signal (N, 3), head frame, in g (see the module doc)."""
    R = np.asarray(so3.matrix_from_quat(jnp.asarray(record.q_I_H_wxyz)))
    if otolith == "unity":
        f_I = (np.asarray(gravity_I()) - record.a_I_m_s2) / G_M_S2
        return np.einsum("nji,nj->ni", R, f_I)
    if otolith == "pendulum":
        from verticality import simulation
        from verticality.params import otolith_pendula

        pendula, _ = otolith_pendula("medial", ())
        s_H, _ = simulation.otolith_replay(record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s,
                                           record.a_I_m_s2, pendula)
        return np.asarray(s_H)[:, 0, :]
    raise InputError(f"unknown otolith {otolith!r}; known: {', '.join(OTOLITHS)}")


@jax.jit
def _run(est, ys, dts):
    return est.run(est.init(None), None, ys, dts)[1]


def perceive(record: MotionRecord, model: str = "merfeld", preset: str | None = None, params=(),
             otolith: str = "unity", canal: str = "high-pass") -> Perception:
    """Perceived gravity, rotation, acceleration and velocity for the head motion ``record``
    (the perception model starts upright and still; ``params``: ``NAME=VALUE`` overrides)."""
    if otolith not in OTOLITHS:
        raise InputError(f"unknown otolith {otolith!r}; known: {', '.join(OTOLITHS)}")
    if len(record.t_s) < 2:
        raise InputError("perceive: the motion needs at least two rows")
    p = perception_params(model, preset, params)
    est = estimator(model, p)
    alpha = canal_signals(canal_model(model, p, canal), record.omega_H_rad_s, record.t_s)
    f = otolith_signals(record, otolith)
    t = np.asarray(record.t_s, float)
    dts = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    outs = _run(est, jnp.asarray(np.concatenate([alpha, f], axis=1)), jnp.asarray(dts))
    R = np.asarray(so3.matrix_from_quat(jnp.asarray(record.q_I_H_wxyz)))
    g_true = np.einsum("nji,j->ni", R, np.array([0.0, 0.0, -1.0]))
    a_true = np.einsum("nji,nj->ni", R, record.a_I_m_s2)
    return Perception(t, np.asarray(outs.g_H), g_true, np.asarray(outs.omega_H_rad_s),
                      np.asarray(record.omega_H_rad_s, float), np.asarray(outs.a_H_m_s2), a_true,
                      np.asarray(outs.v_H_m_s))


def tilt_deg(g_H) -> np.ndarray:
    """The angle (deg) between gravity ``g_H`` (N, 3) and the head's −z axis."""
    g = np.asarray(g_H, float)
    g = g / np.linalg.norm(g, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(-g[..., 2], -1.0, 1.0)))


def pitch_up_deg(g_H) -> np.ndarray:
    """Pitch (deg, nose up positive) of the head for gravity ``g_H``: atan2(−g_x, −g_z)."""
    g = np.asarray(g_H, float)
    return np.degrees(np.arctan2(-g[..., 0], -g[..., 2]))


def fit_time_constant(t_s, y) -> float:
    """Time constant (s) of an exponential decay ``y(t) > 0``: log-linear least squares."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    ok = y > 0
    if np.count_nonzero(ok) < 2:
        return float("nan")
    return float(-1.0 / np.polyfit(t[ok], np.log(y[ok]), 1)[0])


def e_fold_time(t_s, y, t0_s: float) -> float:
    """The time (s) from ``t0_s`` until ``y`` first falls below ``y(t0)/e`` (NaN if it does not)."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    m = t >= t0_s - 1e-9
    below = np.nonzero(y[m] < y[m][0] / np.e)[0]
    return float(t[m][below[0]] - t[m][0]) if below.size else float("nan")
