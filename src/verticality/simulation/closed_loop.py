"""Closed-loop simulator: trunk trajectory → head on the gimbal → otolith pendulum(s) → sensors →
estimator → controller → motors (P13 §3 and §5; docs/reproduction.md, `ekf-impact`, `ekf-jump`).

Three clocks, each an integer multiple of the one below::

    plant       fixed-step RK4, dt_plant_s (1 ms)          state: gimbal (θ, θ̇) + pendulum(s)
    control     every dt_control_s (1 ms)                  m = controller(R̂_IH, ω_gyro, θ, θ̇), ZOH
    estimator   every dt_estimator_s (20 ms)               y measured, estimator.step(u, y, dt)

One run (:func:`run_loop`) is one ``lax.scan`` over estimator ticks (:func:`estimator_tick`), with a
scan over control ticks inside (:func:`control_tick`) and the plant's RK4 steps inside that
(:func:`plant_step`). The static part of a loop is a :class:`Loop` (settings, plug-ins, clock
ratios); the trunk's motion is sampled once (:func:`trunk_stages`) and handed to the compiled loop
as data, so one compilation serves every trajectory of the same duration. Batches of runs are
``jax.vmap`` of the same function over keys, plant parameters, noise and initial estimator states
(:func:`simulate_batch`).

The plant is a model value, :class:`verticality.models.gimbal_plant.GimbalPlant` (the head on its
gimbal over the trunk, carrying its otolith pendula; :data:`DEFAULT_PLANT` is P13's medial plant),
integrated as it is: its ``dynamics`` (staged RK4 with the trunk's motion at the stage times) and
its ``project``. The sensors are :mod:`verticality.sensors.readings`' gyro and inclinometer.

Conditions (static): ``"fixed"`` — the head is rigid on the trunk (P13: ᵀR_H = I), the gimbal is
locked at θ = 0 and no controller runs; ``"stabilized"`` — the gimbal's joint dynamics
(:class:`verticality.models.gimbal.GimbalHead`) under the motor torques of the controller.

Plug-in API
-----------
*Estimator* (:class:`Estimator`): any object with

    step(state, u, y, dt) -> (state, out)       the common estimator API (estimators/base.py)
    R_I_H(state) -> (3, 3)                      the head-orientation estimate the controller uses

called once per estimator tick t_k (k ≥ 1) with

    u                  a :class:`~verticality.models.head.HeadInput` ``(τ_H, a_I)`` whose leaves
                       have a leading axis of ``u_blocks``: the total torque on the head in frame
                       H (``FreeHead.torque``: motors plus gimbal constraint, the torque that
                       drives the free-head model of F 2.3) and the head centre's linear
                       acceleration in frame I (gravity excluded), each the exact (RK4-quadrature)
                       mean over one of ``u_blocks`` equal sub-intervals of (t_{k−1}, t_k] — the
                       input of a ``Discretized`` model with ``u_blocks`` sub-steps; with
                       ``SimConfig(accel_frame="head")`` a
                       :class:`~verticality.models.otolith_head.HeadFrameInput` ``(τ_H, ᴴa)``
                       (F §4.2.1's u = (ᴴτ, ᴴa)) instead;
    y  (2·P + 3,)      the P otolith pendulums' angles (φ_x, φ_y) of F 2.8–2.9, each with white
                       noise σ = ``noise.otolith_std_rad``, then the gyro (ω_H + bias + noise),
                       at t_k;
    dt                 dt_estimator_s.

``verticality.estimators.ekf.medial_filter`` fits this directly::

    filt = ekf.medial_filter(P13_EKF_PENDULUM, P13_EKF_HEAD, u_blocks=4)
    est = Estimator(step=filt.step, R_I_H=lambda s: s.x.head.R_I_H)
    run = make_simulator(trajectories.impact(), SimConfig(condition="stabilized", u_blocks=4),
                         estimator=est, controller=p13_controller())
    result = run(key, DEFAULT_PLANT, NoiseParams(), filt.init(x0, P0))

``estimator=None`` feeds the controller the true R_IH at every control tick (and the record's
estimate is the truth).

*Controller*: ``controller(R_I_H_est, omega_H_rad_s, theta_rad, thetadot_rad_s) -> motor torques
(2,)``. ``omega_H_rad_s`` is the head's gyro read at the control tick (rate, bias and white noise
of ``noise.gyro``); ``R_I_H_est`` is the estimator's latest estimate, propagated between estimator
ticks with that gyro (R̂ ← R̂ exp([ω_gyro]× dt_c), reset at every estimator tick); the joint angles
and rates are measured (the encoders, exact). Without an estimator the controller gets the true
R_IH and ω_H. :func:`p13_controller` is P13 §3's joint-space PD (k_p = 32 N·m/rad,
k_d = 5 N·m·s/rad, θ_d = Λ⁻¹ of the upright head for R̂_IT = R̂_IH Λ(θ)ᵀ), by default on the joint
error and its rate (F §4.2.2: the controller "used the estimated head's angular orientation and
velocity").

Records (:class:`Record`, leading axis = estimator ticks t_1 … t_K, plus the optional
per-control-tick :class:`ControlRecord`) hold the truth, the estimate, measurements and inputs,
and the tilt error of docs/conventions.md.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import cache, partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.compiling import jit_evaluated_once
from verticality.core.errors import InputError
from verticality.core.integrate import rk4_step_staged
from verticality.models import gimbal
from verticality.models.gimbal import GimbalInput
from verticality.models.gimbal_plant import GimbalPlant, GimbalPlantState, gimbal_plant
from verticality.models.head import FreeHead, HeadInput
from verticality.models.kinematics import RigidMotion
from verticality.models.otolith_head import HeadFrameInput, Otoliths
from verticality.models.params import P13_HEAD, P13_KD_NMS_RAD, P13_KP_NM_RAD, P13_PENDULUM
from verticality.models.pendulum import Pendulum, arm_direction_H
from verticality.sensors import readings as sensors
from verticality.sensors.readings import GyroParams

CONDITIONS = ("fixed", "stabilized")
ACCEL_FRAMES = ("inertial", "head")


class SimConfig(NamedTuple):
    """Static settings (a change recompiles)."""

    duration_s: float = 10.0
    condition: str = "stabilized"
    dt_plant_s: float = 1e-3
    dt_control_s: float = 1e-3
    dt_estimator_s: float = 0.02
    u_blocks: int = 1  # sub-interval means of u handed to the estimator per tick
    record_control: bool = False  # also record the truth at every control tick
    # u's acceleration: "inertial" (ᴵa, P13 §4) or "head" (ᴴa, F §4.2.1)
    accel_frame: str = "inertial"


DEFAULT_CONFIG = SimConfig()


class NoiseParams(NamedTuple):
    """Sensor noise (P13 §5: σ = 0.02 on the two inclinometer angles and the three gyro rates)."""

    otolith_std_rad: float = 0.02
    gyro: GyroParams = GyroParams(noise_std_rad_s=0.02, bias_rw_q_rad2_s3=0.0)


DEFAULT_PLANT = gimbal_plant(P13_HEAD, (P13_PENDULUM,))
"""P13's plant (§5): the P13 head on the gimbal carrying one pendulum at its centre (medial)."""
DEFAULT_NOISE = NoiseParams()


