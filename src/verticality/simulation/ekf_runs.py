"""The closed-loop EKF runs of `ekf-impact`, `ekf-jump`, `ekf-sensitivity`, the `ekf-*` sweep
kernels and `stabilize`: the EKF on the gimbal head, fixed versus stabilized (P13 §5, F §4.2.2).

Plant (truth, :mod:`verticality.simulation.closed_loop`): the head on the 2-DOF gimbal over the
moving trunk, carrying the otolith pendulum, P13's true parameters (m = 50 g, l = 0.06 m,
J_H = 0.125 I, β = 0.001), fixed-step RK4 at 1 ms; the joint-space PD of P13 §3 (k_p = 32,
k_d = 5) at 1 ms, fed by the latest estimate; the EKF every 20 ms; measurement noise σ = 0.02 on
the two inclinometer angles and the three gyro rates (seeded). Trajectories:
:func:`verticality.simulation.trajectories.impact` and
:func:`verticality.simulation.trajectories.jump` (their docstrings give their readings of P13
Fig. 2).

Estimators: the multiplicative EKF on SO(3) (:mod:`verticality.estimators.ekf`, the metrics of
docs/reproduction.md) and the papers' stacked 24-element EKF
(:mod:`verticality.estimators.ekf_stacked`, extra keys ``*_stacked``), both with P13's wrong model
parameters (m̃ = 60 g, l̃ = 0.04 m, J̃_H = 0.15 I, β̃ = 0.0005), both started 0.1 rad off (a
rotation of 0.1 rad about the head's (1, 1, 0)/√2 axis applied to both R_IS and R_IH: a 5.7° tilt
error), P0 below.

Readings where the papers are silent (choices):
- **Torque input** (P13 §4: "u = (ᴵa, ᴴτ) ... the torque applied to the head"). P13 §3 defines τ as
  the torque "applied to the head platform by the actuated gimbal". In the ``stabilized`` condition
  the EKF receives the total torque on the head (``FreeHead.torque`` of the head's motion: motors
  plus the constraint torque about the one unactuated axis; the simulator's input). In the ``fixed``
  condition the gimbal is locked and no actuator torque exists: the EKF receives zero torque, so its
  head model does not know how the trunk rotates the head and the gyros must carry that
  (``torque_input="gimbal"``, default). The alternative reading, the total torque in both conditions
  (the head's motion then known in both), is run too: keys ``*_total_torque``. docs/ekf.md discusses
  both.
- Inputs are given as 4 block means over each 20 ms period (5 ms each, the simulator's exact
  quadrature) and the EKF predicts with 4 RK4 substeps, each with its block's input held.
- **Acceleration input**: ᴵa of the head centre, gravity excluded, noise-free (P13 §4: ᴵa).
  F §4.2.1 writes ᴴa instead; that reading (the simulator's ``accel_frame="head"``, the filter's
  model the input adapter :class:`~verticality.models.otolith_head.HeadFrameAcceleration`, which
  rotates ᴴa with its own R̂_IH) is run too: keys ``*_head_frame_accel``.
- **Process noise** (one setting, both conditions, both experiments), per 20 ms step, on the error
  state (δθ_S, δω_S, δθ_H, δω_H) = (0.001, 0.03, 0.0003, 0.001), plus the parameter-uncertainty
  ("consider") noise of :mod:`verticality.estimators.parameter_noise`: the model's own m̃, l̃, β̃,
  J̃_H each uncertain by 50 % (1 σ, relative), linearized by autodiff at the prior into the rates'
  noise. It vanishes for a pendulum hanging at rest (its equilibrium does not depend on m, l, β)
  and grows when the pendulum swings or the head is driven by a large torque, which a constant Q
  cannot do. The head's rate keeps P13 §5's σ_w = 0.001: the free-head model driven by the known
  torque is trusted, right for the servoed head and wrong for the fixed head, whose trunk-driven
  motion the model does not know (zero gimbal torque) — the asymmetry P13 attributes the benefit
  to (how much the ratio depends on that σ, on the jump's trunk pitch and on the sensor noise:
  :mod:`verticality.simulation.ekf_ratio_sweeps`). The head's rotation error gets 3e-4 rad (it
  only absorbs integration error); the pendulum's rate 0.03 rad/s (the input's 5 ms block means).
  The previous constant Q (0.001, 0.3, 0.0003, 0.001), no parameter noise, is run too: keys
  ``*_constant_q``.
- **Initial covariance** (``p0="common"``): the initial estimate's pendulum hangs at rest relative
  to its head, so the 0.1 rad error is one common rotation of both frames: cov(δθ_S, δθ_H) =
  σ0² R_SH, plus 0.02 rad independent on δθ_S (``initial_covariance``). The diagonal σ0² I₁₂ treats
  the otolith–head angle as uncertain by 0.1 rad too, which it is not.
- **Trajectories.** ``impact`` with a 1.5 s ramp-in (the 0.5 s default faded the oscillation in with
  9.6 m/s² and 12.9 rad/s² transients, larger than the oscillation's own 3.0 m/s² and 4.2 rad/s²;
  1.5 s keeps the ramp within 3.4 m/s² / 4.1 rad/s²). ``jump`` with the push at 3 s and 8 s in all:
  with the default push at 1 s the whole jump ends before the 2 s convergence window
  docs/reproduction.md excludes, and the metrics would score a trunk at rest. Amplitudes unchanged.
- Seeds 0, 1, 2 (vmapped): ``max`` is the largest over the seeds, ``rms`` over all their samples;
  ``*_per_seed`` lists each seed's maximum. Figures show seed 0.
- Metrics after t ≥ 2 s (docs/reproduction.md), per EKF sample (50 Hz).

Runs that differ only in their filter's Q and R, their sensor noise or their trunk motion (of one
duration) share one compiled closed loop: the estimator and the controller of a reading are built
once per process (:func:`closed_loop_estimator`), Q and R ride in the estimator's state
(:class:`Tuned`) and the trunk's motion is data
(:func:`verticality.simulation.closed_loop.make_simulator`).
"""

