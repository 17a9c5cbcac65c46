"""`platform` — F ch. 5: simulated copy of the gimbal platform, inclinometer-fed vs observer-fed PD.

Each gimbal axis is its identified model (F §5.2; :class:`verticality.models.platform.PlatformAxis`): pitch
J1 = 0.008, b1 = 1.35; roll J2 = 0.0006, b2 = 0.137 (``J θ̈ + b (θ̇ − θ̇_base) = u``), with the
identified inclinometer ``J_s ÿ + b_s ẏ + k_s y = k_s ψ`` (J_s = 0.0015, b_s = 0.3776, k_s = 5.629),
ψ = θ + atan2(a_h, g). The axes are decoupled (F §5.1.1) and simulated side by side (``vmap``).
The controller runs every 3 ms (F §5.1.4) with the command held; the plant is integrated by RK4 at
1 ms. Two feeds of a PD ``u = k_p (0 − θ̃) − k_d ω̃`` that keeps the platform horizontal:

- ``sensor_feedback``: θ̃ the inclinometer reading, ω̃ its backward difference over 3 ms (F §5.2);
- ``observer_feedback``: θ̃, ω̃ from :mod:`verticality.estimators.luenberger` on the same model value
  linearized at upright by autodiff (states θ, ω, y, ẏ; inputs u and a_h; output y).

Readings the thesis leaves open, fixed here:
- Scenario: phase 1 (``SWING_S``): the base link is swung by hand, modelled as a smooth sine of
  45° (pitch, 0.4 Hz) and 40° (roll, 0.5 Hz) amplitude, ramped in over 1 s; phase 2: base still,
  the platform centre accelerated with a(t) = 2 sin(2π·0.8 t) m/s² (pitch) and 2 cos(2π·1.1 t)
  m/s² (roll), ramped in over 1 s.
- The base motion enters the platform only through the joint damping (motor back-EMF and friction
  act on the joint velocity); it is unknown to the observer, which knows u and the linear
  acceleration a_h (an ideal linear-acceleration input, as in F §4.4's simulations: an accelerometer
  on the platform measures the same gravito-inertial combination θ + a/g as the inclinometer, so it
  cannot be used to separate them without the tilt it is meant to help estimate).
- PD gains (not printed in F): pitch k_p = 300, k_d = 1.0; roll k_p = 40, k_d = 0.05 (state-fed
  closed loops well damped, crossover above the inclinometer's slow pole at 15.9 rad/s).
- Observer poles −150, −170, −190, −210 s⁻¹ for both axes (≈ 10× the inclinometer's slow pole;
  with −60…−90 the observer-fed platform stays stable but oscillates up to 0.25 rad).
- Amplifier limit |u| ≤ 50 (pitch), 5 (roll), which only the unstable loop ever reaches.
- Reading noise σ = 1e-3 rad (ADC) on the inclinometer, the same in both feeds.
- **Unstable**: |θ| exceeds 1 rad (the workspace) or is non-finite, or the tilt envelope grows
  (max over the last quarter > 2 × max over the second quarter of a phase, and > 0.05 rad), in
  either axis. ``max_platform_tilt_rad`` is max |θ| over both axes, both phases, t ≥ 1 s.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.estimators import luenberger as lu
from verticality.estimators.kalman import ContinuousObserver
from verticality.experiments import Result, check, register
from verticality.integrate import rk4_step
from verticality.models import platform as pf
from verticality.models.linearize import linearize, select_inputs

LOOP_DT_S = 3e-3
SUBSTEPS = 3
AXES = {"pitch": pf.PITCH, "roll": pf.ROLL}
GAINS = {"pitch": (300.0, 1.0), "roll": (40.0, 0.05)}
U_MAX = {"pitch": 50.0, "roll": 5.0}
BASE_AMP_RAD = {"pitch": np.deg2rad(45.0), "roll": np.deg2rad(40.0)}
BASE_FREQ_HZ = {"pitch": 0.4, "roll": 0.5}
ACC_AMP_M_S2 = 2.0
ACC_FREQ_HZ = {"pitch": 0.8, "roll": 1.1}
ACC_PHASE = {"pitch": 0.0, "roll": np.pi / 2}
OBSERVER_POLES = (-150.0, -170.0, -190.0, -210.0)
SIGMA_Y_RAD = 1e-3
SETTLE_S = 1.0


def observer_for(axis: pf.PlatformAxis) -> ContinuousObserver:
    """Luenberger observer on the axis model linearized at upright (F 4.10), with the inputs it
    knows: the command u and the acceleration a_h (not the base's rate)."""
    z = jnp.asarray(0.0)
    lin = linearize(axis, pf.AxisState(z, z, z, z), pf.AxisInput(z, z, z))
    return lu.design(select_inputs(lin, [0, 1]), OBSERVER_POLES)


class AxisCfg(NamedTuple):
    p: pf.PlatformAxis
    kp: jnp.ndarray
    kd: jnp.ndarray
    u_max: jnp.ndarray
    base_amp: jnp.ndarray
    base_w: jnp.ndarray
    acc_w: jnp.ndarray
    acc_phase: jnp.ndarray
    obs: ContinuousObserver
    use_observer: jnp.ndarray  # 0.0 sensor, 1.0 observer
    key: jnp.ndarray


def _ramp(t, t0):
    return jnp.clip(t - t0, 0.0, 1.0)


def _drive(cfg: AxisCfg, t, swing_s):
    """Base angular velocity and platform linear acceleration at time t (the two phases)."""
    in_swing = t < swing_s
    r = _ramp(t, 0.0)
    omega_base = jnp.where(in_swing, r * cfg.base_amp * cfg.base_w * jnp.cos(cfg.base_w * t)
                           + (t < 1.0) * cfg.base_amp * jnp.sin(cfg.base_w * t), 0.0)
    a = jnp.where(in_swing, 0.0,
                  _ramp(t, swing_s) * ACC_AMP_M_S2 * jnp.sin(cfg.acc_w * (t - swing_s) + cfg.acc_phase))
    return omega_base, a


def _simulate(cfg: AxisCfg, n_loops: int, swing_s: float):
    h = LOOP_DT_S / SUBSTEPS
    noise = jax.random.normal(cfg.key, (n_loops,)) * SIGMA_Y_RAD

    def f_plant(t, x, u):
        omega_base, a = _drive(cfg, t, swing_s)
        return cfg.p.dynamics(x, pf.AxisInput(u, a, omega_base))

    def body(carry, k):
        x, base, ls, y_prev = carry
        t = k * LOOP_DT_S
        y = x.y_rad + noise[k]
        _, a_now = _drive(cfg, t, swing_s)
        rate = jnp.where(k > 0, (y - y_prev) / LOOP_DT_S, 0.0)
        th = jnp.where(cfg.use_observer > 0, ls.x[0], y)
        om = jnp.where(cfg.use_observer > 0, ls.x[1], rate)
        u = jnp.clip(-cfg.kp * th - cfg.kd * om, -cfg.u_max, cfg.u_max)
        ls_new, _ = cfg.obs.step(ls, jnp.array([u, a_now]), jnp.atleast_1d(y), LOOP_DT_S)

        def sub(i, xb):
            xx, bb = xb
            ts = t + i * h
            om_b, _ = _drive(cfg, ts, swing_s)
            return rk4_step(f_plant, ts, xx, h, u), bb + h * om_b

        x_new, base_new = jax.lax.fori_loop(0, SUBSTEPS, sub, (x, base))
        out = (x.theta_rad, y, ls.x[0], base, u, a_now)
        return (x_new, base_new, ls_new, y), out

    z = jnp.asarray(0.0)
    carry0 = (pf.AxisState(z, z, z, z), 0.0, cfg.obs.init(jnp.zeros(4)), 0.0)
    _, outs = jax.lax.scan(body, carry0, jnp.arange(n_loops))
    return outs


_simulate_batch = jax.jit(jax.vmap(_simulate, in_axes=(0, None, None)), static_argnums=(1, 2))


def _configs():
    rows, cfgs = [], []
    keys = jax.random.split(jax.random.PRNGKey(5), 4)
    i = 0
    for feed, use in (("sensor_feedback", 0.0), ("observer_feedback", 1.0)):
        for axis, p in AXES.items():
            kp, kd = GAINS[axis]
            cfgs.append(AxisCfg(p, jnp.asarray(kp), jnp.asarray(kd), jnp.asarray(U_MAX[axis]),
                                jnp.asarray(BASE_AMP_RAD[axis]),
                                jnp.asarray(2 * np.pi * BASE_FREQ_HZ[axis]),
                                jnp.asarray(2 * np.pi * ACC_FREQ_HZ[axis]),
                                jnp.asarray(ACC_PHASE[axis]), observer_for(p), jnp.asarray(use),
                                keys[i]))
            rows.append((feed, axis))
            i += 1
    cfg = jax.tree_util.tree_map(lambda *a: jnp.stack([jnp.asarray(v) for v in a]), *cfgs)
    return rows, cfg


def _grows(x):
    n = x.size
    q2 = np.abs(x[n // 4: n // 2]).max()
    q4 = np.abs(x[3 * n // 4:]).max()
    return bool(q4 > 0.05 and q4 > 2.0 * q2)


def is_unstable(t, theta, swing_s):
    """The documented instability criterion (module docstring)."""
    theta = np.asarray(theta)
    if not np.all(np.isfinite(theta)):
        return True
    if np.abs(theta[t >= SETTLE_S]).max() > 1.0:
        return True
    return _grows(theta[t < swing_s]) or _grows(theta[t >= swing_s])


@register("platform", "Gimbal platform: inclinometer-fed vs observer-fed PD (F ch. 5)",
          source="F §5.2, Fig. 5.7–5.9", figures=lambda r, d: figures(r, d))
def run(quick: bool = False) -> Result:
    swing_s, accel_s = (5.0, 5.0) if quick else (15.0, 15.0)
    duration = swing_s + accel_s
    n = int(round(duration / LOOP_DT_S))
    rows, cfg = _configs()
    th, y, th_hat, base, u, a = (np.asarray(v) for v in _simulate_batch(cfg, n, swing_s))
    t = np.arange(n) * LOOP_DT_S
    unstable: dict = {"sensor_feedback": False, "observer_feedback": False}
    by_axis: dict = {}
    max_tilt: dict = {}
    series: dict = {"t": t[::3], "swing_s": swing_s}
    for i, (feed, axis) in enumerate(rows):
        uns = is_unstable(t, th[i], swing_s)
        unstable[feed] = unstable[feed] or uns
        by_axis.setdefault(feed, {})[axis] = uns
        m = np.abs(th[i][t >= SETTLE_S])
        max_tilt.setdefault(feed, {})[axis] = float(m.max()) if np.all(np.isfinite(m)) else float("nan")
        for name, arr in (("tilt", th[i]), ("reading", y[i]), ("estimate", th_hat[i]),
                          ("base", base[i]), ("u", u[i]), ("a", a[i])):
            series[f"{feed}/{axis}/{name}"] = arr[::3]
    obs_max = max(max_tilt["observer_feedback"].values())
    base_swing = {ax: float(np.abs(base[rows.index(("observer_feedback", ax))]).max()) for ax in AXES}
    est_err = {ax: float(np.abs(th_hat[i] - th[i])[t >= SETTLE_S].max())
               for i, (feed, ax) in enumerate(rows) if feed == "observer_feedback"}
    metrics = {
        "unstable": unstable,
        "max_platform_tilt_rad": {"observer_feedback": obs_max,
                                  "by_axis": max_tilt},
        "unstable_by_axis": by_axis,
        "base_swing_rad": base_swing,
        "max_estimation_error_rad": est_err,
        "checks": {
            "sensor_unstable": check(float(unstable["sensor_feedback"]), 0.0, unstable["sensor_feedback"]),
            "observer_stable": check(float(unstable["observer_feedback"]), 0.0,
                                     not unstable["observer_feedback"]),
            "observer_tilt_le_0.1": check(obs_max, 0.1, obs_max <= 0.1),
        },
    }
    paper = {"unstable": {"sensor_feedback": True, "observer_feedback": False},
             "max_platform_tilt_rad": {"observer_feedback": 0.1}}
    return Result(metrics=metrics, paper=paper, series=series, simulated_s=duration * len(rows))


def figures(result: Result, out_dir: Path) -> list[Path]:
    """F Fig. 5.7/5.8 (base swing) and 5.9 (translation): tilt, reading, estimate, base, command."""
    from verticality.plots import new_figure, published_line, save

    s = result.series
    t = s["t"]
    fig, axes = new_figure(3, 4, width=15)
    for j, (feed, axis) in enumerate([(f, a) for f in ("sensor_feedback", "observer_feedback")
                                      for a in AXES]):
        k = f"{feed}/{axis}"
        ax = axes[0, j]
        ax.plot(t, s[f"{k}/base"], color="0.6", lw=0.8, label="base link")
        ax.plot(t, s[f"{k}/reading"], lw=0.8, label="inclinometer")
        ax.plot(t, s[f"{k}/tilt"], label="platform tilt")
        if feed == "observer_feedback":
            ax.plot(t, s[f"{k}/estimate"], lw=0.8, ls="--", label="estimate")
        ax.axvline(s["swing_s"], color="k", lw=0.6, ls=":")
        ax.set_ylim(-1.5, 1.5)
        uns = result.metrics["unstable_by_axis"][feed][axis]
        ax.set_title(f"{axis}, {feed.replace('_', ' ')}: {'UNSTABLE' if uns else 'stable'}", fontsize=9)
        ax.set_ylabel("rad")
        ax = axes[1, j]
        ax.plot(t, np.abs(s[f"{k}/tilt"]), color="C1", lw=0.8, label="|platform tilt|")
        published_line(ax, 0.1, label="F: < 0.1 rad (observer)")
        ax.set_ylim(0, 0.5)
        ax.set_ylabel("|tilt| rad")
        ax = axes[2, j]
        ax.plot(t, s[f"{k}/u"], lw=0.7, label="command u")
        ax2 = ax.twinx()
        ax2.plot(t, s[f"{k}/a"], color="C2", lw=0.7, label="a [m/s²]")
        ax2.set_ylim(-3, 3)
        ax.set_ylabel("motor torque u [N·m]")
        ax2.set_ylabel("base acceleration a [m/s²]")
        ax.set_xlabel("t [s]  (base swing | translation)")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    axes[1, 0].legend(fontsize=7)
    return [save(fig, out_dir / "fig5_7_5_9_platform.png")]