def noiseless() -> NoiseParams:
    return NoiseParams(otolith_std_rad=0.0, gyro=GyroParams(0.0, 0.0))


class Estimator(NamedTuple):
    """Adapter for any estimator with the common API (see the module docstring)."""

    step: Callable  # (state, u (HeadInput, leaves (u_blocks, 3)), y (2P+3,), dt) -> (state, out)
    R_I_H: Callable  # state -> (3, 3)


class Record(NamedTuple):
    """Per estimator tick (leading axis), at t_k = k · dt_estimator_s, k = 1 … K."""

    t_s: jnp.ndarray
    R_I_H: jnp.ndarray  # true head orientation (K, 3, 3)
    R_I_T: jnp.ndarray  # trunk orientation
    R_I_H_est: jnp.ndarray  # the estimate after the tick's update (truth if no estimator)
    tilt_error_deg: jnp.ndarray  # tilt error of R_I_H_est (docs/conventions.md)
    theta_rad: jnp.ndarray  # (K, 2) joint angles
    thetadot_rad_s: jnp.ndarray
    otolith_rad: jnp.ndarray  # (K, P, 2) true (noise-free) otolith angles
    y: jnp.ndarray  # (K, 2P+3) the measurements handed to the estimator
    u: Any  # HeadInput (or HeadFrameInput), leaves (K, u_blocks, 3): the estimator's inputs
    motor_torque_Nm: jnp.ndarray  # (K, 2) last motor torque of the interval
    estimator_out: Any  # the estimator's ``out`` pytree (None without estimator)


class ControlRecord(NamedTuple):
    """Per control tick (leading axis), at the *start* of each control interval."""

    t_s: jnp.ndarray
    R_I_H: jnp.ndarray
    R_I_H_est: jnp.ndarray  # the held estimate the controller used
    tilt_error_deg: jnp.ndarray
    theta_rad: jnp.ndarray
    otolith_rad: jnp.ndarray
    motor_torque_Nm: jnp.ndarray


class SimResult(NamedTuple):
    record: Record
    control: ControlRecord | None
    final_plant: GimbalPlantState
    final_estimator: Any


# ----------------------------------------------------------------------------------------------
# Controllers
# ----------------------------------------------------------------------------------------------


@cache
def p13_controller(kp: float = P13_KP_NM_RAD, kd: float = P13_KD_NMS_RAD,
                   tracking: bool = True) -> Callable:
    """P13 §3 joint-space PD (via :mod:`verticality.simulation.control`), θ_d = Λ⁻¹ of the upright
    head for the trunk estimate R̂_IT = R̂_IH Λ(θ)ᵀ.

    ``tracking=True`` (default): m = k_p (θ_d − θ) + k_d (θ̇_d − θ̇), P13's ``PD(θ_d − θ)`` with θ̇_d
    from the head's gyro and the encoders (:func:`control.joint_space_pd_tracking`).
    ``tracking=False``: m = k_p (θ_d − θ) − k_d θ̇, which lags a turning trunk (kept for comparison).
    One controller per gains, so that the compiled closed loops keyed on it are shared.
    """
    from verticality.simulation import control

    def controller(R_I_H_est, omega_H_rad_s, theta_rad, thetadot_rad_s):
        R_I_T_est = control.trunk_orientation_estimate(R_I_H_est, theta_rad)
        if tracking:
            return control.joint_space_pd_tracking(theta_rad, thetadot_rad_s, R_I_T_est,
                                                   omega_H_rad_s, kp, kd)
        return control.joint_space_pd(theta_rad, thetadot_rad_s, R_I_T_est, kp, kd)

    return controller