from __future__ import annotations

import dataclasses
import inspect
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.estimators import ekf, ekf_stacked, parameter_noise
from verticality.models import gimbal
from verticality.models.gimbal_plant import gimbal_plant
from verticality.models.head import HeadInput, state_from_motion
from verticality.models.otolith_head import HeadFrameAcceleration, HeadFrameInput, OtolithHeadState
from verticality.models.params import P13_EKF_HEAD, P13_EKF_PENDULUM, P13_HEAD, P13_PENDULUM
from verticality.simulation import closed_loop as sim
from verticality.simulation import trajectories

T_SETTLE_S = 2.0
INITIAL_ERROR_RAD = 0.1
SIGMA_PROCESS = (1e-3, 0.03, 3e-4, 1e-3)  # per step: δθ_S, δω_S, δθ_H, δω_H (+ parameter noise)
SIGMA_MEASUREMENT = 0.02  # P13 §5: inclinometer angles (rad) and gyro rates (rad/s), sim and filter
# a constant Q without parameter noise (*_constant_q)
SIGMA_PROCESS_CONSTANT = (1e-3, 0.3, 3e-4, 1e-3)
SEEDS = (0, 1, 2)
IMPACT_RAMP_IN_S = 1.5
JUMP_T_PUSH_S, JUMP_DURATION_S = 3.0, 8.0
QUICK_DURATION_S = 6.0  # both scenarios' quick runs: one duration, so one compiled loop per head
# The closed loop the scenarios' full runs are simulated on: the impact's duration (the longer);
# the jump's 8 s are its first 400 EKF ticks (:func:`loop_duration_s`).
FULL_LOOP_DURATION_S = 10.0
SIGMA_PROCESS_STACKED = (0.3, 1e-3, 0.03, 1e-3)  # blocks in P13's order: ω_S, R_IS, ω_H, R_IH
SIGMA_RELATIVE_PENDULUM_RAD = 0.02
U_BLOCKS = 4
SEED = 0
PLANT = gimbal_plant(P13_HEAD, (P13_PENDULUM,))
EKF_MODEL = (P13_EKF_PENDULUM, P13_EKF_HEAD)  # the filter's (pendulum, head) parameters, P13 §5


