"""Head motions of the classic vestibular-perception paradigms, as MOTION.csv rows.

Each generator returns a :class:`verticality.io.motion.MotionRecord` sampled every ``dt_s``: the
head orientation ``q_I_H`` (frame I: z up), the head angular velocity ``ω_H`` (head frame; over
each interval the constant rate that takes one sample's orientation to the next, so that a model
holding ``ω_H[k]`` over ``[t_k, t_{k+1}]`` follows the orientation exactly) and the acceleration of
the head centre ``a_I`` (gravity excluded). Head axes: x forward (naso-occipital), y left
(interaural), z up. Every paradigm starts with ``still_s`` seconds upright and at rest.

* :func:`yaw_step` — Earth-vertical yaw: a velocity step to ``omega_deg_s``, held for ``on_s``,
  then a step back to rest (per- and post-rotatory responses).
* :func:`somatogravic` — a sustained forward acceleration (0.2 g) in the dark, head upright.
* :func:`ovar` — off-vertical-axis rotation: the head pitched ``tilt_deg`` and rotating about its
  own z axis at ``omega_deg_s`` (a velocity step at the start of rotation).
* :func:`post_rotatory_tilt` — yaw at ``omega_deg_s``, a stop, then (``tilt=True``) a quick
  ``pitch_deg`` pitch within ``pitch_s`` seconds after the stop; ``tilt=False`` stays upright.
* :func:`centrifuge` — fixed-radius centrifuge spin-up, the interaural axis along the radius.
* :func:`roll_swing` — the variable-radius roll swing of Rader et al. 2009: the head on a swing
  arm below an Earth-horizontal axis (along the head's x), its interaural force nulled by swinging
  at the pendulum frequency of the radius, and its vertical force nulled or doubled by a radial
  oscillation at twice the swing frequency.
* :func:`stabilized` — any head motion with the head servoed upright (heading and acceleration
  kept), to ask a perception model the thesis's question.
"""

from __future__ import annotations

import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.io.motion import MotionRecord

DT_S = 0.01


def _record(t, R_I_H, a_I) -> MotionRecord:
    """Rows from orientations ``R_I_H`` (N, 3, 3) and accelerations ``a_I`` (N, 3)."""
    R = np.asarray(R_I_H, float)
    rel = np.einsum("nji,njk->nik", R[:-1], R[1:])  # R_k^T R_{k+1}
    dt = np.diff(t)
    w = np.asarray(so3.log_principal(rel)) / dt[:, None]
    w = np.concatenate([w, w[-1:]], axis=0)
    q = np.asarray(so3.quat_from_matrix(R))
    return MotionRecord(np.asarray(t, float), q, w, np.asarray(a_I, float))


def _times(total_s, dt_s):
    return np.arange(int(round(total_s / dt_s)) + 1) * dt_s


def _rot(axis_fn, angle) -> np.ndarray:
    """``so3``'s rotation about one axis, batched over ``angle``, as NumPy (products of these stay
    NumPy matrix products)."""
    return np.asarray(axis_fn(np.asarray(angle, float)))


def _yaw_angle(t, start_s, stop_s, omega_rad_s):
    """The angle of a velocity step: ω from start to stop, zero before and after."""
    return omega_rad_s * (np.clip(t, start_s, stop_s) - start_s)


def yaw_step(omega_deg_s: float = 60.0, on_s: float = 60.0, after_s: float = 60.0,
             still_s: float = 1.0, dt_s: float = DT_S) -> MotionRecord:
    t = _times(still_s + on_s + after_s, dt_s)
    psi = _yaw_angle(t, still_s, still_s + on_s, np.radians(omega_deg_s))
    return _record(t, _rot(so3.rot_z, psi), np.zeros((t.size, 3)))


def somatogravic(accel_g: float = 0.2, on_s: float = 30.0, still_s: float = 1.0,
                 dt_s: float = DT_S) -> MotionRecord:
    t = _times(still_s + on_s, dt_s)
    a = np.zeros((t.size, 3))
    a[t >= still_s, 0] = accel_g * G_M_S2
    return _record(t, np.broadcast_to(np.eye(3), (t.size, 3, 3)), a)