# ----------------------------------------------------------------------------------------------
# Plant
# ----------------------------------------------------------------------------------------------


def estimator_input(head: RigidMotion, head_model: FreeHead, accel_frame: str = "inertial"):
    """The estimator's input for the head moving as ``head`` (see the module docstring):
    :class:`HeadInput` ``(τ_H, ᴵa)`` with τ_H the total torque on the head
    (``head_model.torque``: motors plus gimbal constraint, the torque that drives the free-head
    model of F 2.3 along the head's actual motion).

    ``accel_frame="head"``: a :class:`HeadFrameInput` ``(τ_H, ᴴa = R_IHᵀ ᴵa)`` instead (F §4.2.1's
    u = (ᴴτ, ᴴa), still gravity excluded); the estimator must rotate it with its own R̂_IH."""
    return input_value(input_rows(head, head_model, accel_frame), accel_frame)


def input_rows(head: RigidMotion, head_model: FreeHead, accel_frame: str = "inertial"):
    """:func:`estimator_input` as one array ``(a (3), τ_H (3))`` (the form the simulator averages
    over its sub-intervals; :func:`input_value` makes the value of it)."""
    a = head.a_I_m_s2
    if accel_frame == "head":
        a = jnp.einsum("...ji,...j->...i", head.R_I_B, a)
    elif accel_frame != "inertial":
        raise ValueError(f"accel_frame must be one of {ACCEL_FRAMES}, not {accel_frame!r}")
    return jnp.concatenate([a, head_model.torque(head.omega_B_rad_s, head.omegadot_B_rad_s2)],
                           axis=-1)


def input_value(rows, accel_frame: str = "inertial"):
    """The :class:`HeadInput` (or :class:`HeadFrameInput`) of rows ``(..., 6)`` of
    :func:`input_rows`."""
    a, tau = rows[..., :3], rows[..., 3:]
    return HeadFrameInput(tau, a) if accel_frame == "head" else HeadInput(tau, a)


def initial_state(plant: GimbalPlant, trunk: RigidMotion, theta0_rad=None) -> GimbalPlantState:
    """θ0: the upright head for the trunk at rest (``theta0_rad=None``; 0 and ignored when the plant
    is ``fixed``), at rest relative to the trunk; pendula at rest relative to the head along the
    gravito-inertial vertical."""
    if theta0_rad is None and not plant.fixed:
        theta0_rad = gimbal.joint_angles_for_up(so3.up_in_frame(trunk.R_I_B))
    return plant.rest_state(trunk, theta0_rad)


def with_condition(plant: GimbalPlant, condition: str) -> GimbalPlant:
    """``plant`` in the ``condition`` of :data:`CONDITIONS` (``fixed``: head rigid on the trunk)."""
    if condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {CONDITIONS}, not {condition!r}")
    return dataclasses.replace(plant, fixed=condition == "fixed")


# ----------------------------------------------------------------------------------------------
# The simulator: one scan over estimator ticks (:func:`estimator_tick`), a scan over control ticks
# inside (:func:`control_tick`), the plant's RK4 steps inside that (:func:`plant_step`)
# ----------------------------------------------------------------------------------------------


def _ratio(a: float, b: float, what: str) -> int:
    n = round(a / b)
    if n < 1 or abs(n * b - a) > 1e-9 * max(a, 1.0):
        raise ValueError(f"{what}: {a} is not an integer multiple of {b}")
    return n


class Loop(NamedTuple):
    """The static part of a closed loop: its settings, its plug-ins and its clocks' ratios.

    Hashable (the plug-ins by identity): the compiled loop is keyed on it, so every trunk motion,
    plant, noise and estimator state of the same shapes reuses one compilation. The trunk's motion
    is an argument of the compiled loop, not a constant of it (:func:`trunk_stages`)."""

    config: SimConfig
    estimator: Estimator | None
    controller: Callable | None
    steps_per_control: int  # plant steps per control tick
    controls_per_estimate: int  # control ticks per estimator tick
    estimates: int  # estimator ticks in the run

    @property
    def stabilized(self) -> bool:
        return self.config.condition == "stabilized"


def make_loop(config: SimConfig, estimator: Estimator | None = None,
              controller: Callable | None = None) -> Loop:
    """The :class:`Loop` of ``config`` with its plug-ins, its settings checked."""
    if config.condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {CONDITIONS}, not {config.condition!r}")
    if config.condition == "stabilized" and controller is None:
        raise ValueError("the stabilized condition needs a controller (e.g. p13_controller())")
    n_c = _ratio(config.dt_control_s, config.dt_plant_s, "dt_control_s")
    n_e = _ratio(config.dt_estimator_s, config.dt_control_s, "dt_estimator_s")
    n_k = _ratio(config.duration_s, config.dt_estimator_s, "duration_s")
    nb = int(config.u_blocks)
    if n_e % nb:
        raise ValueError(f"u_blocks={nb} must divide the {n_e} control ticks of an estimator tick")
    if config.accel_frame not in ACCEL_FRAMES:
        raise ValueError(f"accel_frame must be one of {ACCEL_FRAMES}, not {config.accel_frame!r}")
    return Loop(config, estimator, controller, n_c, n_e, n_k)


