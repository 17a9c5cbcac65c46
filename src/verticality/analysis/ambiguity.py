"""The tilt–translation ambiguity in steady state (F §3.2, eq. 3.10–3.18): exact and small-angle.

An otolith pendulum at rest relative to its head lines up with the **specific force** at its pivot,
the gravito-inertial vector that an accelerometer reads,

    f_H = a_H − g_H = a_H + g u_H,        u_H = R_IHᵀ e3  (the world's up in the head frame),

with ``a_H`` the head's linear acceleration in head-frame components (gravity excluded, z up) and
``g = G_M_S2`` (core/constants.py). The steady state of the project's pendulum model
(:class:`verticality.models.pendulum.Pendulum`, at rest relative to a still or uniformly accelerated
head, the pendulum's turn about its own arm being the smallest rotation from the head) has its
arm along ``−f_H``, and the otolith angles of F 2.8–2.9 (``φ_x = atan2([R_HS]32, [R_HS]33)``,
``φ_y = atan2([R_HS]31, [R_HS]33)``) are then

    tan φ_x = −f_y / f_z,     tan φ_y = −f_x / f_z.                                      (1)

With the tilt angles of F 3.8–3.9 (``tan Θ_x = u_y/u_z``, ``tan Θ_y = u_x/u_z``), (1) gives every
direction of the ambiguity:

* otolith angles from acceleration and tilt (:func:`otolith_angles`): (1) with
  ``u_H = (tan Θ_y, tan Θ_x, 1)/√(1 + tan²Θ_x + tan²Θ_y)``;
* head acceleration from the otolith angles, the tilt and the vertical acceleration ``a_z`` that
  the saccule measures (:func:`head_acceleration`; F 3.11, 3.13–3.18)::

      a_x = −(a_z + g u_z) tan φ_y − g u_x,     a_y = −(a_z + g u_z) tan φ_x − g u_y;    (2)

* head tilt from the otolith angles and a known acceleration (:func:`head_tilt`; the observer of
  F Fig. 4.11): ``u_H = (λ d − a_H)/g`` with ``d = (−tan φ_y, −tan φ_x, 1)`` and ``λ > 0`` such
  that ``|u_H| = 1``.

For an upright head (Θ = 0) and ``a_z = 0``, (2) is ``a_x = −g tan φ_y`` (F 3.11), whose small-angle
form is ``a_x ≈ −g φ_y`` (F 3.12). With one tilt in the plane of the acceleration, (2) multiplied by
``cos φ`` is

    a_x cos φ_y + a_z sin φ_y = −g sin(φ_y + Θ_y)                                      (F 3.16)

and for a small pendulum angle (``cos φ ≈ 1``, ``sin φ ≈ φ``, the head's tilt kept exact)

    a_x ≈ −g sin(φ_y + Θ_y) − a_z φ_y,    a_y ≈ −g sin(φ_x + Θ_x) − a_z φ_x,           (F 3.17–3.18)

the small-angle forms here (``small_angle=True``); they agree with (2) to second order in the
angles. F writes them per plane: with a large tilt about one axis the other axis' form is off at
first order (by ``g (φ_y + Θ_y)(1 − cos Θ_x)`` for a_x), since the two planes share ``u_z``.

**The printed equations.** F 3.10–3.18 are printed as ``a_x = g tan φ_y``,
``a_x = (g − a_z) tan φ_y``, ``a_z sin φ_y + a_x cos φ_y = g sin(φ_y + Θ_y)`` and
``a_x = g sin(φ_y + Θ_y) − a_z φ_y``. Against the model (verified to 1e-12 in
``tests/test_ambiguity.py``) they hold only with three sign conventions the thesis does not state,
each opposite to its own definitions elsewhere:
(i) the pendulum angle positive when it leans *back* under a forward acceleration (F's text),
i.e. ``φ_F = −φ`` of F 2.8–2.9; (ii) the head tilt ``Θ_F = −Θ`` of F 3.8–3.9; (iii) ``a_z`` positive
*downward* — F's text has the head "accelerated forward and up" with z up, and then the factor is
``g + a_z`` (an upward push is felt as heavier gravity), not the printed ``g − a_z``. We use the
project's conventions (F 2.8–2.9, F 3.8–3.9, head frame z up) and the signs of (2), which the model
confirms. Two smaller points: F's text before 3.10 names the sagittal pendulum angle ``φ_x`` while
3.10–3.12 write ``φ_y`` (the angle about the head's y axis, F 2.9: we follow the equations); and
F 3.14–3.15 hold simultaneously in 3-D only with the pendulum's turn about its arm at the smallest
rotation from the head (F 2.8–2.9 read row 3 of ``R_HS``, which depends on that turn;
``docs/conventions.md``).

**Planar forms** (:func:`planar_reading`, :func:`planar_head_acceleration`,
:func:`planar_head_tilt`) use the convention of :mod:`verticality.models.planar`: rotations about
the head's x axis (the coronal plane), the reading ``r = θ_S − θ_H`` (= φ_x), the head angle ``θ_H``
(= Θ_x) and the acceleration's head-frame components ``(a_h, a_z)`` along the head's y and z axes::

    r = atan2(−(a_h + g sin θ_H), a_z + g cos θ_H),     a_h = −(a_z + g cos θ_H) tan r − g sin θ_H.

For the sagittal plane :mod:`verticality.models.planar` takes ``h = −x`` and rotations about y: then
``r = −φ_y``, ``θ_H = −Θ_y`` and ``a_h = −a_x`` (:func:`sagittal_to_planar`).

Everything is vectorized (NumPy or JAX arrays broadcast together) and differentiable.
"""