def true_initial_state(traj, condition: str) -> OtolithHeadState:
    """The plant's initial head and pendulum (:func:`simulation.initial_state` of ``PLANT``) as
    the filter's state (the medial model's :class:`OtolithHeadState`)."""
    plant = sim.with_condition(PLANT, condition)
    trunk = traj.motion(0.0)
    x0 = sim.initial_state(plant, trunk)
    head = trunk if plant.fixed else gimbal.head_motion(x0.gimbal, jnp.zeros(2), trunk)
    return OtolithHeadState(x0.pendula, state_from_motion(head))


def perturbed(x: OtolithHeadState) -> OtolithHeadState:
    """``x`` with both rotations turned by ``INITIAL_ERROR_RAD`` about the head's (1, 1, 0)/√2."""
    d = INITIAL_ERROR_RAD * jnp.array([1.0, 1.0, 0.0]) / jnp.sqrt(2.0)
    return OtolithHeadState(tuple(p._replace(R_I_S=p.R_I_S @ so3.exp(d)) for p in x.pendula),
                            x.head._replace(R_I_H=x.head.R_I_H @ so3.exp(d)))


def multiplicative_filter(sigma_process, accel_frame: str = "inertial",
                          sigma_measurement: float = SIGMA_MEASUREMENT,
                          model_params=EKF_MODEL) -> ekf.ExtendedKalmanFilter:
    """The multiplicative EKF of the ekf-* runs: :func:`ekf.medial_filter` with ``U_BLOCKS`` input
    blocks; ``accel_frame="head"``: its model is the :class:`HeadFrameAcceleration` adapter of the
    same medial model (F §4.2.1's ᴴa input)."""
    filt = ekf.medial_filter(*model_params, sigma_process, sigma_measurement, U_BLOCKS)
    if accel_frame == "head":  # F §4.2.1's u = (ᴴτ, ᴴa): the model rotates ᴴa with its own R̂_IH
        discrete = filt.model
        filt = dataclasses.replace(filt, model=dataclasses.replace(
            discrete, model=HeadFrameAcceleration(discrete.model)))
    return filt


def initial_covariance(x0: OtolithHeadState, kind: str = "common") -> jnp.ndarray:
    """P0 of the multiplicative EKF (error state δθ_S, δω_S, δθ_H, δω_H).

    ``"diagonal"``: σ0² I₁₂ (σ0 = 0.1 rad, P13 §5's initial error, every element independent).
    ``"common"``: the initial estimate's pendulum hangs at rest *relative to its head*, so the
    unknown is one common rotation e of both (δθ_S = R_SH δθ_H): cov(δθ_H) = σ0² I,
    cov(δθ_S, δθ_H) = σ0² R_SH, cov(δθ_S) = σ0² I + σ_rel² I (σ_rel = 0.02 rad, one otolith noise
    σ, the pendulum's own offset from its head); rates σ0² I as in ``"diagonal"``.
    """
    s2 = INITIAL_ERROR_RAD**2
    P = s2 * jnp.eye(ekf.N_ERR)
    if kind == "diagonal":
        return P
    if kind != "common":
        raise ValueError(f"p0 must be 'diagonal' or 'common', not {kind!r}")
    R_SH = x0.pendula[0].R_I_S.T @ x0.head.R_I_H
    P = P.at[0:3, 0:3].add(SIGMA_RELATIVE_PENDULUM_RAD**2 * jnp.eye(3))
    P = P.at[0:3, 6:9].set(s2 * R_SH).at[6:9, 0:3].set(s2 * R_SH.T)
    return P