def trunk_stages(traj, loop: Loop):
    """The trunk's motion at the start, middle and end of every plant step (the stages of the
    plant's RK4), evaluated in one vectorised pass (the trajectory is open-loop), shaped
    ``(estimates, controls_per_estimate, steps_per_control, 3, ...)``."""
    n_k, n_e, n_c = loop.estimates, loop.controls_per_estimate, loop.steps_per_control
    h = loop.config.dt_plant_s
    n_steps = n_k * n_e * n_c
    motion = jax.vmap(traj.motion)(jnp.arange(2 * n_steps + 1) * (0.5 * h))
    stages = jax.tree_util.tree_map(
        lambda a: jnp.stack([a[0:-1:2], a[1::2], a[2::2]], axis=1), motion)
    return jax.tree_util.tree_map(lambda a: a.reshape((n_k, n_e, n_c) + a.shape[1:]), stages)


def plant_rate(trunk: RigidMotion, x: GimbalPlantState, m, plant: GimbalPlant,
               accel_frame: str):
    """(ẋ, the estimator's input rows) of the plant under motor torques ``m`` with the trunk
    moving as ``trunk``, for the staged RK4; the input is computed outside the loop when the
    plant is fixed (it is open-loop: :func:`open_loop_input`)."""
    rate, head = plant.rate_and_motion(x, GimbalInput(m, trunk))
    if plant.fixed:
        return rate, jnp.zeros(0)
    return rate, input_rows(head, plant.head, accel_frame)


def plant_step(plant: GimbalPlant, trunk3: RigidMotion, x: GimbalPlantState, m, h: float,
               accel_frame: str):
    """One RK4 step of ``h`` seconds of the plant (motor torques ``m`` held, the trunk's motion
    ``trunk3`` at the step's start, middle and end): the next state and the RK4 mean of the
    estimator's input rows over the step."""
    return rk4_step_staged(plant_rate, trunk3, x, h, m, plant, accel_frame,
                           project=plant.project)


def motor_torque(loop: Loop, R_I_H_est, omega_H_rad_s, gimbal_state):
    """The controller's motor torques (2,) (zero when the gimbal is locked)."""
    if not loop.stabilized:
        return jnp.zeros(2)
    return loop.controller(R_I_H_est, omega_H_rad_s, gimbal_state.theta_rad,
                           gimbal_state.thetadot_rad_s)


def control_tick(loop: Loop, plant: GimbalPlant, bias, carry, trunk_steps, t0_s, gyro_noise):
    """One control tick: the gyro read, the controller, then the plant's steps over the tick
    with the torque held. ``carry`` is (plant state, the controller's held estimate R̂_IH);
    ``trunk_steps`` the trunk's motion at (start, middle, end) of each of the tick's plant steps.
    Returns the carry at the tick's end and (the mean input rows, m, the tick's record)."""
    n_c, h = loop.steps_per_control, loop.config.dt_plant_s
    accel_frame = loop.config.accel_frame
    x, R_hat = carry
    trunk0 = jax.tree_util.tree_map(lambda a: a[0, 0], trunk_steps)
    R_I_H = plant.head_orientation(x, trunk0)
    omega_true = plant.head_angular_velocity(x, trunk0)
    if loop.estimator is None:  # the controller sees the truth
        R_hat, omega_meas = R_I_H, omega_true
    else:  # the head's gyro at the control rate
        omega_meas = sensors.gyro_reading(omega_true, bias, gyro_noise)
    m = motor_torque(loop, R_hat, omega_meas, x.gimbal)
    locked = x.gimbal
    if not loop.stabilized:  # the locked gimbal stays out of the integration
        x = x._replace(gimbal=None)
    if n_c == 1:  # one plant step per control tick: no inner loop (its overhead is per step)
        x_new, u_step = plant_step(plant, jax.tree_util.tree_map(lambda a: a[0], trunk_steps),
                                   x, m, h, accel_frame)
        u_steps = u_step[None]
    else:
        x_new, u_steps = jax.lax.scan(lambda c, w3: plant_step(plant, w3, c, m, h, accel_frame),
                                      x, trunk_steps)
    if not loop.stabilized:
        x, x_new = x._replace(gimbal=locked), x_new._replace(gimbal=locked)
    rec = None
    if loop.config.record_control:
        rec = ControlRecord(t0_s, R_I_H, R_hat, so3.tilt_error_deg(R_I_H, R_hat),
                            x.gimbal.theta_rad, plant.otoliths.angles(x.pendula, R_I_H), m)
    # between estimator ticks the controller's estimate is propagated with the gyro
    R_next = so3.orthonormalize(R_hat @ so3.exp(omega_meas * (n_c * h)))
    return (x_new, R_next), (jnp.mean(u_steps, 0), m, rec)


def open_loop_input(plant: GimbalPlant, trunk_ticks, accel_frame: str):
    """Simpson (= RK4) mean over each plant step of the fixed head's (the trunk's) input rows,
    averaged over each control tick: (controls_per_estimate, 6)."""
    u_stage = jax.vmap(jax.vmap(jax.vmap(
        lambda w: input_rows(w, plant.head, accel_frame))))(trunk_ticks)  # (n_e, n_c, 3, 6)
    return jnp.mean((u_stage[:, :, 0] + 4.0 * u_stage[:, :, 1] + u_stage[:, :, 2]) / 6.0, axis=1)


