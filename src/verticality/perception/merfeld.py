"""The Merfeld & Zupan 2002 observer of self-motion perception (F §1.4.3, F eq. 1.4), reimplemented
from its equations.

Sensors (the measurement ``y``, (6,)): the three canal signals ``α_scc`` (rad/s, head frame; the
high-pass canals of :mod:`verticality.models.canal`) and the otolith signal ``f`` (head frame, in
units of g): the gravito-inertial force ``f = g − a`` (``g`` the gravity vector, pointing down, of
length 1; ``a`` the linear acceleration in g), as a unity-gain otolith reads it. An upright head at
rest reads ``f = (0, 0, −1)``.

Internal model and the four feedback channels (head frame; the estimates carry hats)::

    α̂_scc = canal(ω̂)                        internal canal model (models.canal.HighPassCanal):
                                              ĉ' = (ω̂ − ĉ)/τ, d̂' = (ω̂ − ĉ − d̂)/τ_a,
                                              α̂ = ω̂ − ĉ − d̂
    ω̂ = c_d α_scc + kω (α_scc − α̂_scc) + kfω e_f   (angular velocity; c_d = canal_direct, 0
                                              in every preset)
    ĝ' = −(ω̂ + kf e_f) × ĝ                   (F eq. 1.4, plus the GIF correction)
    f̂ = ĝ − â,    â = ka (f − f̂)              (linear acceleration, in g)
    v̂' = g₀ â − ω̂ × v̂ − v̂/τ_v                (perceived velocity, m/s; τ_v = inf: no leak)

``e_f`` is the GIF rotation error, the rotation vector (rad) that takes the measured ``f`` to the
expected ``f̂``: axis ``f × f̂``, angle ∠(f, f̂).

Readings where the paper leaves a choice (stated so that they can be changed):

* Signs: with ``e_f`` defined as the rotation from ``f`` to ``f̂`` the published gains are all
  positive except ka; ``−(kf e_f) × ĝ`` rotates ĝ toward f, and ``kfω e_f`` enters ω̂ with the
  sign that, through ``−ω̂ × ĝ``, also turns ĝ toward f.
* The two algebraic loops (ω̂ through α̂, â through f̂) are solved exactly:
  ``ω̂ = ((c_d + kω) α + kω (ĉ + d̂) + kfω e_f)/(1 + kω)`` and ``â = ka/(1 − ka) (f − ĝ)``.
* ĝ is rotated, never scaled, so ``|ĝ| = 1`` (it starts at unit length).
* The perceived velocity is kept in the head frame (hence the transport term ``−ω̂ × v̂``); the
  Observer tool's leaky integration is the ``−v̂/τ_v`` term.
* Between samples the observer's ODE is integrated by RK4 with the measurement held
  (``substeps`` steps per sample).

Estimator interface (:mod:`verticality.estimators.base`): ``u`` is not used (pass 0 or None).
Missing data: a NaN canal component drops that component's canal error (kω = 0 on that axis);
a NaN otolith component is replaced by ĝ's, which makes its GIF difference zero; ``measured``
flags the six components; an all-NaN ``y`` is :meth:`MerfeldZupan.predict` (the internal model
running open loop: no perceived rotation or acceleration, ĝ held, v̂ leaking).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.constants import G_M_S2
from verticality.core.integrate import rk4_step
from verticality.estimators.base import keep_finite, scan_steps, split_measurement
from verticality.models.base import model_dataclass, static_field
from verticality.models.canal import HighPassCanal, HighPassState
from verticality.perception.params import MerfeldParams


class MerfeldState(NamedTuple):
    g_H: jnp.ndarray  # (3,) perceived gravity, head frame, units of g (unit length)
    c_rad_s: jnp.ndarray  # (3,) internal canal model: low-passed ω̂
    d_rad_s: jnp.ndarray  # (3,) internal canal model: adaptation
    v_H_m_s: jnp.ndarray  # (3,) perceived linear velocity, head frame


class MerfeldOut(NamedTuple):
    g_H: jnp.ndarray  # (3,) perceived gravity (unit), head frame
    omega_H_rad_s: jnp.ndarray  # (3,) perceived angular velocity
    a_H_m_s2: jnp.ndarray  # (3,) perceived linear acceleration
    v_H_m_s: jnp.ndarray  # (3,) perceived linear velocity
    measured: jnp.ndarray  # (6,) bool


def upright_state() -> MerfeldState:
    """Perceived upright and still: ĝ = (0, 0, −1), internal canal at rest."""
    z = jnp.zeros(3)
    return MerfeldState(jnp.array([0.0, 0.0, -1.0]), z, z, z)


def high_pass_canal(p: MerfeldParams) -> HighPassCanal:
    """The observer's internal canal model: the high-pass canal of :mod:`verticality.models.canal`
    with the preset's time constants."""
    return HighPassCanal(p.tau_s, p.tau_a_s)