class Setting(NamedTuple):
    """What may differ between runs that share one compiled simulator (:func:`run_settings` batches
    them under ``vmap``): the filter's process noise and the sensor noise."""

    # per step, the variant's blocks; None: the variant's default
    sigma_process: tuple | None = None
    sensor_noise_std: float = SIGMA_MEASUREMENT  # σ in the simulation and in the filter's R alike


class Tuned(NamedTuple):
    """An EKF state carrying its filter's Q and R and the reading's switches, so that they are
    traced values, not constants compiled into the simulator: the readings that differ only in
    them share one compiled closed loop."""

    ekf_state: ekf.EKFState
    Q: jnp.ndarray
    R: jnp.ndarray
    zero_torque: jnp.ndarray  # bool: the filter is told zero torque (the locked gimbal's reading)
    consider: jnp.ndarray  # bool: the model's parameter noise is added to Q (multiplicative EKF)


def _filter_for(variant: str, setting: Setting, accel_frame: str = "inertial",
                model_params=EKF_MODEL) -> ekf.ExtendedKalmanFilter:
    if variant == "multiplicative":
        sig = SIGMA_PROCESS if setting.sigma_process is None else setting.sigma_process
        return multiplicative_filter(sig, accel_frame, setting.sensor_noise_std, model_params)
    sig = SIGMA_PROCESS_STACKED if setting.sigma_process is None else setting.sigma_process
    return ekf_stacked.stacked_filter(*model_params, sig, setting.sensor_noise_std, U_BLOCKS)


_ESTIMATORS: dict = {}  # (variant, frame, id of the model parameters): (them, filter, estimator)


def closed_loop_estimator(variant: str, accel_frame: str = "inertial", model_params=EKF_MODEL):
    """The filter and the closed-loop adapter of a :class:`Tuned` state (Q, R and the switches
    are read from the state), built once per process for each (variant, acceleration frame,
    model), so that the compiled closed loop keyed on it
    (:class:`verticality.simulation.closed_loop.Loop`) serves every run that shares them."""
    key = (variant, accel_frame, id(model_params))
    kept = _ESTIMATORS.get(key)
    if kept is not None and kept[0] is model_params:
        return kept[1], kept[2]
    filt, est = _estimator(variant, accel_frame, model_params)
    _ESTIMATORS[key] = (model_params, filt, est)
    return filt, est


def _estimator(variant: str, accel_frame: str, model_params):
    filt = _filter_for(variant, Setting(), accel_frame, model_params)  # its model; Q, R replaced
    if variant == "multiplicative":
        R_of = lambda s: ekf.head_orientation(s.ekf_state.x)  # noqa: E731
    else:
        R_of = lambda s: ekf_stacked.head_orientation(s.ekf_state.x)  # noqa: E731
    # the continuous model value (or its adapter) whose parameter noise the switch adds
    model = filt.model.model if variant == "multiplicative" else None

    def step(state: Tuned, u, y, dt):
        u = u._replace(tau_H_Nm=jnp.where(state.zero_torque, 0.0, u.tau_H_Nm))
        Q = state.Q
        if model is not None:  # the model's parameter uncertainty, linearized into Q at the prior
            x = state.ekf_state.x
            head_model = model
            u_I = u
            if isinstance(model, HeadFrameAcceleration):
                head_model = model.model
                u_I = inertial_blocks(x, u)
            Q = Q + jnp.where(state.consider,
                              parameter_noise.medial_parameter_noise(head_model, x, u_I, dt), 0.0)
        inner, out = ekf.with_noise(filt, Q, state.R).step(state.ekf_state, u, y, dt)
        return state._replace(ekf_state=inner), out

    return filt, sim.Estimator(step=step, R_I_H=R_of)