def sense(plant: GimbalPlant, x: GimbalPlantState, trunk: RigidMotion, bias, key_k,
          noise: NoiseParams, dt_s: float):
    """The sensors at an estimator tick: ``(y, φ, R_IH, the gyro bias after the tick)``; y is the
    otolith angles φ with white noise, then the gyro (ω_H + bias + noise)."""
    R_I_H = plant.head_orientation(x, trunk)
    omega_H = plant.head_angular_velocity(x, trunk)
    phi = plant.otoliths.angles(x.pendula, R_I_H)
    k_phi, k_gyro, k_bias = jax.random.split(key_k, 3)
    y_phi = sensors.inclinometer(k_phi, phi, noise.otolith_std_rad)
    y_gyro = sensors.gyro_reading(omega_H, bias,
                                  sensors.gyro_white_noise(k_gyro, (3,), noise.gyro))
    bias = sensors.gyro_bias_step(k_bias, bias, dt_s, noise.gyro)
    return jnp.concatenate([y_phi.reshape(-1), y_gyro]), phi, R_I_H, bias


def estimator_update(loop: Loop, est_state, u, y, R_I_H):
    """The estimator's step on (u, y): ``(its state, its out, the estimate R̂_IH)``; without an
    estimator the estimate is the truth ``R_I_H``."""
    if loop.estimator is None:
        return est_state, None, R_I_H
    est_state, out = loop.estimator.step(est_state, u, y, loop.config.dt_estimator_s)
    return est_state, out, loop.estimator.R_I_H(est_state)