def ovar(tilt_deg: float = 20.0, omega_deg_s: float = 60.0, on_s: float = 120.0,
         still_s: float = 1.0, dt_s: float = DT_S) -> MotionRecord:
    """The head pitched nose-down by ``tilt_deg`` from the start (held still for ``still_s``),
    then spinning about its own z axis."""
    t = _times(still_s + on_s, dt_s)
    psi = _yaw_angle(t, still_s, still_s + on_s, np.radians(omega_deg_s))
    R = _rot(so3.rot_y, np.full(t.size, np.radians(tilt_deg))) @ _rot(so3.rot_z, psi)
    return _record(t, R, np.zeros((t.size, 3)))


def post_rotatory_tilt(tilt: bool = True, omega_deg_s: float = 60.0, on_s: float = 60.0,
                       after_s: float = 60.0, pitch_deg: float = 90.0, pitch_s: float = 1.0,
                       still_s: float = 1.0, dt_s: float = DT_S) -> MotionRecord:
    """Yaw about Earth-vertical, stop at ``still_s + on_s``; then pitch (about the head's y axis,
    nose down for positive angles) at a constant rate over ``pitch_s`` seconds."""
    t = _times(still_s + on_s + after_s, dt_s)
    stop = still_s + on_s
    psi = _yaw_angle(t, still_s, stop, np.radians(omega_deg_s))
    theta = np.radians(pitch_deg) * np.clip((t - stop) / pitch_s, 0.0, 1.0) if tilt else 0.0 * t
    return _record(t, _rot(so3.rot_z, psi) @ _rot(so3.rot_y, theta), np.zeros((t.size, 3)))


def centrifuge(radius_m: float = 1.0, omega_deg_s: float = 180.0, ramp_s: float = 10.0,
               on_s: float = 60.0, still_s: float = 1.0, dt_s: float = DT_S) -> MotionRecord:
    """Fixed-radius centrifuge spin-up: the head ``radius_m`` from an Earth-vertical axis, upright,
    facing the direction of travel with its left ear (y) toward the axis; the rotation rate ramps
    linearly to ``omega_deg_s`` over ``ramp_s`` and is held. The centripetal acceleration ω²r
    points along the head's +y, so the GIF is rolled by atan(ω²r/g)."""
    t = _times(still_s + on_s, dt_s)
    w = np.radians(omega_deg_s)
    s = t - still_s
    rate = np.where(s <= 0, 0.0, np.where(s < ramp_s, w * s / ramp_s, w))
    accel = np.where((s > 0) & (s < ramp_s), w / ramp_s, 0.0)
    psi = np.where(s <= 0, 0.0, np.where(s < ramp_s, 0.5 * w * s**2 / ramp_s,
                                         0.5 * w * ramp_s + w * (s - ramp_s)))
    c, si = np.cos(psi), np.sin(psi)
    a = radius_m * (accel[:, None] * np.stack([-si, c, 0 * c], -1)
                    - (rate**2)[:, None] * np.stack([c, si, 0 * c], -1))
    return _record(t, _rot(so3.rot_z, psi + np.pi / 2), a)


SWING_CONDITIONS = ("center", "y-null", "z-null", "z-double")
"""Rader et al. 2009's conditions (Table 4: C, YN, ZN, ZD)."""


def swing_radial_amplitude_m(radius_m: float, tilt_deg: float, freq_hz: float) -> float:
    """Amplitude (m) of the radial oscillation at twice the swing frequency that cancels the
    second-harmonic variation of the head-vertical force on a fixed-radius swing,
    ``r θ̇² + g cos θ ≈ const + (r θ₀² ω²/2 + g θ₀²/4) cos 2ωt`` (small angles): its radial
    acceleration amplitude ``Z = r θ₀² ω²/2 + g θ₀²/4`` over ``(2ω)²``."""
    th0, w = np.radians(tilt_deg), 2 * np.pi * freq_hz
    return float((radius_m * th0**2 * w**2 / 2 + G_M_S2 * th0**2 / 4) / (2 * w) ** 2)