def inertial_blocks(x: OtolithHeadState, u: HeadFrameInput) -> HeadInput:
    """Head-frame input blocks (leading axis) in frame I with the estimate's R̂_IH: ᴵa = R̂_IH ᴴa
    (:meth:`HeadFrameAcceleration.inertial_input` of each block). Written on the blocks' (a, τ)
    rows, one matrix product for all, as the ekf-* numbers were computed: another arrangement of
    the same product rounds differently inside the compiled closed loop (1e-15)."""
    rows = jnp.concatenate([u.a_H_m_s2, u.tau_H_Nm], -1)
    rows = rows.at[:, :3].set(rows[:, :3] @ x.head.R_I_H.T)
    return HeadInput(rows[:, 3:], rows[:, :3])


def _sensor_noise(std: float) -> sim.NoiseParams:
    return sim.NoiseParams(otolith_std_rad=std,
                           gyro=sim.DEFAULT_NOISE.gyro._replace(noise_std_rad_s=std))


def loop_duration_s(quick: bool) -> float:
    """The duration the ekf-* scenarios' runs are simulated for (``loop_duration_s`` of
    :func:`simulate_runs`): one for both scenarios, so that the jump's runs reuse the closed loops
    compiled for the impact's (a loop compiles once per duration; the closed loop is causal, so the
    first ticks of a longer run are the shorter run's, and only those are scored)."""
    return QUICK_DURATION_S if quick else FULL_LOOP_DURATION_S


def simulate_runs(traj, condition: str, settings, seeds, variant: str = "multiplicative",
                  torque_input: str = "gimbal", accel_frame: str = "inertial", p0: str = "common",
                  consider_noise: bool = True, *, model_params=EKF_MODEL,
                  t_settle_s: float = T_SETTLE_S, loop_duration_s: float | None = None):
    """The closed loop of the ekf-* runs for a batch of runs, one :class:`Setting` and one noise
    seed each (``settings`` and ``seeds`` of equal length): one compiled simulator, all runs in one
    ``vmap`` batch. Returns the batch's :class:`simulation.SimResult` and its per-run
    :func:`simulation.tilt_metrics` (arrays with a leading run axis).

    ``loop_duration_s`` (default the trajectory's duration): simulate this long, at least the
    trajectory's duration, on a trajectory defined that long, and keep the record of the
    trajectory's duration only (its final states are the loop's): runs of shorter trajectories
    then share the compiled loop of a longer one (:func:`loop_duration_s`)."""
    settings = [Setting(*s) for s in settings]
    seeds = list(seeds)
    if not settings or len(settings) != len(seeds):
        raise ValueError("simulate_runs needs one setting per seed, at least one "
                         f"(got {len(settings)} settings, {len(seeds)} seeds)")
    loop_s = traj.duration_s if loop_duration_s is None else float(loop_duration_s)
    if loop_s < traj.duration_s:
        raise ValueError(f"loop_duration_s {loop_s} is shorter than the trajectory's "
                         f"{traj.duration_s} s")
    for s in settings:
        if not s.sensor_noise_std > 0.0:
            raise ValueError("sensor_noise_std must be > 0 (it is also the filter's R), not "
                             f"{s.sensor_noise_std!r}")
    filt, est = closed_loop_estimator(variant, accel_frame, model_params)
    cfg = sim.SimConfig(duration_s=loop_s, condition=condition, u_blocks=U_BLOCKS,
                        accel_frame=accel_frame)
    controller = sim.p13_controller() if condition == "stabilized" else None
    run = sim.make_simulator(traj, cfg, est, controller)
    x0 = perturbed(true_initial_state(traj, condition))
    if variant == "multiplicative":
        s0 = filt.init(x0, initial_covariance(x0, p0))
    else:
        s0 = filt.init(ekf_stacked.to_flat(x0), ekf_stacked.init_covariance(INITIAL_ERROR_RAD))
    n = len(seeds)
    distinct = list(dict.fromkeys(settings))  # each distinct setting's filter built once
    filters = {s: _filter_for(variant, s, accel_frame, model_params) for s in distinct}

    def per_run(values):  # one value per run -> a leading axis of n
        return jnp.stack([jnp.asarray(v, dtype=jnp.float64) for v in values])

    states0 = Tuned(jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n,) + a.shape), s0),
                    per_run([filters[s].Q for s in settings]),
                    per_run([filters[s].R for s in settings]),
                    jnp.full(n, condition == "fixed" and torque_input == "gimbal"),
                    jnp.full(n, variant == "multiplicative" and consider_noise))
    noise = jax.tree_util.tree_map(lambda *v: per_run(v),
                                   *[_sensor_noise(s.sensor_noise_std) for s in settings])
    keys = jnp.stack([jax.random.PRNGKey(seed) for seed in seeds])
    res = sim.simulate_batch(run, keys, PLANT, noise, states0, batched_estimator=True,
                             batched_noise=True)
    if loop_s != traj.duration_s:  # the trajectory's ticks (runs, ticks, ...)
        ticks = sim.make_loop(cfg._replace(duration_s=traj.duration_s), est, controller).estimates
        res = res._replace(record=jax.tree_util.tree_map(lambda a: a[:, :ticks], res.record))
    per = jax.vmap(lambda r: sim.tilt_metrics(r, t_settle_s))(res.record)
    return res, per