from __future__ import annotations

import jax.numpy as jnp

from verticality.core.constants import G_M_S2


def up_H(theta_x_rad, theta_y_rad):
    """The world's up axis in the head frame, ``R_IHᵀ e3`` (..., 3), from the tilt angles of
    F 3.8–3.9 (|Θ| < 90°): ``(tan Θ_y, tan Θ_x, 1)`` normalized."""
    tx, ty = jnp.tan(theta_x_rad), jnp.tan(theta_y_rad)
    tx, ty = jnp.broadcast_arrays(tx, ty)
    v = jnp.stack([ty, tx, jnp.ones_like(tx)], -1)
    return v / jnp.linalg.norm(v, axis=-1, keepdims=True)


def specific_force_H(a_H_m_s2, theta_x_rad=0.0, theta_y_rad=0.0, g_m_s2=G_M_S2):
    """``f_H = a_H + g u_H`` (..., 3): what an accelerometer on the head reads (head frame)."""
    return jnp.asarray(a_H_m_s2) + g_m_s2 * up_H(theta_x_rad, theta_y_rad)


def otolith_angles(a_H_m_s2, theta_x_rad=0.0, theta_y_rad=0.0, g_m_s2=G_M_S2, small_angle=False):
    """Steady-state otolith angles ``(φ_x, φ_y)`` (..., 2) of F 2.8–2.9 for a head tilted by
    ``(Θ_x, Θ_y)`` (F 3.8–3.9) and accelerated by ``a_H`` (..., 3; head frame, gravity excluded):
    eq. (1) of the module doc. ``small_angle``: the inverse of F 3.17–3.18 to first order in φ,
    ``φ_y ≈ −(a_x + g sin Θ_y)/(a_z + g cos Θ_y)`` (and x alike)."""
    a = jnp.asarray(a_H_m_s2)
    if small_angle:
        phi_x = (-(a[..., 1] + g_m_s2 * jnp.sin(theta_x_rad))
                 / (a[..., 2] + g_m_s2 * jnp.cos(theta_x_rad)))
        phi_y = (-(a[..., 0] + g_m_s2 * jnp.sin(theta_y_rad))
                 / (a[..., 2] + g_m_s2 * jnp.cos(theta_y_rad)))
        return jnp.stack(jnp.broadcast_arrays(phi_x, phi_y), -1)
    f = specific_force_H(a, theta_x_rad, theta_y_rad, g_m_s2)
    return jnp.stack([jnp.arctan2(-f[..., 1], f[..., 2]), jnp.arctan2(-f[..., 0], f[..., 2])], -1)


def head_acceleration(phi_x_rad, phi_y_rad, a_z_H_m_s2=0.0, theta_x_rad=0.0, theta_y_rad=0.0,
                      g_m_s2=G_M_S2, small_angle=False):
    """The head's acceleration ``a_H`` (..., 3; head frame, gravity excluded) that the otolith
    angles ``(φ_x, φ_y)`` indicate, given the head's tilt ``(Θ_x, Θ_y)`` and the vertical
    acceleration ``a_z`` measured by the saccule (returned as the third component): eq. (2) of the
    module doc (F 3.11, 3.13–3.16), or with ``small_angle`` F 3.17–3.18. ``Θ = 0``: the upright
    assumption (F 3.14–3.15)."""
    phi_x, phi_y, a_z, tx, ty = jnp.broadcast_arrays(
        *(jnp.asarray(v, dtype=float) for v in (phi_x_rad, phi_y_rad, a_z_H_m_s2, theta_x_rad,
                                                theta_y_rad)))
    if small_angle:
        a_x = -g_m_s2 * jnp.sin(phi_y + ty) - a_z * phi_y
        a_y = -g_m_s2 * jnp.sin(phi_x + tx) - a_z * phi_x
    else:
        u = up_H(tx, ty)
        f_z = a_z + g_m_s2 * u[..., 2]
        a_x = -f_z * jnp.tan(phi_y) - g_m_s2 * u[..., 0]
        a_y = -f_z * jnp.tan(phi_x) - g_m_s2 * u[..., 1]
    return jnp.stack([a_x, a_y, a_z], -1)