def roll_swing(condition: str = "y-null", radius_m: float = 1.22, tilt_deg: float = 10.0,
               freq_hz: float = 0.45, on_s: float = 40.0, ramp_cycles: float = 2.0,
               still_s: float = 1.0, dt_s: float = DT_S) -> MotionRecord:
    """Roll swing after Rader et al. 2009: the head hangs ``r(t)`` below an Earth-horizontal axis
    along its x (naso-occipital) axis, its z axis toward the axis; the swing angle (head roll) is
    ``θ(t) = θ₀ e(s) sin ωs`` (``s`` the time since the start, ``θ₀ = tilt_deg``,
    ``ω = 2π·freq_hz``), its amplitude raised by ``e(s) = (1 − cos(πs/T))/2`` over
    ``T = ramp_cycles`` periods so that the swing starts upright and at rest.

    The head position is ``p = −r(t) z_H`` (z_H the head's z axis), so its acceleration in head
    axes is ``(2ṙθ̇ + rθ̈)`` along y and ``(rθ̇² − r̈)`` along z, and the gravito-inertial force
    per unit mass ``f_y = 2ṙθ̇ + rθ̈ + g sin θ``, ``f_z = rθ̇² − r̈ + g cos θ``.

    * ``center`` — the ears on the axis (r = 0): a pure roll tilt, ``f_y = g sin θ``;
    * ``y-null`` — ``r = radius_m`` swung at ``freq_hz``; with Rader's pairing (1.22 m, 0.45 Hz;
      0.38 m, 0.8 Hz) ω² ≈ g/r, so ``rθ̈`` cancels ``g sin θ`` to first order (a free pendulum);
    * ``z-null`` / ``z-double`` — ``y-null`` plus ``r(t) = r₀ ± A (1 − cos 2ωs)``,
      ``A`` = :func:`swing_radial_amplitude_m`: a radial acceleration ``±A (2ω)² cos 2ωs`` that
      cancels or doubles the second-harmonic variation of ``f_z``.

    Readings: the paper gives the radial accelerations it applied (0.25 m/s² at 0.9 Hz for
    1.22 m); here the amplitude follows from the geometry (0.22 m/s² for 10° at 0.45 Hz), the
    value that nulls the vertical-force variation of this swing to second order in θ₀. How the
    swing was started is not described in the paper (the raised-cosine start is ours); the
    measurements are taken over the last cycles."""
    if condition not in SWING_CONDITIONS:
        raise ValueError(f"unknown swing condition {condition!r}; known: {SWING_CONDITIONS}")
    t = _times(still_s + on_s, dt_s)
    s = np.clip(t - still_s, 0.0, None)
    w, th0 = 2 * np.pi * freq_hz, np.radians(tilt_deg)
    T = ramp_cycles / freq_hz
    ramp = s < T
    e = np.where(ramp, 0.5 * (1 - np.cos(np.pi * s / T)), 1.0)
    ed = np.where(ramp, 0.5 * np.pi / T * np.sin(np.pi * s / T), 0.0)
    edd = np.where(ramp, 0.5 * (np.pi / T) ** 2 * np.cos(np.pi * s / T), 0.0) * (t > still_s)
    sn, cs = np.sin(w * s), np.cos(w * s)
    th = th0 * e * sn
    thd = th0 * (ed * sn + e * w * cs)
    thdd = th0 * (edd * sn + 2 * ed * w * cs - e * w**2 * sn)
    r0 = 0.0 if condition == "center" else radius_m
    amp = {"z-null": 1.0, "z-double": -1.0}.get(condition, 0.0) * swing_radial_amplitude_m(
        radius_m, tilt_deg, freq_hz)
    r = r0 + amp * (1.0 - np.cos(2 * w * s))
    rd = amp * 2 * w * np.sin(2 * w * s)
    rdd = amp * (2 * w) ** 2 * np.cos(2 * w * s) * (t > still_s)
    R = _rot(so3.rot_x, th)
    y_H, z_H = R[:, :, 1], R[:, :, 2]
    a_I = (2 * rd * thd + r * thdd)[:, None] * y_H + (r * thd**2 - rdd)[:, None] * z_H
    return _record(t, R, a_I)


def stabilized(record: MotionRecord) -> MotionRecord:
    """The head of ``record`` (rigid on the trunk) servoed upright: the same centre acceleration
    and heading, no tilt (reading: an ideal stabilizer, keeping the head's yaw, the heading of its
    x axis, and putting its z axis on the vertical)."""
    R = np.asarray(so3.matrix_from_quat(record.q_I_H_wxyz))
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return _record(record.t_s, _rot(so3.rot_z, np.unwrap(yaw)), record.a_I_m_s2)