def run_settings(traj, condition: str, settings, variant: str = "multiplicative",
                 torque_input: str = "gimbal", seeds=(SEED,), accel_frame: str = "inertial",
                 p0: str = "common", consider_noise: bool = True, *, model_params=EKF_MODEL,
                 t_settle_s: float = T_SETTLE_S,
                 loop_duration_s: float | None = None) -> list[tuple[dict, dict]]:
    """:func:`run_condition` for several :class:`Setting` s at once: all settings × seeds in one
    :func:`simulate_runs` batch (each seed's noise is the same in every setting).
    Returns ``(metrics, series)`` per setting, in order."""
    settings = [Setting(*s) for s in settings]
    if not settings:
        raise ValueError("run_settings needs at least one setting")
    n_set, n_seed = len(settings), len(seeds)
    res, per = simulate_runs(traj, condition, [s for s in settings for _ in seeds],
                             [seed for _ in settings for seed in seeds], variant, torque_input,
                             accel_frame, p0, consider_noise, model_params=model_params,
                             t_settle_s=t_settle_s, loop_duration_s=loop_duration_s)
    mx_all = np.asarray(per["max_tilt_error_deg"]).reshape(n_set, n_seed)
    rms_all = np.asarray(per["rms_tilt_error_deg"]).reshape(n_set, n_seed)
    out = []
    for i in range(n_set):
        mx_seed, rms_seed = mx_all[i], rms_all[i]
        metrics = {"max_tilt_error_deg": float(mx_seed.max()),
                   "rms_tilt_error_deg": float(np.sqrt(np.mean(rms_seed**2))),
                   "max_tilt_error_deg_per_seed": mx_seed.tolist(),
                   "rms_tilt_error_deg_per_seed": rms_seed.tolist()}
        rec = jax.tree_util.tree_map(lambda a, j=i * n_seed: a[j], res.record)  # first seed
        metrics["rejected_updates"] = int(np.sum(np.asarray(rec.estimator_out.rejected)))
        R_est = np.asarray(rec.R_I_H_est)
        metrics["orthonormality_error_max"] = float(
            np.max(np.asarray(so3.orthonormality_error(R_est))))
        series = {
            "t_s": np.asarray(rec.t_s),
            "tilt_true_deg": np.degrees(np.asarray(so3.tilt_angles(rec.R_I_H))),
            "tilt_est_deg": np.degrees(np.asarray(so3.tilt_angles(rec.R_I_H_est))),
            "tilt_error_deg": np.asarray(rec.tilt_error_deg),
            "a_I_m_s2": np.asarray(rec.u[1].mean(axis=1)),  # the input's acceleration
        }
        out.append((metrics, series))
    return out