def rotation_error(f, f_hat):
    """The rotation vector (rad) that takes ``f`` to ``f_hat`` (zero when either is zero)."""
    cross = jnp.cross(f, f_hat)
    s = jnp.linalg.norm(cross)
    angle = jnp.arctan2(s, jnp.dot(f, f_hat))
    safe = jnp.where(s > 1e-300, s, 1.0)
    return jnp.where(s > 1e-300, cross * (angle / safe), jnp.zeros(3))


@model_dataclass
class MerfeldZupan:
    """The observer as an estimator value; ``params`` a :class:`MerfeldParams` (presets in
    :mod:`verticality.perception.params`)."""

    params: MerfeldParams
    substeps: int = static_field(1)

    def init(self, x0=None, P0=None) -> MerfeldState:
        x = upright_state() if x0 is None else x0
        return MerfeldState(*(jnp.asarray(v, dtype=jnp.float64) for v in x))

    def signals(self, x: MerfeldState, alpha, f, canal_ok):
        """``(ω̂, â in g, e_f)`` for the state ``x`` and the (filled) measurement."""
        p = self.params
        a_hat = p.k_a / (1.0 - p.k_a) * (f - x.g_H)
        e_f = rotation_error(f, x.g_H - a_hat)
        k_w = jnp.where(canal_ok, p.k_omega, 0.0)
        direct = jnp.where(canal_ok, p.canal_direct, 0.0)
        w_hat = ((direct + k_w) * alpha + k_w * (x.c_rad_s + x.d_rad_s)
                 + p.k_f_omega * e_f) / (1.0 + k_w)
        return w_hat, a_hat, e_f

    def rates(self, x: MerfeldState, alpha, f, canal_ok) -> MerfeldState:
        p = self.params
        w_hat, a_hat, e_f = self.signals(x, alpha, f, canal_ok)
        # the internal canal is the canal model itself, driven by the perceived rotation ω̂
        canal_rates = high_pass_canal(p).dynamics(HighPassState(x.c_rad_s, x.d_rad_s), w_hat)
        return MerfeldState(
            g_H=-jnp.cross(w_hat + p.k_f * e_f, x.g_H),
            c_rad_s=canal_rates.c_rad_s,
            d_rad_s=canal_rates.d_rad_s,
            v_H_m_s=G_M_S2 * a_hat - jnp.cross(w_hat, x.v_H_m_s) - x.v_H_m_s / p.tau_v_s,
        )

    def _advance(self, x: MerfeldState, alpha, f, canal_ok, dt):
        h = dt / self.substeps

        def rates(t, s):
            return self.rates(s, alpha, f, canal_ok)

        def unit_gravity(s: MerfeldState) -> MerfeldState:
            return s._replace(g_H=s.g_H / jnp.linalg.norm(s.g_H))

        def rk4(s, _):
            return rk4_step(rates, 0.0, s, h, project=unit_gravity), None

        return jax.lax.scan(rk4, x, None, length=self.substeps)[0]

    def max_step_s(self) -> float:
        """The longest interval one RK4 step of the observer may span: half the inverse of a
        bound on its fastest rate (the tilt feedback kf + kfω, the canal model's 1/τ and 1/τ_a,
        the velocity leak 1/τ_v), well inside RK4's stability interval (2.78 on the real axis).
        A longer interval between samples (a gap) is stepped in pieces of at most this, the
        measurement held (the sampling of 100 Hz recordings stays one step a sample)."""
        p = self.params
        rate = p.k_f + p.k_f_omega + 1.0 / p.tau_s + 1.0 / p.tau_a_s + 1.0 / p.tau_v_s
        return 0.5 / rate

    def _fill(self, state: MerfeldState, y):
        y = jnp.asarray(y, dtype=jnp.float64)
        fill = jnp.concatenate([jnp.zeros(3), state.g_H])
        y_safe, measured = split_measurement(y, fill)
        return y_safe[:3], y_safe[3:], measured[:3], measured

    def predict(self, state: MerfeldState, u, dt) -> MerfeldState:
        return self.step(state, u, jnp.full(6, jnp.nan), dt)[0]

    def step(self, state: MerfeldState, u, y, dt):
        alpha, f, canal_ok, measured = self._fill(state, y)
        new, _ = keep_finite(self._advance(state, alpha, f, canal_ok, dt), state)
        alpha, f, canal_ok, _ = self._fill(new, y)
        w_hat, a_hat, _ = self.signals(new, alpha, f, canal_ok)
        out = MerfeldOut(new.g_H, w_hat, G_M_S2 * a_hat, new.v_H_m_s, measured)
        return new, out

    def run(self, state: MerfeldState, us, ys, dts):
        return scan_steps(self.step, state, us, ys, dts)