def estimator_tick(loop: Loop, plant: GimbalPlant, noise: NoiseParams, key, carry, inp):
    """The scan body over estimator ticks: the control ticks of the interval (t_k, t_k+1], the
    estimator's input (``u_blocks`` block means), the sensors at t_k+1 and the estimator's step.
    ``carry`` is (plant state, estimator state, gyro bias, the controller's held estimate);
    ``inp`` is (k, the trunk's stage motions of the interval, (n_e, n_c, 3, ...))."""
    cfg = loop.config
    n_e, n_c, h = loop.controls_per_estimate, loop.steps_per_control, cfg.dt_plant_s
    x, est_state, bias, R_hat = carry
    k, trunk_ticks = inp
    t_ctrl = (k * n_e + jnp.arange(n_e)) * (n_c * h)
    k_ctrl, key_k = jax.random.split(jax.random.fold_in(key, k))
    gyro_noise = sensors.gyro_white_noise(k_ctrl, (n_e, 3), noise.gyro)
    (x, _), (u_ticks, m_ticks, crec) = jax.lax.scan(
        lambda c, a: control_tick(loop, plant, bias, c, a[0], a[1], a[2]), (x, R_hat),
        (trunk_ticks, t_ctrl, gyro_noise))
    if not loop.stabilized:
        u_ticks = open_loop_input(plant, trunk_ticks, cfg.accel_frame)
    nb = int(cfg.u_blocks)
    u = input_value(jnp.mean(u_ticks.reshape(nb, n_e // nb, 6), axis=1), cfg.accel_frame)
    t = (k + 1) * n_e * n_c * h
    trunk = jax.tree_util.tree_map(lambda a: a[-1, -1, 2], trunk_ticks)  # at t_{k+1}
    y, phi, R_I_H, bias = sense(plant, x, trunk, bias, key_k, noise, cfg.dt_estimator_s)
    est_state, out, R_est = estimator_update(loop, est_state, u, y, R_I_H)
    rec = Record(
        t_s=t, R_I_H=R_I_H, R_I_T=trunk.R_I_B, R_I_H_est=R_est,
        tilt_error_deg=so3.tilt_error_deg(R_I_H, R_est), theta_rad=x.gimbal.theta_rad,
        thetadot_rad_s=x.gimbal.thetadot_rad_s, otolith_rad=phi, y=y, u=u,
        motor_torque_Nm=m_ticks[-1], estimator_out=out)
    return (x, est_state, bias, R_est), (rec, crec)


def run_loop(loop: Loop, trunk0: RigidMotion, stages, key, plant: GimbalPlant = DEFAULT_PLANT,
             noise: NoiseParams = DEFAULT_NOISE, estimator_state0=None, gyro_bias0_rad_s=None,
             theta0_rad=None) -> SimResult:
    """One run of the closed loop ``loop`` (traceable; :data:`run_compiled` is it compiled):
    the trunk at rest-relative start ``trunk0`` (its motion at t = 0) and moving through
    ``stages`` (:func:`trunk_stages`), the plant from :func:`initial_state` (``theta0_rad``)."""
    plant = with_condition(plant, loop.config.condition)
    x0 = initial_state(plant, trunk0, theta0_rad)
    bias0 = jnp.zeros(3) if gyro_bias0_rad_s is None else jnp.asarray(gyro_bias0_rad_s, float)
    R_hat0 = plant.head_orientation(x0, trunk0)
    if loop.estimator is not None:
        R_hat0 = loop.estimator.R_I_H(estimator_state0)
    (x, est, _, _), (rec, crec) = jax.lax.scan(
        lambda c, inp: estimator_tick(loop, plant, noise, key, c, inp),
        (x0, estimator_state0, bias0, R_hat0), (jnp.arange(loop.estimates), stages))
    if crec is not None:
        crec = jax.tree_util.tree_map(lambda a: a.reshape((-1,) + a.shape[2:]), crec)
    return SimResult(rec, crec, x, est)


run_compiled = jax.jit(run_loop, static_argnums=0)
""":func:`run_loop` compiled, once per :class:`Loop` and argument shapes."""


@partial(jax.jit, static_argnums=(0, 1))
def run_batch_compiled(loop: Loop, in_axes: tuple, trunk0, stages, theta0_rad, keys, plant,
                       noise, estimator_states0):
    """``jax.vmap`` of :func:`run_loop` over ``keys`` and the arguments ``in_axes`` marks (the
    trunk's motion is shared), compiled once per :class:`Loop`, axes and shapes."""

    def one(key, plant_i, noise_i, state0):
        return run_loop(loop, trunk0, stages, key, plant_i, noise_i, state0, None, theta0_rad)

    return jax.vmap(one, in_axes=in_axes)(keys, plant, noise, estimator_states0)


_SAMPLED_TRUNKS: list = []  # (trajectory, clocks, its samples): the last few sampled
_SAMPLED_TRUNKS_KEPT = 4


def sample_trunk(traj, loop: Loop):
    """``(the trunk's motion at t = 0, its :func:`trunk_stages`)``, compiled for this trajectory
    (its functions close over its parameters); the last few trajectories' samples are kept, so
    that the runs of one trajectory sample it once."""
    clocks = (loop.config.dt_plant_s, loop.steps_per_control, loop.controls_per_estimate,
              loop.estimates)
    for kept, kept_clocks, samples in _SAMPLED_TRUNKS:
        if kept is traj and kept_clocks == clocks:
            return samples
    samples = jit_evaluated_once(lambda: (traj.motion(0.0), trunk_stages(traj, loop)))()
    _SAMPLED_TRUNKS.insert(0, (traj, clocks, samples))
    del _SAMPLED_TRUNKS[_SAMPLED_TRUNKS_KEPT:]
    return samples


class Simulator(NamedTuple):
    """A closed loop on one trunk motion (:func:`make_simulator`): call it as
    ``run(key, plant, noise, estimator_state0, gyro_bias0_rad_s) -> SimResult``."""

    loop: Loop
    trunk0: RigidMotion  # the trunk's motion at t = 0
    stages: RigidMotion  # :func:`trunk_stages`
    theta0_rad: Any  # None: the upright head for the trunk at rest

    def __call__(self, key, plant: GimbalPlant = DEFAULT_PLANT,
                 noise: NoiseParams = DEFAULT_NOISE, estimator_state0=None,
                 gyro_bias0_rad_s=None) -> SimResult:
        return run_compiled(self.loop, self.trunk0, self.stages, key, plant, noise,
                            estimator_state0, gyro_bias0_rad_s, self.theta0_rad)


def make_simulator(traj, config: SimConfig, estimator: Estimator | None = None,
                   controller: Callable | None = None, theta0_rad=None) -> Simulator:
    """The closed loop of ``config`` with its plug-ins on the trunk trajectory ``traj`` (a
    :class:`verticality.simulation.trajectories.Trajectory`): a :class:`Simulator`,
    ``run(key, plant, noise, estimator_state0) -> SimResult``.

    The trunk's motion is sampled once here (:func:`trunk_stages`) and handed to the compiled
    loop as data, so that runs on other trajectories of the same duration share its compilation.
    ``plant`` is a :class:`GimbalPlant` value (default :data:`DEFAULT_PLANT`); ``config.condition``
    sets its ``fixed`` switch. Use :func:`simulate_batch` for batches.
    """
    loop = make_loop(config, estimator, controller)
    theta0 = None if theta0_rad is None else jnp.asarray(theta0_rad, float)
    return Simulator(loop, *sample_trunk(traj, loop), theta0)


def simulate(traj, config: SimConfig, key=None, plant: GimbalPlant = DEFAULT_PLANT,
             noise: NoiseParams = DEFAULT_NOISE, estimator: Estimator | None = None,
             estimator_state0=None, controller: Callable | None = None) -> SimResult:
    """One run (keep :func:`make_simulator`'s ``run`` to run the same trunk motion again)."""
    key = jax.random.PRNGKey(0) if key is None else key
    run = make_simulator(traj, config, estimator, controller)
    return run(key, plant, noise, estimator_state0)


def simulate_batch(run: Simulator, keys, plant: GimbalPlant = DEFAULT_PLANT,
                   noise: NoiseParams = DEFAULT_NOISE, estimator_states0=None,
                   batched_plant: bool = False, batched_estimator: bool = False,
                   batched_noise: bool = False) -> SimResult:
    """``jax.vmap`` of a :func:`make_simulator` ``run`` over ``keys`` (B, 2) and, optionally, over a
    leading batch axis of the plant's parameters, of ``noise`` and of the initial estimator
    states."""
    in_axes = (0, 0 if batched_plant else None, 0 if batched_noise else None,
               0 if batched_estimator else None)
    return run_batch_compiled(run.loop, in_axes, run.trunk0, run.stages, run.theta0_rad, keys,
                              plant, noise, estimator_states0)


def tilt_metrics(record: Record, t_min_s: float = 2.0) -> dict:
    """``max`` and ``rms`` tilt error (deg) after ``t_min_s`` (docs/reproduction.md, `ekf-*`)."""
    mask = record.t_s >= t_min_s
    e = jnp.where(mask, record.tilt_error_deg, 0.0)
    n = jnp.maximum(jnp.sum(mask), 1)
    return {"max_tilt_error_deg": jnp.max(e), "rms_tilt_error_deg": jnp.sqrt(jnp.sum(e * e) / n)}


# ----------------------------------------------------------------------------------------------
# Open-loop replay of a recorded head motion (the `verticality otolith` command)
# ----------------------------------------------------------------------------------------------


def _lerp(a, b, f):
    return a + f * (b - a)


def _replay_chunk(otoliths: Otoliths, x0: tuple, rows, xs):
    """RK4 over a chunk of sub-steps; inputs interpolated linearly between rows (the quaternion
    interpolated then normalized, ω̇ the slope of ω). Returns the states and (s_H, φ) after each."""
    t_rows, q_rows, w_rows, a_rows = rows

    def head_at(i, f):
        q = _lerp(q_rows[i], q_rows[i + 1], f)
        w = _lerp(w_rows[i], w_rows[i + 1], f)
        dt = jnp.maximum(t_rows[i + 1] - t_rows[i], 1e-300)
        return RigidMotion(R_I_B=so3.matrix_from_quat(q / jnp.linalg.norm(q)), omega_B_rad_s=w,
                           omegadot_B_rad_s2=(w_rows[i + 1] - w_rows[i]) / dt,
                           a_I_m_s2=_lerp(a_rows[i], a_rows[i + 1], f))

    def rate(head, x):
        return otoliths.dynamics(x, head), None

    def body(x, inp):
        i, f0, fh, h = inp
        heads = jax.tree_util.tree_map(lambda *a: jnp.stack(a), head_at(i, f0),
                                       head_at(i, f0 + 0.5 * fh), head_at(i, f0 + fh))
        x_new, _ = rk4_step_staged(rate, heads, x, h, project=otoliths.project)
        R_I_H = heads.R_I_B[2]
        s = jnp.stack([arm_direction_H(xp, R_I_H) for xp in x_new])
        return x_new, (s, otoliths.angles(x_new, R_I_H))

    return jax.lax.scan(body, x0, xs)


_replay_chunk_jit = jax.jit(_replay_chunk)


def otolith_replay(t_s, q_I_H_wxyz, omega_H_rad_s, a_I_m_s2, pendula: tuple[Pendulum, ...],
                   max_substep_s: float = 1e-3, chunk: int = 8192, progress=None):
    """What the otolith pendulum(s) report for a recorded head motion.

    Between rows the inputs are interpolated linearly (the quaternion then normalized; ω̇ is the
    slope of ω over the interval) and integrated by RK4 with ⌈Δt / h⌉ equal sub-steps, ``h`` the
    shorter of ``max_substep_s`` and half the pendulums' fastest time constant
    (:func:`replay_substep_s`: a stiff model gets short steps or is refused with the reason). The
    work is sized before anything is allocated (:func:`check_replay_size`), and a row whose
    simulated output is not finite is refused (:class:`InputError`), never written as NaN.
    The pendulums start at rest relative to the head, along the gravito-inertial vertical of the
    first row (:meth:`Pendulum.rest_state`). ``pendula``: the :class:`Pendulum` values (one for
    the medial model; :func:`verticality.models.params.lateral_pendulums` for the lateral one).
    Returns ``s_H`` (N, P, 3) and ``φ`` (N, P, 2) on the rows. ``progress(done, total)`` is called
    after each chunk of sub-steps.
    """
    t = np.asarray(t_s, float)
    q = np.array(q_I_H_wxyz, float)
    max_substep_s = replay_substep_s(pendula, max_substep_s)
    check_replay_size(t, max_substep_s)
    for i in range(1, len(q)):  # q and −q are one rotation: interpolate along the short arc
        if np.dot(q[i], q[i - 1]) < 0.0:
            q[i] = -q[i]
    w = np.asarray(omega_H_rad_s, float)
    a = np.asarray(a_I_m_s2, float)
    otoliths = Otoliths(tuple(pendula))
    n_rows = t.size
    dt = np.diff(t)
    n_sub = np.maximum(np.ceil(dt / max_substep_s - 1e-9).astype(int), 1)
    total = int(n_sub.sum())
    idx = np.repeat(np.arange(n_rows - 1), n_sub)
    k = np.arange(total) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)
    fh = 1.0 / n_sub[idx] if total else np.zeros(0)
    f0 = k * fh
    h = dt[idx] / n_sub[idx] if total else np.zeros(0)
    pad = (-total) % chunk if total else 0
    xs = (np.concatenate([idx, np.zeros(pad, int)]), np.concatenate([f0, np.zeros(pad)]),
          np.concatenate([fh, np.zeros(pad)]), np.concatenate([h, np.zeros(pad)]))
    # a last, duplicated row keeps the gathers of padded sub-steps in range
    rows = tuple(jnp.asarray(np.concatenate([v, v[-1:]])) for v in (t + 0.0, q, w, a))
    rows = (rows[0].at[-1].add(1.0),) + rows[1:]
    w_dot0 = (w[1] - w[0]) / dt[0] if n_rows > 1 else np.zeros(3)
    R0 = so3.matrix_from_quat(jnp.asarray(q[0]))
    head0 = RigidMotion(R0, jnp.asarray(w[0]), jnp.asarray(w_dot0), jnp.asarray(a[0]))
    x = otoliths.rest_state(head0)
    s_out = [np.stack([np.asarray(arm_direction_H(xp, R0)) for xp in x])[None]]
    phi_out = [np.asarray(otoliths.angles(x, R0))[None]]
    n_chunks = (total + pad) // chunk
    for c in range(n_chunks):
        sl = slice(c * chunk, (c + 1) * chunk)
        x, (s_c, phi_c) = _replay_chunk_jit(otoliths, x, rows,
                                            tuple(jnp.asarray(v[sl]) for v in xs))
        s_out.append(np.asarray(s_c))
        phi_out.append(np.asarray(phi_c))
        if progress is not None:
            progress(c + 1, n_chunks)
    s_all = np.concatenate(s_out)[: total + 1]
    phi_all = np.concatenate(phi_out)[: total + 1]
    at_rows = np.concatenate([[0], np.cumsum(n_sub)]) if total else np.zeros(1, int)
    s_rows, phi_rows = s_all[at_rows], phi_all[at_rows]
    bad = ~(np.all(np.isfinite(s_rows), axis=(1, 2)) & np.all(np.isfinite(phi_rows), axis=(1, 2)))
    if np.any(bad):
        k = int(np.argmax(bad))
        raise InputError(f"the simulated pendulum became non-finite at row {k + 1} "
                         f"(t = {t[k]:g} s): "
                         "the head's motion is beyond what the model integrates (an acceleration "
                         f"of {np.max(np.abs(a[:k + 1])):.3g} m/s² or a rate of "
                         f"{np.max(np.abs(w[:k + 1])):.3g} rad/s by then); no row is written")
    return s_rows, phi_rows


RK4_STEPS_PER_TIME_CONSTANT = 2.0  # sub-step ≤ τ_fastest / 2: |hλ| ≤ 0.5, far inside RK4's
# stability limit (|hλ| < 2.78 on the negative real axis) and accurate to ~1e-4 per step
MIN_SUBSTEP_S = 1e-7
SUBSTEP_BYTES = 112  # sub-step tables (32 B) and outputs (40 B per pendulum)


@jax.jit
def _A_at_rest(pendulum, still: RigidMotion):
    """A of the pendulum linearized at rest on ``still``, compiled: op by op, the autodiff cost
    seconds of dispatch and compilation per process."""
    from verticality.models.linearize import linearize

    return linearize(pendulum, pendulum.rest_state(still), still).A


def fastest_rate_1_s(pendula) -> float:
    """The largest |eigenvalue| (1/s) of the pendulums' dynamics linearized at rest on a still,
    upright head (:func:`verticality.models.linearize.linearize` of each model value): one over
    the fastest time constant (the damped spin about the arm, β/J_zz, for the P13 pendulum)."""
    still = RigidMotion(jnp.eye(3), jnp.zeros(3), jnp.zeros(3), jnp.zeros(3))
    rho = 0.0
    for p in pendula:
        A = np.asarray(_A_at_rest(p, still))
        rho = max(rho, float(np.max(np.abs(np.linalg.eigvals(A)))))
    return rho


def replay_substep_s(pendula, max_substep_s: float = 1e-3) -> float:
    """The RK4 sub-step of :func:`otolith_replay`: ``max_substep_s``, shortened to half the
    pendulums' fastest time constant (:func:`fastest_rate_1_s`) when that is shorter (a short arm
    or a large damping makes the model stiff). A model whose time constant is not finite, or asks
    for a sub-step below ``MIN_SUBSTEP_S``, is refused with the reason."""
    rho = fastest_rate_1_s(pendula)
    if not np.isfinite(rho):
        raise InputError("the pendulum's dynamics are not finite at rest (check --param: mass, "
                         "arm and inertias must be positive)")
    if rho * max_substep_s <= 1.0 / RK4_STEPS_PER_TIME_CONSTANT:
        return max_substep_s
    h = 1.0 / (RK4_STEPS_PER_TIME_CONSTANT * rho)
    if h < MIN_SUBSTEP_S:
        raise InputError(f"the pendulum is too stiff to integrate: its fastest time constant is "
                         f"{1.0 / rho:.3g} s, which needs RK4 steps of {h:.3g} s (below "
                         f"{MIN_SUBSTEP_S:g} s); lengthen the arm or lower the damping (--param "
                         "l=..., beta=..., Jzz=...)")
    return h


def check_replay_size(t_s, substep_s: float) -> None:
    """Refuse, before anything is allocated, a replay of times ``t_s`` whose RK4 sub-steps of
    ``substep_s`` do not fit in memory (:func:`verticality.core.sizing.check_work_size`; a time
    stamp that jumps by 10⁶ s, a stiff model over a long recording), naming the size, the largest
    step and what to change."""
    from verticality.core.sizing import check_work_size

    t = np.asarray(t_s, float)
    dt = np.diff(t)
    if dt.size == 0:
        return
    total = float(np.sum(np.maximum(np.ceil(dt / substep_s - 1e-9), 1.0)))
    k = int(np.argmax(dt))
    check_work_size(total, SUBSTEP_BYTES, f"RK4 sub-steps of {substep_s:.3g} s",
                    f"the largest time step is {dt[k]:.6g} s (data row {k + 2}); cut the recording "
                    "into shorter files or remove the jump, or lengthen the pendulum's time "
                    "constants (--param)")