def run_condition(traj, condition: str, variant: str = "multiplicative",
                  torque_input: str = "gimbal", sigma_process=None, seeds=(SEED,),
                  accel_frame: str = "inertial", p0: str = "common", consider_noise: bool = True,
                  *, sensor_noise_std: float = SIGMA_MEASUREMENT, model_params=EKF_MODEL,
                  t_settle_s: float = T_SETTLE_S, loop_duration_s: float | None = None):
    """Closed-loop runs (one per seed, vmapped); returns the metrics and the first seed's series.

    ``sensor_noise_std``: σ of the white noise on the two inclinometer angles and the three gyro
    rates, in the simulation and in the filter's R alike (P13 §5: 0.02). ``model_params``: the
    (pendulum, head) parameters of the filter's model (default P13's wrong ones; ``(P13_PENDULUM,
    P13_HEAD)`` is the exact model). The metrics cover t ≥ ``t_settle_s``.

    Metrics: ``max``/``rms`` tilt error over the seeds (max of maxima, rms over all samples), plus
    ``*_per_seed`` lists. ``loop_duration_s``: as in :func:`simulate_runs`."""
    return run_settings(traj, condition, [Setting(sigma_process, sensor_noise_std)], variant,
                        torque_input, seeds, accel_frame, p0, consider_noise,
                        model_params=model_params, t_settle_s=t_settle_s,
                        loop_duration_s=loop_duration_s)[0]




# The trunk motion's amplitude and time-scale parameters of each scenario's trajectory function
# (:func:`scenario_trajectory`'s ``amplitude_scale`` multiplies the first, ``frequency_scale``
# multiplies the frequencies and divides the durations).
SCALED_PARAMETERS = {
    "impact": {"amplitude": ("translation_amplitude_m", "rotation_amplitude_rad"),
               "frequency": ("translation_frequency_hz", "rotation_frequency_hz"), "duration": ()},
    "jump": {"amplitude": ("jump_length_m", "pitch_rad", "roll_rad"), "frequency": (),
             "duration": ("push_sigma_s", "flight_s", "edge_sigma_s")},
}


def scenario_trajectory(scenario: str, quick: bool = False, *, amplitude_scale: float = 1.0,
                        frequency_scale: float = 1.0, **overrides):
    """The trunk trajectory of ``ekf-impact`` (``scenario="impact"``) or ``ekf-jump`` (``"jump"``),
    with the settings above; ``quick``: their quick duration, 6 s (the impact at 5 s and the
    stop after it included; the jump's whole motion), one for both so that their quick runs
    share compiled closed loops. ``overrides`` go to the trajectory function (e.g. ``pitch_rad``).

    ``amplitude_scale`` and ``frequency_scale`` scale the trunk's motion through the trajectory's
    parameters (:data:`SCALED_PARAMETERS`). Impact: the oscillation's translation and rotation
    amplitudes, and its frequencies; the ramp-in, the impact's time, its 30 m/s² spike and the stop
    are kept. Jump: its length, pitch and roll, and its time scale (push width, flight time, the
    free fall's edges divided by ``frequency_scale``: a faster jump is a shorter, lower one, g
    being g); the push time and the landing's 30 m/s² peak are kept."""
    if scenario == "impact":
        kw = {"ramp_in_s": IMPACT_RAMP_IN_S,
              **({"duration_s": QUICK_DURATION_S} if quick else {})}
        fn = trajectories.impact
    elif scenario == "jump":
        kw = {"duration_s": QUICK_DURATION_S if quick else JUMP_DURATION_S,
              "t_push_s": JUMP_T_PUSH_S}
        fn = trajectories.jump
    else:
        raise ValueError(f"scenario must be 'impact' or 'jump', not {scenario!r}")
    kw = {**kw, **overrides}
    if amplitude_scale != 1.0 or frequency_scale != 1.0:
        defaults = {k: v.default for k, v in inspect.signature(fn).parameters.items()}
        names = SCALED_PARAMETERS[scenario]
        for key, factor in (("amplitude", amplitude_scale), ("frequency", frequency_scale),
                            ("duration", 1.0 / frequency_scale)):
            for name in names[key]:
                v = kw.get(name, defaults[name])
                kw[name] = tuple(factor * x for x in v) if isinstance(v, tuple) else factor * v
    return fn(**kw)