def head_tilt(phi_x_rad, phi_y_rad, a_H_m_s2, g_m_s2=G_M_S2):
    """The head's tilt ``(Θ_x, Θ_y)`` (..., 2) from the otolith angles and a known acceleration
    ``a_H`` (..., 3): ``u_H = (λ d − a_H)/g``, ``d = (−tan φ_y, −tan φ_x, 1)``, ``λ`` the positive
    root of ``|λ d − a_H| = g`` (the specific force points up in the head frame, ``f_z > 0``).
    Needs ``|a_H| < g`` for a unique answer."""
    a = jnp.asarray(a_H_m_s2, dtype=float)
    d = jnp.stack(jnp.broadcast_arrays(-jnp.tan(phi_y_rad), -jnp.tan(phi_x_rad),
                                       jnp.ones_like(jnp.asarray(phi_x_rad, dtype=float))), -1)
    dd = jnp.sum(d * d, -1)
    da = jnp.sum(d * a, -1)
    aa = jnp.sum(a * a, -1)
    lam = (da + jnp.sqrt(da * da - dd * (aa - g_m_s2**2))) / dd
    u = lam[..., None] * d - a
    return jnp.stack([jnp.arctan2(u[..., 1], u[..., 2]), jnp.arctan2(u[..., 0], u[..., 2])], -1)


# ----------------------------------------------------------------------------------------------
# One plane (the convention of verticality.models.planar: rotations about the head's x axis)
# ----------------------------------------------------------------------------------------------


def _coronal(a_h, a_z):
    a_h, a_z = jnp.broadcast_arrays(jnp.asarray(a_h, dtype=float), jnp.asarray(a_z, dtype=float))
    return jnp.stack([jnp.zeros_like(a_h), a_h, a_z], -1)


def planar_reading(a_h_H_m_s2, a_z_H_m_s2, theta_H_rad, g_m_s2=G_M_S2, small_angle=False):
    """Steady-state reading ``r = θ_S − θ_H`` of the planar pendulum (``PlanarPendulum.output``)
    on a head at ``θ_H`` accelerated by ``(a_h, a_z)`` (head frame): :func:`otolith_angles` in the
    coronal plane, ``r = atan2(−(a_h + g sin θ_H), a_z + g cos θ_H)``. ``small_angle``: first order
    in r (the inverse of F 3.17)."""
    return otolith_angles(_coronal(a_h_H_m_s2, a_z_H_m_s2), theta_H_rad, 0.0, g_m_s2,
                          small_angle)[..., 0]


def planar_head_acceleration(reading_rad, a_z_H_m_s2, theta_H_rad, g_m_s2=G_M_S2,
                             small_angle=False):
    """The horizontal head-frame acceleration ``a_h`` that a reading indicates, for a head at
    ``θ_H`` with vertical acceleration ``a_z`` (:func:`head_acceleration` in the coronal plane:
    F 3.16, ``a_h = −(a_z + g cos θ_H) tan r − g sin θ_H``; ``small_angle``: F 3.17,
    ``a_h ≈ −g sin(r + θ_H) − a_z r``). ``θ_H = 0``: the upright assumption (F 3.14)."""
    return head_acceleration(reading_rad, 0.0, a_z_H_m_s2, theta_H_rad, 0.0, g_m_s2,
                             small_angle)[..., 1]


def planar_head_tilt(reading_rad, a_h_H_m_s2, a_z_H_m_s2, g_m_s2=G_M_S2):
    """The head angle ``θ_H`` from a reading and a known head-frame acceleration ``(a_h, a_z)``
    (:func:`head_tilt` in the coronal plane)."""
    return head_tilt(reading_rad, 0.0, _coronal(a_h_H_m_s2, a_z_H_m_s2), g_m_s2)[..., 0]


def sagittal_to_planar(phi_y_rad, theta_y_rad, a_x_H_m_s2):
    """Sagittal-plane quantities of the 3-D conventions → the planar model's ``(r, θ_H, a_h)``:
    ``(−φ_y, −Θ_y, −a_x)`` (rotations about y, ``h = −x``; module doc). Its own inverse."""
    return -jnp.asarray(phi_y_rad), -jnp.asarray(theta_y_rad), -jnp.asarray(a_x_H_m_s2)


def small_angle_error_m_s2(tilt_rad, a_h_H_m_s2, a_z_H_m_s2=0.0, g_m_s2=G_M_S2):
    """The error of F 3.17 against the exact relation, for a planar head at ``tilt_rad`` with a
    head-frame acceleration ``(a_h, a_z)``: the steady reading is formed exactly and the
    acceleration recovered with the small-angle form, minus the true ``a_h`` (broadcast grid)."""
    r = planar_reading(a_h_H_m_s2, a_z_H_m_s2, tilt_rad, g_m_s2)
    return planar_head_acceleration(r, a_z_H_m_s2, tilt_rad, g_m_s2, small_angle=True) - a_h_H_m_s2


def upright_assumption_error_m_s2(tilt_rad, a_h_H_m_s2, a_z_H_m_s2=0.0, g_m_s2=G_M_S2):
    """The error of the acceleration the otolith indicates under the upright assumption (F 3.14,
    θ_H taken as 0) for a head actually at ``tilt_rad`` (broadcast grid): the ambiguity's bite."""
    r = planar_reading(a_h_H_m_s2, a_z_H_m_s2, tilt_rad, g_m_s2)
    return planar_head_acceleration(r, a_z_H_m_s2, 0.0, g_m_s2) - a_h_H_m_s2
