"""`platform` — F ch. 5: simulated copy of the gimbal platform, inclinometer-fed vs observer-fed PD.

Each gimbal axis is its identified model (F §5.2;
:class:`verticality.models.platform.PlatformAxis`): pitch J1 = 0.008, b1 = 1.35; roll J2 = 0.0006,
b2 = 0.137 (``J θ̈ + b (θ̇ − θ̇_base) = u``), with the identified inclinometer
``J_s ÿ + b_s ẏ + k_s y = k_s ψ`` (J_s = 0.0015, b_s = 0.3776, k_s = 5.629), ψ = θ + atan2(a_h, g).
The axes are decoupled (F §5.1.1) and simulated side by side (``vmap``). The controller runs
every 3 ms (F §5.1.4) with the command held; the plant is integrated by RK4 at 1 ms. Two feeds
of a PD ``u = k_p (0 − θ̃) − k_d ω̃`` that keeps the platform horizontal:

- ``sensor_feedback``: θ̃ the inclinometer reading, ω̃ its backward difference over 3 ms (F §5.2);
- ``observer_feedback``: θ̃, ω̃ from :mod:`verticality.estimators.luenberger` on the same model value
  linearized at upright by autodiff (states θ, ω, y, ẏ; inputs u and a_h; output y), fed the true
  acceleration a_h (ours: the ideal input);
- ``accelerometer_fed`` (F §5.2's own setting: "reference inputs to the motor amplifiers and
  accelerometer measurements were used as known inputs for the observer"): the same observer fed
  the platform accelerometer's reading instead (:func:`accelerometer_reading`, the project's
  accelerometer model: the specific force along the platform's axis, ``a_h cos θ + g sin θ``, plus
  white noise σ = 0.02 m/s², our reading; F gives none). Its tilt term is what F means by "the
  accelerometer measurements were less influenced by the head's actual tilt when head was close to
  be horizontal": the observer's model reads it as acceleration, so the estimate loses ``g sin θ``.

Readings the thesis leaves open, fixed here:
- Scenario: phase 1 (``SWING_S``): the base link is swung by hand, modelled as a smooth sine of
  45° (pitch, 0.4 Hz) and 40° (roll, 0.5 Hz) amplitude, ramped in over 1 s; phase 2: base still,
  the platform centre accelerated with a(t) = 2 sin(2π·0.8 t) m/s² (pitch) and 2 cos(2π·1.1 t)
  m/s² (roll), ramped in over 1 s.
- The base motion enters the platform only through the joint damping (motor back-EMF and friction
  act on the joint velocity); it is unknown to the observer, which knows u and the linear
  acceleration a_h: ideal in ``observer_feedback`` (as in F §4.4's simulations), measured in
  ``accelerometer_fed`` (an accelerometer on the platform measures the same gravito-inertial
  combination as the inclinometer, so it separates them only while the platform stays near level).
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

import jax
import jax.numpy as jnp
import numpy as np

from verticality.experiments import Result, check, register
from verticality.models import platform as pf
from verticality.simulation.platform_loop import (
    LOOP_DT_S,
    AxisCfg,
    observer_for,
    simulate_batch,
)

AXES = {"pitch": pf.PITCH, "roll": pf.ROLL}
GAINS = {"pitch": (300.0, 1.0), "roll": (40.0, 0.05)}
U_MAX = {"pitch": 50.0, "roll": 5.0}
BASE_AMP_RAD = {"pitch": np.deg2rad(45.0), "roll": np.deg2rad(40.0)}
BASE_FREQ_HZ = {"pitch": 0.4, "roll": 0.5}
ACC_FREQ_HZ = {"pitch": 0.8, "roll": 1.1}
ACC_PHASE = {"pitch": 0.0, "roll": np.pi / 2}
SETTLE_S = 1.0


FEEDS = ("sensor_feedback", "observer_feedback", "accelerometer_fed")


def _configs():
    rows, cfgs = [], []
    keys = jnp.concatenate([jax.random.split(jax.random.PRNGKey(5), 4),
                            jax.random.split(jax.random.PRNGKey(6), 2)])
    i = 0
    for feed in FEEDS:
        use = 0.0 if feed == "sensor_feedback" else 1.0
        for axis, p in AXES.items():
            kp, kd = GAINS[axis]
            cfgs.append(AxisCfg(p, jnp.asarray(kp), jnp.asarray(kd), jnp.asarray(U_MAX[axis]),
                                jnp.asarray(BASE_AMP_RAD[axis]),
                                jnp.asarray(2 * np.pi * BASE_FREQ_HZ[axis]),
                                jnp.asarray(2 * np.pi * ACC_FREQ_HZ[axis]),
                                jnp.asarray(ACC_PHASE[axis]), observer_for(p), jnp.asarray(use),
                                keys[i], jnp.asarray(float(feed == "accelerometer_fed"))))
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
    th, y, th_hat, base, u, a, a_acc = (np.asarray(v) for v in simulate_batch(cfg, n, swing_s))
    t = np.arange(n) * LOOP_DT_S
    unstable: dict = dict.fromkeys(FEEDS, False)
    by_axis: dict = {}
    max_tilt: dict = {}
    series: dict = {"t": t[::3], "swing_s": swing_s}
    swing, transl = (t >= SETTLE_S) & (t < swing_s), t >= swing_s + SETTLE_S
    reading_deg: dict = {}
    transl_tilt: dict = {}
    for i, (feed, axis) in enumerate(rows):
        uns = is_unstable(t, th[i], swing_s)
        unstable[feed] = unstable[feed] or uns
        by_axis.setdefault(feed, {})[axis] = uns
        m = np.abs(th[i][t >= SETTLE_S])
        max_tilt.setdefault(feed, {})[axis] = (float(m.max()) if np.all(np.isfinite(m))
                                               else float("nan"))
        reading_deg.setdefault(feed, {})[axis] = float(np.degrees(np.abs(y[i][swing]).max()))
        transl_tilt.setdefault(feed, {})[axis] = float(np.abs(th[i][transl]).max())
        for name, arr in (("tilt", th[i]), ("reading", y[i]), ("estimate", th_hat[i]),
                          ("base", base[i]), ("u", u[i]), ("a", a[i]), ("a_acc", a_acc[i])):
            series[f"{feed}/{axis}/{name}"] = arr[::3]
    obs_max = max(max_tilt["observer_feedback"].values())
    acc_max = max(max_tilt["accelerometer_fed"].values())
    base_swing = {ax: float(np.abs(base[rows.index(("observer_feedback", ax))]).max())
                  for ax in AXES}

    def est_err(feed):
        return {ax: float(np.abs(th_hat[i] - th[i])[t >= SETTLE_S].max())
                for i, (f, ax) in enumerate(rows) if f == feed}

    acc_err = {ax: float(np.sqrt(np.mean((a_acc[i] - a[i])[transl] ** 2)))
               for i, (f, ax) in enumerate(rows) if f == "accelerometer_fed"}
    # F Fig. 5.9 is its own test (the platform translated, the base still): the same loops from
    # rest under the translation alone
    n_t = int(round(accel_s / LOOP_DT_S))
    th_t = np.asarray(simulate_batch(cfg, n_t, 0.0)[0])
    t_t = np.arange(n_t) * LOOP_DT_S
    transl_only: dict = {}
    for i, (feed, axis) in enumerate(rows):
        m = np.abs(th_t[i][t_t >= SETTLE_S])
        transl_only.setdefault(feed, {})[axis] = (float(m.max()) if np.all(np.isfinite(m))
                                                  else None)
    metrics = {
        "unstable": {k: unstable[k] for k in ("sensor_feedback", "observer_feedback")},
        "max_platform_tilt_rad": {"observer_feedback": obs_max,
                                  "by_axis": {k: max_tilt[k] for k in ("sensor_feedback",
                                                                       "observer_feedback")}},
        "unstable_by_axis": {k: by_axis[k] for k in ("sensor_feedback", "observer_feedback")},
        "base_swing_rad": base_swing,
        "max_estimation_error_rad": est_err("observer_feedback"),
        "accelerometer_fed": {
            "unstable": unstable["accelerometer_fed"],
            "unstable_by_axis": by_axis["accelerometer_fed"],
            "max_platform_tilt_rad": acc_max,
            "max_platform_tilt_rad_by_axis": max_tilt["accelerometer_fed"],
            "max_estimation_error_rad": est_err("accelerometer_fed"),
            "rms_accelerometer_minus_acceleration_m_s2": acc_err,
        },
        "fig_5_8": {"max_inclinometer_reading_deg": {
            k: max(reading_deg[k].values()) for k in ("observer_feedback", "accelerometer_fed")}},
        "fig_5_9": {"max_tilt_translation_rad": {k: max(v.values())
                                                 for k, v in transl_tilt.items()},
                    "translation_only_max_tilt_rad": {
                        k: None if None in v.values() else max(v.values())
                        for k, v in transl_only.items()},
                    "translation_only_max_tilt_rad_by_axis": transl_only},
        "checks": {
            "sensor_unstable": check(float(unstable["sensor_feedback"]), 0.0,
                                     unstable["sensor_feedback"]),
            "observer_stable": check(float(unstable["observer_feedback"]), 0.0,
                                     not unstable["observer_feedback"]),
            "observer_tilt_le_0.1": check(obs_max, 0.1, obs_max <= 0.1),
        },
    }
    paper = {"unstable": {"sensor_feedback": True, "observer_feedback": False},
             "max_platform_tilt_rad": {"observer_feedback": 0.1},
             "accelerometer_fed": {"unstable": False, "max_platform_tilt_rad": 0.1},
             "fig_5_8": {"max_inclinometer_reading_deg": 20.0},
             "fig_5_9": {"translation_only_max_tilt_rad": {"sensor_feedback": 0.5,
                                                           "accelerometer_fed": 0.1}}}
    return Result(metrics=metrics, paper=paper, series=series,
                  simulated_s=(duration + accel_s) * len(rows))


def figures(result: Result, out_dir: Path) -> list[Path]:
    """F Fig. 5.7/5.8 (base swing) and 5.9 (translation): tilt, reading, estimate, base, command,
    for the three feeds (inclinometer; observer given the true acceleration; observer given the
    platform accelerometer's reading)."""
    from verticality.core.plots import new_figure, published_line, save

    s = result.series
    t = s["t"]
    fig, axes = new_figure(3, 6, width=21)
    unstable = {**result.metrics["unstable_by_axis"],
                "accelerometer_fed": result.metrics["accelerometer_fed"]["unstable_by_axis"]}
    for j, (feed, axis) in enumerate([(f, a) for f in FEEDS for a in AXES]):
        k = f"{feed}/{axis}"
        ax = axes[0, j]
        ax.plot(t, s[f"{k}/base"], color="0.6", lw=0.8, label="base link")
        ax.plot(t, s[f"{k}/reading"], lw=0.8, label="inclinometer")
        ax.plot(t, s[f"{k}/tilt"], label="platform tilt")
        if feed != "sensor_feedback":
            ax.plot(t, s[f"{k}/estimate"], lw=0.8, ls="--", label="estimate")
        ax.axvline(s["swing_s"], color="k", lw=0.6, ls=":")
        ax.set_ylim(-1.5, 1.5)
        uns = unstable[feed][axis]
        ax.set_title(f"{axis}, {feed.replace('_', ' ')}: {'UNSTABLE' if uns else 'stable'}",
                     fontsize=9)
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
        if feed == "accelerometer_fed":
            ax2.plot(t, s[f"{k}/a_acc"], color="C4", lw=0.5, label="accelerometer [m/s²]")
        ax2.set_ylim(-3, 3)
        ax.set_ylabel("motor torque u [N·m]")
        ax2.set_ylabel("base acceleration a [m/s²]")
        ax.set_xlabel("t [s]  (base swing | translation)")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    axes[1, 0].legend(fontsize=7)
    return [save(fig, out_dir / "fig5_7_5_9_platform.png")]
