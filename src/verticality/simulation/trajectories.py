"""Prescribed trunk (or head) motions: Lissajous (P11), impact (P13 A), jump (P13 B), walking
(F Fig. 4.13), step, sine and PRTS (Tahboub §III.A).

Every trajectory is a pair of smooth ``jax.numpy`` functions of time, the position of the body's
centre ``position_I_m(t)`` (3,) and its orientation ``R_I_B(t)`` (3, 3), built from Euler angles
(``R = Rz(yaw) Ry(pitch) Rx(roll)``) with explicit sines and cosines. Everything a model needs is
*derived by forward-mode autodiff* from those two functions, so the kinematics are exact and
mutually consistent (integrating ω reproduces R, integrating a twice reproduces the position):

    ω_B  = vee(R_IBᵀ dR_IB/dt)          body-frame angular velocity (rad/s)
    ω̇_B  = d/dt ω_B                      (rad/s²)
    a_I  = d²p_I/dt²                     acceleration of the centre, frame I, gravity excluded

Spikes are smooth (Gaussian pulses of a given peak and width, resolved by the 1 ms plant step)
and "then stop" is a smooth deceleration to rest, so no model ever sees a discontinuity (except
the published stimuli that define one: the `step`, whose critically damped onset has an
acceleration jump, and the `prts`, whose velocity steps between its levels).

A :class:`Trajectory` is a NamedTuple of functions: close over it in jitted code (do not pass it
as a traced argument). ``sample(traj, t)`` evaluates it on an array of times (vmapped).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from scipy.special import ndtr

from verticality.core import so3
from verticality.core.compiling import jit_evaluated_once
from verticality.core.constants import G_M_S2
from verticality.core.errors import InputError
from verticality.models.kinematics import RigidMotion
from verticality.models.lissajous import LISSAJOUS_AMPLITUDE, lissajous_trunk


class Trajectory(NamedTuple):
    """A prescribed rigid motion. ``motion(t)`` is the body's :class:`RigidMotion` at time ``t``.

    ``rpy_rad(t)`` gives (roll, pitch, yaw) with ``R_I_B = Rz(yaw) Ry(pitch) Rx(roll)``.
    """

    position_I_m: Callable  # t -> (3,)
    rpy_rad: Callable  # t -> (3,) roll, pitch, yaw
    duration_s: float
    name: str = ""
    events: dict | None = None  # named event times (s), e.g. the jump's take-off and landing

    def orientation_R_I_B(self, t):
        rpy = self.rpy_rad(t)
        return so3.matrix_from_rpy(rpy[0], rpy[1], rpy[2])

    def motion(self, t) -> RigidMotion:
        return motion_from(self.position_I_m, self.rpy_rad, t)


# --------------------------------------------------------------------------------------------
# Kinematics by autodiff
# --------------------------------------------------------------------------------------------


def _d_dt(f, t):
    """(f(t), f'(t)) by one forward-mode pass (t scalar)."""
    return jax.jvp(f, (t,), (jnp.ones_like(t),))


def omega_from_rpy_rates(rpy, rpy_dot):
    """Body-frame angular velocity of R = Rz(ψ) Ry(θ) Rx(φ): ω_B = vee(Rᵀ Ṙ) =
    (φ̇ − ψ̇ sθ, θ̇ cφ + ψ̇ sφ cθ, −θ̇ sφ + ψ̇ cφ cθ)."""
    phi, theta = rpy[0], rpy[1]
    dphi, dtheta, dpsi = rpy_dot[0], rpy_dot[1], rpy_dot[2]
    sf, cf, st, ct = jnp.sin(phi), jnp.cos(phi), jnp.sin(theta), jnp.cos(theta)
    return jnp.stack([dphi - dpsi * st, dtheta * cf + dpsi * sf * ct,
                      -dtheta * sf + dpsi * cf * ct])


def motion_from(position_fn, rpy_fn, t) -> RigidMotion:
    """Exact :class:`RigidMotion` at ``t`` of the body with position ``position_fn`` and Euler
    angles ``rpy_fn`` (smooth functions of a scalar time), by forward-mode autodiff:
    ω = E(rpy)·d(rpy)/dt (= vee(RᵀṘ), tested), ω̇ its derivative, a = d²p/dt²."""
    t = jnp.asarray(t, dtype=jnp.float64)

    def rates(s):
        return _d_dt(rpy_fn, s)

    (rpy, rpy_dot), (_, rpy_ddot) = jax.jvp(rates, (t,), (jnp.ones_like(t),))
    omega, omegadot = jax.jvp(omega_from_rpy_rates, (rpy, rpy_dot), (rpy_dot, rpy_ddot))

    def velocity_I(s):
        return _d_dt(position_fn, s)[1]

    a_I = _d_dt(velocity_I, t)[1]
    R = so3.matrix_from_rpy(rpy[0], rpy[1], rpy[2])
    return RigidMotion(R_I_B=R, omega_B_rad_s=omega, omegadot_B_rad_s2=omegadot, a_I_m_s2=a_I)


def sample(traj: Trajectory, t_s) -> RigidMotion:
    """The trajectory's :class:`RigidMotion` at every time of ``t_s`` (leading axis = time)."""
    return jit_evaluated_once(jax.vmap(traj.motion))(jnp.asarray(t_s, dtype=jnp.float64))


def positions(traj: Trajectory, t_s):
    """Positions (N, 3) at the times ``t_s``."""
    return jit_evaluated_once(jax.vmap(traj.position_I_m))(jnp.asarray(t_s, dtype=jnp.float64))


def from_euler(position_fn, rpy_fn, duration_s: float, name: str = "") -> Trajectory:
    """A trajectory from a position function and a (roll, pitch, yaw) function of t (rad)."""
    return Trajectory(position_fn, rpy_fn, float(duration_s), name)


# --------------------------------------------------------------------------------------------
# Smooth building blocks
# --------------------------------------------------------------------------------------------

_SQRT_2PI = math.sqrt(2.0 * math.pi)


def smoothstep(u):
    """0 for u ≤ 0, 1 for u ≥ 1, C³ in between (the septic smoothstep 35u⁴−84u⁵+70u⁶−20u⁷)."""
    u = jnp.clip(u, 0.0, 1.0)
    return u**4 * (35.0 - 84.0 * u + 70.0 * u**2 - 20.0 * u**3)


def _phi(u):
    return jnp.exp(-0.5 * u * u) / _SQRT_2PI


def _Phi(u):
    return jax.scipy.special.ndtr(u)


def _ramp(u):
    """∫Φ: uΦ(u) + φ(u), → max(u, 0) away from 0."""
    return u * _Phi(u) + _phi(u)


def _parabola(u):
    """∫∫Φ: ((u²+1)Φ(u) + uφ(u))/2, → max(u, 0)²/2 + 1/2·[u>0] away from 0."""
    return 0.5 * ((u * u + 1.0) * _Phi(u) + u * _phi(u))


def gaussian_pulse_position(t, t_c, sigma, delta_v):
    """Displacement whose acceleration is a Gaussian pulse of area ``delta_v`` (m/s) at ``t_c``.

    Peak acceleration ``delta_v / (σ√(2π))``; the velocity goes from 0 to ``delta_v``.
    """
    return delta_v * sigma * _ramp((t - t_c) / sigma)


def acceleration_step_position(t, t_c, sigma, accel):
    """Displacement whose acceleration is a smoothed step (Gaussian CDF) from 0 to ``accel``."""
    return accel * sigma**2 * _parabola((t - t_c) / sigma)


def jolt_position(t, t_c, sigma, peak_m_s2):
    """Displacement D·Φ((t−t_c)/σ): a biphasic acceleration spike of peak ``peak_m_s2`` at t_c − σ
    (and −peak at t_c + σ); the body starts and ends at rest, moved by D = peak σ²/φ(1)."""
    D = peak_m_s2 * sigma**2 / float(np.exp(-0.5) / _SQRT_2PI)
    return D * _Phi((t - t_c) / sigma)


# --------------------------------------------------------------------------------------------
# P11: Lissajous
# --------------------------------------------------------------------------------------------


def lissajous(amplitude: float = LISSAJOUS_AMPLITUDE, duration_s: float = 10.0) -> Trajectory:
    """P11 §VI (and F §4.3): :func:`lissajous_trunk` as a 3-D trajectory.

    P11's plane is the coronal plane (models/planar.py: the head's y–z plane, rotations about x):
    P11's horizontal ``x`` is our y, P11's vertical ``y`` is our z, Θ is a rotation about x (roll).
    """

    def position(t):
        x, z, _ = lissajous_trunk(t, amplitude)
        return jnp.stack([0.0 * t, x, z])

    def rpy(t):
        return jnp.stack([lissajous_trunk(t, amplitude)[2], 0.0 * t, 0.0 * t])

    return from_euler(position, rpy, duration_s, "lissajous")


# --------------------------------------------------------------------------------------------
# P13 A: 3-D oscillation, impact spike, stop
# --------------------------------------------------------------------------------------------


def impact(
    duration_s: float = 10.0,
    t_impact_s: float = 5.0,
    spike_m_s2: float = 30.0,
    spike_sigma_s: float = 0.02,
    spike_direction_I=(1.0, 0.0, 0.0),
    stop_s: float = 1.0,
    ramp_in_s: float = 0.5,
    translation_amplitude_m=(0.3, 0.2, 0.1),
    translation_frequency_hz=(0.5, 0.3, 1.0),
    rotation_amplitude_rad=(0.2, 0.3, 0.2),
    rotation_frequency_hz=(0.7, 0.5, 0.3),
) -> Trajectory:
    """P13 §5 scenario A (docs/reproduction.md, `ekf-impact`): the trunk oscillates in 3-D
    (rotation and translation, amplitudes of tenths of a radian and of a metre, 0.3–1 Hz), a sudden
    impact at ``t_impact_s`` gives a 30 m/s² acceleration spike, then the trunk stops.

    Readings where P13 is silent (documented choices):
    - oscillation: x, y, z = (0.3, 0.2, 0.1) m at (0.5, 0.3, 1.0) Hz; roll, pitch, yaw = (0.2, 0.3,
      0.2) rad at (0.7, 0.5, 0.3) Hz (phases 0, 0.5, 1.0 rad per axis), faded in over
      ``ramp_in_s`` so the trunk starts at rest, upright;
    - impact: a jolt D·Φ((t−t_i)/σ) along ``spike_direction_I`` (horizontal x by default, where it
      disturbs the gravito-inertial vertical most), σ = 20 ms: its acceleration is a smooth
      biphasic spike whose peak is exactly ``spike_m_s2`` (at t_i − σ) and whose net velocity change
      is zero; the oscillation's own acceleration (≤ ~4 m/s²) adds to it;
    - stop: from t_i the oscillation is multiplied by a C³ smoothstep falling from 1 to 0 over
      ``stop_s``; afterwards the trunk is at rest, upright.
    """
    A_p = jnp.asarray(translation_amplitude_m, float)
    f_p = jnp.asarray(translation_frequency_hz, float)
    A_r = jnp.asarray(rotation_amplitude_rad, float)
    f_r = jnp.asarray(rotation_frequency_hz, float)
    phase = jnp.array([0.0, 0.5, 1.0])
    d = np.asarray(spike_direction_I, float)
    d = jnp.asarray(d / np.linalg.norm(d))

    def envelope(t):
        return smoothstep(t / ramp_in_s) * (1.0 - smoothstep((t - t_impact_s) / stop_s))

    def position(t):
        osc = A_p * jnp.sin(2.0 * jnp.pi * f_p * t + phase)
        # the jolt is centred σ after t_i so its first (positive) peak falls at t_i
        return envelope(t) * osc + d * jolt_position(t, t_impact_s + spike_sigma_s, spike_sigma_s,
                                                     spike_m_s2)

    def rpy(t):
        return envelope(t) * A_r * jnp.sin(2.0 * jnp.pi * f_r * t + phase)

    return from_euler(position, rpy, duration_s, "impact")


# --------------------------------------------------------------------------------------------
# P13 B: forward jump
# --------------------------------------------------------------------------------------------


def jump(
    duration_s: float = 6.0,
    t_push_s: float = 1.0,
    push_sigma_s: float = 0.06,
    flight_s: float = 0.45,
    landing_peak_m_s2: float = 30.0,
    jump_length_m: float = 0.8,
    edge_sigma_s: float = 0.01,
    pitch_rad: float = 0.2,
    roll_rad: float = 0.05,
) -> Trajectory:
    """P13 §5 scenario B (docs/reproduction.md, `ekf-jump`): a forward jump along x — take-off push
    upward, flight (free fall), landing impact, then stop.

    The head centre's acceleration (gravity excluded) is built from closed-form pieces whose double
    integrals are exact: a Gaussian push pulse centred at ``t_push_s`` (up and forward), a smoothed
    step to −g during the flight (free fall: a = (0, 0, −g), the centre's acceleration is
    gravity's), and a Gaussian landing pulse (up and backward) that brings the body to rest. The
    vertical velocity changes balance (push + landing = g·flight) and their timing returns the body
    to its starting height; the landing pulse's width is chosen so that the *net* vertical
    acceleration peaks at ``landing_peak_m_s2`` (the flight's −g is still fading when it starts).
    The trunk pitches forward by ``pitch_rad`` and rolls by ``roll_rad`` (Gaussian bumps over the
    jump) so the motion is 3-D, as in P13 Fig. 2d–e. Values P13 leaves open (flight 0.45 s, 0.8 m
    long, push σ = 60 ms; the centre rises 0.25 m during the flight and ≈ 0.4 m in all) are this
    module's choice.
    """
    g = G_M_S2
    t_p = float(t_push_s)
    t_to = t_p + 2.0 * push_sigma_s  # free fall starts as the push ends
    t_ld = t_to + flight_s
    t_mid = 0.5 * (t_to + t_ld)
    T_f = float(flight_s)

    def solve_landing(sigma_l):
        # landing pulse centred σ_l after the flight ends; impulses balance height and velocity
        t_l = t_ld + 1.0 * sigma_l
        v_up = g * T_f * (t_l - t_mid) / (t_l - t_p)
        v_land = g * T_f - v_up
        return t_l, v_up, v_land

    def net_peak(sigma_l):
        t_l, _, v_land = solve_landing(sigma_l)
        ts = np.linspace(t_ld - 0.2, t_ld + 0.3, 20001)
        a = (v_land * np.exp(-0.5 * ((ts - t_l) / sigma_l) ** 2) / (sigma_l * _SQRT_2PI)
             - g * (ndtr((ts - t_to) / edge_sigma_s) - ndtr((ts - t_ld) / edge_sigma_s)))
        return a.max()

    lo, hi = 1e-3, 0.5  # bisection on σ_l for the requested net peak (peak decreases with σ_l)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if net_peak(mid) > landing_peak_m_s2 else (lo, mid)
    sigma_l = 0.5 * (lo + hi)
    t_l, v_up, v_land = solve_landing(sigma_l)
    v_x = jump_length_m / (t_l - t_p)
    t_end_motion = t_l + 4.0 * sigma_l
    sigma_rot = 0.25 * (t_end_motion - t_p)

    def position(t):
        z = (gaussian_pulse_position(t, t_p, push_sigma_s, v_up)
             + gaussian_pulse_position(t, t_l, sigma_l, v_land)
             - acceleration_step_position(t, t_to, edge_sigma_s, g)
             + acceleration_step_position(t, t_ld, edge_sigma_s, g))
        x = (gaussian_pulse_position(t, t_p, push_sigma_s, v_x)
             - gaussian_pulse_position(t, t_l, sigma_l, v_x))
        return jnp.stack([x, 0.0 * t, z])

    def rpy(t):
        bump = jnp.exp(-0.5 * ((t - 0.5 * (t_p + t_l)) / sigma_rot) ** 2)
        return jnp.stack([roll_rad * bump, pitch_rad * bump, 0.0 * t])

    events = {"push_s": t_p, "takeoff_s": t_to, "apex_s": t_mid, "touchdown_s": t_ld,
              "landing_peak_s": t_l, "at_rest_s": t_end_motion, "push_dv_up_m_s": v_up,
              "landing_dv_up_m_s": v_land, "forward_speed_m_s": v_x}
    return from_euler(position, rpy, duration_s, "jump")._replace(events=events)


# --------------------------------------------------------------------------------------------
# F Fig. 4.13: walking-like head motion
# --------------------------------------------------------------------------------------------


def walking(
    duration_s: float = 20.0,
    speed_m_s: float = 1.2,
    step_hz: float = 2.0,
    vertical_amplitude_m: float = 0.02,
    fore_aft_amplitude_m: float = 0.01,
    pitch_amplitude_rad: float = 0.03,
    ramp_in_s: float = 1.0,
    harmonics: float = 1.0,
) -> Trajectory:
    """A walking-like head motion in the sagittal (x–z) plane, after F Fig. 4.13 (head linear
    acceleration during locomotion), whose source is Menz, Lord & Fitzpatrick 2003 (F ref. 135:
    head and pelvis accelerations of 30 young adults walking on a level and an irregular surface,
    accelerometers at the occiput; the head's accelerations are dominated by the step frequency,
    vertical larger than fore–aft, and smoother than the pelvis').

    F gives only the figure, not the numbers, and the study's tables are not reproduced here; this
    is a synthetic gait with those features: forward progression at ``speed_m_s`` reached over
    ``ramp_in_s``, a cadence of 2 steps/s (120 steps/min, a usual young-adult cadence), a vertical
    bounce at the step frequency (2 cm at 2 Hz ⇒ ≈ 3.2 m/s² peak, ≈ 0.3 g) with a 2nd harmonic, a
    fore–aft oscillation at the step frequency (1 cm ⇒ ≈ 1.6 m/s²) with a 2nd harmonic, and a
    small pitch oscillation at the stride frequency (1 Hz). Amplitudes are documented choices, not
    digitized data. The one walking stimulus of the project (`ambiguity-*`, the CLI's `walking`).
    ``harmonics`` scales the two 2nd harmonics (0: the step frequency alone, the bounce a quarter
    step behind the sway).
    """
    w = 2.0 * jnp.pi * step_hz

    def position(t):
        e = smoothstep(t / ramp_in_s)
        # forward progression: speed · ∫0^t smoothstep(s/T) ds (closed form of the septic step)
        u = jnp.clip(t / ramp_in_s, 0.0, 1.0)
        integral = ramp_in_s * (7.0 * u**5 - 14.0 * u**6 + 10.0 * u**7 - 2.5 * u**8)
        x_prog = speed_m_s * (integral + jnp.maximum(t - ramp_in_s, 0.0))
        x_osc = fore_aft_amplitude_m * (jnp.sin(w * t)
                                        + harmonics * 0.3 * jnp.sin(2.0 * w * t + 0.7))
        z_osc = vertical_amplitude_m * (jnp.sin(w * t - 0.5 * jnp.pi)
                                        + harmonics * 0.15 * jnp.sin(2.0 * w * t))
        return jnp.stack([x_prog + e * x_osc, 0.0 * t, e * z_osc])

    def rpy(t):
        e = smoothstep(t / ramp_in_s)
        return jnp.stack([0.0 * t, e * pitch_amplitude_rad * jnp.sin(0.5 * w * t), 0.0 * t])

    return from_euler(position, rpy, duration_s, "walking")


# --------------------------------------------------------------------------------------------
# Tahboub §III.A: step, sine, PRTS (body lean about the ankle, sagittal plane)
# --------------------------------------------------------------------------------------------


def _lean(angle_fn, lever_m: float, duration_s: float, name: str) -> Trajectory:
    """A body leaning forward by ``angle_fn(t)`` (pitch about y) about a pivot at the origin; the
    tracked point sits ``lever_m`` above the pivot along the body axis (T: sensors 0.325 m above
    the ankle), so its translation follows the lean exactly."""

    def rpy(t):
        a = angle_fn(t)
        return jnp.stack([0.0 * a, a, 0.0 * a])

    def position(t):
        a = angle_fn(t)
        return lever_m * jnp.stack([jnp.sin(a), 0.0 * a, jnp.cos(a)])

    return Trajectory(position, rpy, float(duration_s), name)


def step(amplitude_rad: float = math.radians(5.0), t_step_s: float = 1.0, settle_s: float = 0.3,
         lever_m: float = 0.0, duration_s: float = 10.0) -> Trajectory:
    """T §III.A (docs/reproduction.md, `tahboub-step`): a lean of ``amplitude_rad`` commanded as a
    step through a critically damped 2nd-order response, θ = A(1 − (1 + ω τ) e^{−ω τ}),
    τ = t − t_step.

    Reading: "0.3 s" is the 95 % settling time, so ω = 4.744/0.3 s⁻¹. The angular acceleration
    jumps to Aω² at onset (the published stimulus's own discontinuity; θ and θ̇ are continuous).
    """
    omega_n = 4.743864518 / settle_s  # 1 − (1 + x)e^{−x} = 0.95

    def angle(t):
        tau = jnp.maximum(t - t_step_s, 0.0)
        return amplitude_rad * (1.0 - (1.0 + omega_n * tau) * jnp.exp(-omega_n * tau))

    return _lean(angle, lever_m, duration_s, "step")


def sine(amplitude_rad: float = math.radians(5.0), frequency_hz: float = 0.2, lever_m: float = 0.0,
         duration_s: float = 60.0, phase_rad: float = 0.0) -> Trajectory:
    """T §III.A (`tahboub-sine`): θ = A sin(2π f t + phase), 5°, 0.2 Hz, 60 s by default."""

    def angle(t):
        return amplitude_rad * jnp.sin(2.0 * jnp.pi * frequency_hz * t + phase_rad)

    return _lean(angle, lever_m, duration_s, "sine")


PRTS_LENGTH = 242
PRTS_DT_S = 0.25
PRTS_TAPS = (0, 0, 0, 1, 2)  # coefficients of s[k-1] ... s[k-5]


def prts_sequence(taps=PRTS_TAPS) -> np.ndarray:
    """One period (242 values in {0, 1, 2}) of the pseudorandom ternary sequence of Peterka 2002
    (T §III.A): the maximal-length sequence of the 5-stage shift register over GF(3)
    ``s[k] = s[k−4] + 2 s[k−5] (mod 3)`` (a primitive polynomial, so the period is 3⁵ − 1)."""
    s = [0, 0, 0, 0, 1]
    for _ in range(PRTS_LENGTH):
        s.append(sum(c * s[-1 - i] for i, c in enumerate(taps)) % 3)
    return np.array(s[5:5 + PRTS_LENGTH])


def prts_velocity_levels(taps=PRTS_TAPS) -> np.ndarray:
    """The sequence as unit velocity levels: 0 → 0, 1 → +1, 2 → −1. Zero mean over a cycle; the
    second half is the negative of the first, so the power sits on the odd harmonics only and the
    integral (the position) returns to its start after every cycle."""
    return np.array([0.0, 1.0, -1.0])[prts_sequence(taps)]


def prts_knots(peak_rad: float, cycles: int, dt_s: float = PRTS_DT_S):
    """``(t_s, angle_rad)`` at the 242·cycles + 1 level changes of the PRTS lean: the exact integral
    of the velocity held at +v, 0 or −v for ``dt_s`` each, centred on the middle of its range
    and scaled so that it spans ±``peak_rad``. Between the knots the lean is linear."""
    if cycles < 1:
        raise InputError("the PRTS needs at least 1 cycle")
    if not dt_s > 0:
        raise InputError(f"the PRTS level duration must be positive, got {dt_s}")
    levels = np.tile(prts_velocity_levels(), cycles)
    pos = np.concatenate([[0.0], np.cumsum(levels) * dt_s])
    one = pos[: PRTS_LENGTH + 1]
    offset = 0.5 * (one.max() + one.min())
    scale = peak_rad / (0.5 * (one.max() - one.min()))
    return np.arange(levels.size + 1) * dt_s, scale * (pos - offset)


def prts_lean_fn(peak_rad: float = math.radians(5.0), cycles: int = 2, dt_s: float = PRTS_DT_S):
    """The PRTS lean as a function of time (rad; ``jax.numpy``, piecewise linear between the
    :func:`prts_knots`, held at the last knot's value after the end)."""
    knots_t, knots_a = (jnp.asarray(a) for a in prts_knots(peak_rad, cycles, dt_s))

    def angle(t):
        return jnp.interp(t, knots_t, knots_a)

    return angle


def prts_stimulus(peak_rad: float, fs_hz: float, n_cycles: int, dt_s: float = PRTS_DT_S):
    """The PRTS lean sampled at ``fs_hz``: ``(t_s, position_rad, velocity_rad_s)`` over
    ``n_cycles`` cycles, the position from :func:`prts_lean_fn` (the lean of the `prts`
    trajectory), the velocity the level held over the sample's interval."""
    if not fs_hz > 0:
        raise InputError(f"fs_hz must be positive, got {fs_hz}")
    n = int(round(n_cycles * PRTS_LENGTH * dt_s * fs_hz))
    t = np.arange(n) / fs_hz
    pos = np.asarray(jit_evaluated_once(prts_lean_fn(peak_rad, n_cycles, dt_s))(jnp.asarray(t)))
    knots_t, knots_a = prts_knots(peak_rad, n_cycles, dt_s)
    k = np.minimum((t / dt_s).astype(int), knots_t.size - 2)
    vel = (knots_a[k + 1] - knots_a[k]) / dt_s
    return t, pos, vel


def prts(peak_rad: float = math.radians(5.0), dt_s: float = PRTS_DT_S, cycles: int = 2,
         lever_m: float = 0.0) -> Trajectory:
    """T §III.A (`tahboub-prts`, after Peterka 2002): the 242-long PRTS sets the lean velocity to
    +v, 0 or −v for Δt = 0.25 s each (cycle 60.5 s); integrated to a lean angle centred on the
    middle of its range and spanning ±``peak_rad`` (5°), repeated ``cycles`` times
    (:func:`prts_lean_fn`: the same lean as the `tahboub-prts` stimulus). The velocity steps
    are the stimulus's definition: the angular velocity is piecewise constant and the angular
    acceleration zero between the level changes (where it is a Dirac impulse)."""
    return _lean(prts_lean_fn(peak_rad, cycles, dt_s), lever_m, cycles * PRTS_LENGTH * dt_s, "prts")


def still(duration_s: float = 10.0, R_I_B=None) -> Trajectory:
    """A body at rest (optionally tilted; ``R_I_B`` with |pitch| < π/2)."""
    rpy0 = jnp.zeros(3) if R_I_B is None else so3.rpy_from_matrix(R_I_B)
    return Trajectory(lambda t: jnp.zeros(3) + 0.0 * t, lambda t: rpy0 + 0.0 * t, float(duration_s),
                      "still")


BY_NAME = {
    "lissajous": lissajous,
    "impact": impact,
    "jump": jump,
    "walking": walking,
    "step": step,
    "sine": sine,
    "prts": prts,
    "still": still,
}
"""Constructors by name (for the CLI); each callable with its defaults."""
