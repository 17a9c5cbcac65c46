"""The sweeps behind `ekf-sensitivity`: what the EKF's stabilization benefit in `ekf-impact` and
`ekf-jump` depends on.

The ekf-* experiments score the ratio of the stabilized head's RMS tilt error (after 2 s) to the
fixed head's (the jump's check asks ≤ 1/2, the impact's ≤ 1/3). Three one-at-a-time sweeps around
their setting (same plant, filter, seeds and trajectories as :mod:`verticality.simulation.ekf_runs`;
one value changed at a time):

1. **The fixed head's head-rate process noise** σ_ωH (rad/s per 20 ms EKF step), impact and jump.
   In the fixed condition the gimbal is locked and the filter's free-head model receives no torque:
   the trunk's torque on the head is unknown. σ_ωH is how much angular acceleration the filter
   admits it does not model (σ_ωH/Δt = 0.015 … 5 rad/s² over the sweep). The ekf-* experiments use
   P13 §5's σ_w = 0.001 in both conditions; the stabilized head's filter (whose torque is known) is
   the same in every row.
2. **The trunk's pitch during the jump** (rad; ekf-jump: 0.2). P13 gives the jump's translation
   only; the trunk's rotation is this project's choice
   (:func:`verticality.simulation.trajectories.jump`).
3. **Sensor noise** σ on the two inclinometer angles (rad) and the three gyro rates (rad/s), in
   the simulation and in the filter's R alike (P13 §5: 0.02), jump.

Metrics per row: ``fixed_max_deg``, ``fixed_rms_deg``, ``stabilized_max_deg``,
``stabilized_rms_deg``, ``rms_ratio`` (stabilized / fixed). No pass/fail check: this is the
analysis behind the ekf-* numbers (docs/ekf.md), not a published figure.
"""

from __future__ import annotations

import inspect

from verticality.simulation import ekf_runs, trajectories

HEAD_RATE_SIGMAS = (3e-4, 1e-3, 3e-3, 1e-2, 3e-2)
HEAD_RATE_SIGMAS_QUICK = (1e-3, 3e-2)
JUMP_PITCHES_RAD = (0.1, 0.2, 0.3, 0.4)
SENSOR_NOISE_STDS = (0.005, 0.01, 0.02)
P13_SIGMA_W = ekf_runs.SIGMA_PROCESS[3]
# ekf-jump's trunk pitch (rad)
DEFAULT_PITCH_RAD = inspect.signature(trajectories.jump).parameters["pitch_rad"].default


def _row(fixed: dict, stabilized: dict) -> dict:
    return {"fixed_max_deg": fixed["max_tilt_error_deg"],
            "fixed_rms_deg": fixed["rms_tilt_error_deg"],
            "stabilized_max_deg": stabilized["max_tilt_error_deg"],
            "stabilized_rms_deg": stabilized["rms_tilt_error_deg"],
            "rms_ratio": stabilized["rms_tilt_error_deg"] / max(fixed["rms_tilt_error_deg"], 1e-12)}


def _plan(quick: bool) -> dict:
    """The sweeps' layout: ``{sweep: {scenario: {row label: (fixed run, stabilized run)}}}``, a
    run being ``(scenario, condition, σ_ωH, pitch, noise)``."""

    def runs(scenario, sigma_head_rate=P13_SIGMA_W, pitch=DEFAULT_PITCH_RAD,
             noise=ekf_runs.SIGMA_MEASUREMENT, stabilized_sigma=P13_SIGMA_W):
        return ((scenario, "fixed", sigma_head_rate, pitch, noise),
                (scenario, "stabilized", stabilized_sigma, pitch, noise))

    sigmas = HEAD_RATE_SIGMAS_QUICK if quick else HEAD_RATE_SIGMAS
    plan: dict = {"fixed_head_rate_sigma": {
        scenario: {f"sigma_{s:g}": runs(scenario, sigma_head_rate=s) for s in sigmas}
        for scenario in (("jump",) if quick else ("impact", "jump"))}}
    if not quick:
        plan["jump_pitch"] = {"jump": {f"pitch_{p:g}_rad": runs("jump", pitch=p)
                                       for p in JUMP_PITCHES_RAD}}
        plan["sensor_noise"] = {"jump": {f"noise_{n:g}": runs("jump", noise=n)
                                         for n in SENSOR_NOISE_STDS}}
    return plan


def run_sweeps(quick: bool = False, progress=None) -> tuple[dict, float]:
    """The three sweeps; returns ``({sweep: {scenario: {row key: row}}}, simulated seconds)``.

    Each distinct run is computed once (the ekf-* setting is shared between sweeps), its seeds in
    one ``vmap`` batch (:func:`verticality.simulation.ekf_runs.run_settings`). Batches of one
    condition, duration and size share one compiled closed loop (the trunk's motion, Q, R and the
    sensor noise are its data), so every run here reuses the closed loop `ekf-impact` or
    `ekf-jump` compiles for its own seeds. ``progress``: an optional callable given a short label
    before each group of runs of one scenario, condition and trunk pitch."""
    seeds = ekf_runs.SEEDS[:1] if quick else ekf_runs.SEEDS
    plan = _plan(quick)
    groups: dict = {}  # (scenario, condition, pitch) -> distinct runs, in plan order
    for table in plan.values():
        for rows in table.values():
            for pair in rows.values():
                for run in pair:
                    group = groups.setdefault((run[0], run[1], run[3]), [])
                    if run not in group:
                        group.append(run)
    metrics: dict = {}
    simulated_s = 0.0
    for (scenario, condition, pitch), runs in groups.items():
        if progress is not None:
            progress(f"{scenario} {condition} pitch={pitch:g}: {len(runs)} setting(s)")
        traj = ekf_runs.scenario_trajectory(
            scenario, quick, **({"pitch_rad": pitch} if scenario == "jump" else {}))
        for run in runs:
            _, _, sigma, _, noise = run
            setting = ekf_runs.Setting(ekf_runs.SIGMA_PROCESS[:3] + (sigma,), noise)
            metrics[run] = ekf_runs.run_settings(
                traj, condition, [setting], seeds=seeds,
                loop_duration_s=ekf_runs.loop_duration_s(quick))[0][0]
        simulated_s += traj.duration_s * len(seeds) * len(runs)
    out = {sweep: {scenario: {label: _row(metrics[fixed], metrics[stab])
                              for label, (fixed, stab) in rows.items()}
                   for scenario, rows in table.items()}
           for sweep, table in plan.items()}
    return out, simulated_s
