"""`platform` — F ch. 5: simulated copy of the gimbal platform, inclinometer-fed vs observer-fed PD.

Each gimbal axis is its identified model (F §5.2;
:class:`verticality.models.platform.PlatformAxis`): pitch J1 = 0.008, b1 = 1.35; roll J2 = 0.0006,
b2 = 0.137 (``J θ̈ + b (θ̇ − s θ̇_base) = u``), with the identified inclinometer
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
- The base motion enters the platform only through the joint damping, through the share s of the
  identified b (F identified ``J θ̈ + b θ̇ = u`` with the base still, so the split is not in F):
  the seed's reading s = :data:`SEED_DRAG_SHARE` = 0.1 (F §5.1.2's "low friction" cable drive),
  beside it 0.3 and 1 (all of b on the joint's velocity, earlier releases), ``metrics.readings``.
  The base motion is unknown to the observer, which knows u and the linear acceleration a_h:
  gravity-free in ``observer_feedback`` (as in F §4.4's simulations), the raw reading in
  ``accelerometer_fed`` (an accelerometer on the platform measures the same gravito-inertial
  combination as the inclinometer, so the observer cannot see a slow tilt).
- The accelerometer is ideal (unbiased, at the pivot) unless stated; F gives neither its offset nor
  its distance from the pivot (it sat on the platform's lower surface). :data:`FRAGILITY`: F Fig.
  5.9's translation alone with a 1 mg offset and with the sensor 5 mm below the pivot (then it
  also reads ``d·ω̇``), for both observer feeds (``metrics.fig_5_9.accelerometer_errors``).
- F's swing is judged as F states it: the platform's amplitude against the base's motion relative
  to it (``swing.*.tilt_over_relative_motion``; F: "significantly smaller", at most 0.5 ours; the
  relative motion, the larger axis, against F's 40–50°); F's "< 0.1 rad" is the translation's.
- PD gains (not printed in F): pitch k_p = 300, k_d = 1.0; roll k_p = 40, k_d = 0.05 (state-fed
  closed loops well damped, crossover above the inclinometer's slow pole at 15.9 rad/s).
- Observer poles −150, −170, −190, −210 s⁻¹ for both axes (≈ 10× the inclinometer's slow pole;
  with −60…−90 the observer-fed platform stays stable but oscillates up to 0.25 rad).
- Amplifier limit |u| ≤ 50 (pitch), 5 (roll), which only the unstable loop ever reaches.
- Reading noise σ = 1e-3 rad (ADC) on the inclinometer, the same in both feeds.
- **Unstable**: |θ| exceeds 1 rad (the workspace) or is non-finite, or the tilt envelope grows
  (max over the last quarter > 2 × max over the second quarter of a phase, and > 0.05 rad), in
  either axis. ``swing_max_tilt_rad`` is max |θ| over both axes in the swing, t ≥ 1 s.
"""

from __future__ import annotations

import dataclasses
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
#: the share of the identified damping b through which the swinging base drags the platform
#: (:class:`verticality.models.platform.PlatformAxis`): the seed's reading first (F §5.1.2's
#: "low friction" cable drive read as a tenth of b), then more of it (all of it: earlier releases)
SEED_DRAG_SHARE = 0.1
DRAG_SHARES = (SEED_DRAG_SHARE, 0.3, 1.0)
#: the accelerometer's errors F does not give, each alone, on F Fig. 5.9's translation: an offset of
#: 1 mg, and the sensor 5 mm below the pivot (F §5.1.2: on the platform's lower surface)
FRAGILITY = {"bias_0.01_m_s2": (0.01, 0.0), "below_pivot_0.005_m": (0.0, 0.005)}


def _cfg(feed: str, axis: str, key, drag_share: float = SEED_DRAG_SHARE, bias: float = 0.0,
         below_pivot_m: float = 0.0) -> AxisCfg:
    p = dataclasses.replace(AXES[axis], base_drag_share=drag_share)
    kp, kd = GAINS[axis]
    return AxisCfg(p, jnp.asarray(kp), jnp.asarray(kd), jnp.asarray(U_MAX[axis]),
                   jnp.asarray(BASE_AMP_RAD[axis]), jnp.asarray(2 * np.pi * BASE_FREQ_HZ[axis]),
                   jnp.asarray(2 * np.pi * ACC_FREQ_HZ[axis]), jnp.asarray(ACC_PHASE[axis]),
                   observer_for(p), jnp.asarray(0.0 if feed == "sensor_feedback" else 1.0), key,
                   jnp.asarray(float(feed == "accelerometer_fed")), jnp.asarray(float(bias)),
                   jnp.asarray(float(below_pivot_m)))


def _stack(cfgs):
    return jax.tree_util.tree_map(lambda *a: jnp.stack([jnp.asarray(v) for v in a]), *cfgs)


def _swing_lanes():
    """(reading, feed, axis) and the configs of the swing-then-translation runs: every feed at the
    seed's drag share and at the whole of b, the accelerometer-fed observer at 0.3."""
    keys = jax.random.split(jax.random.PRNGKey(5), 6)
    rows, cfgs = [], []
    for share in DRAG_SHARES:
        feeds = FEEDS if share in (SEED_DRAG_SHARE, 1.0) else ("accelerometer_fed",)
        for feed in feeds:
            for j, axis in enumerate(AXES):
                rows.append((f"drag_{share}", feed, axis))
                cfgs.append(_cfg(feed, axis, keys[2 * FEEDS.index(feed) + j], share))
    return rows, _stack(cfgs)


def _translation_lanes():
    """(feed, error, axis) and the configs of F Fig. 5.9's test alone (the base still, so the drag
    share does not enter): every feed with an ideal accelerometer, the two observer feeds with
    each error of :data:`FRAGILITY`."""
    keys = jax.random.split(jax.random.PRNGKey(6), 6)
    rows, cfgs = [], []
    for feed in FEEDS:
        for j, axis in enumerate(AXES):
            rows.append((feed, "none", axis))
            cfgs.append(_cfg(feed, axis, keys[2 * FEEDS.index(feed) + j]))
    for feed in ("accelerometer_fed", "observer_feedback"):
        for err, (bias, below) in FRAGILITY.items():
            for j, axis in enumerate(AXES):
                rows.append((feed, err, axis))
                cfgs.append(_cfg(feed, axis, keys[2 * FEEDS.index(feed) + j], bias=bias,
                                 below_pivot_m=below))
    return rows, _stack(cfgs)


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


def _finite_max(x) -> float | None:
    x = np.abs(np.asarray(x))
    return float(x.max()) if np.all(np.isfinite(x)) else None


@register("platform", "Gimbal platform: inclinometer-fed vs observer-fed PD (F ch. 5)",
          source="F §5.2, Fig. 5.7–5.9", figures=lambda r, d: figures(r, d))
def run(quick: bool = False) -> Result:
    swing_s, accel_s = (5.0, 5.0) if quick else (15.0, 15.0)
    duration = swing_s + accel_s
    n = int(round(duration / LOOP_DT_S))
    rows, cfg = _swing_lanes()
    th, y, th_hat, base, u, a, a_acc = (np.asarray(v) for v in simulate_batch(cfg, n, swing_s))
    t = np.arange(n) * LOOP_DT_S
    swing, transl = (t >= SETTLE_S) & (t < swing_s), t >= swing_s + SETTLE_S
    series: dict = {"t": t[::3], "swing_s": swing_s, "drag_share": SEED_DRAG_SHARE}
    lanes: dict = {}
    for i, (reading, feed, axis) in enumerate(rows):
        rel = np.abs(base[i] - th[i])[swing]
        lanes.setdefault(reading, {}).setdefault(feed, {})[axis] = {
            "unstable": is_unstable(t, th[i], swing_s),
            "swing_max_tilt_rad": _finite_max(th[i][swing]),
            "relative_base_motion_rad": float(rel.max()) if np.all(np.isfinite(rel)) else None,
            "translation_phase_max_tilt_rad": _finite_max(th[i][transl]),
            "max_inclinometer_reading_deg": float(np.degrees(np.abs(y[i][swing]).max())),
            "max_estimation_error_rad": _finite_max((th_hat[i] - th[i])[t >= SETTLE_S]),
            "rms_accelerometer_minus_acceleration_m_s2": float(
                np.sqrt(np.mean((a_acc[i] - a[i])[transl] ** 2))),
        }
        if reading == f"drag_{SEED_DRAG_SHARE}":
            for name, arr in (("tilt", th[i]), ("reading", y[i]), ("estimate", th_hat[i]),
                              ("base", base[i]), ("u", u[i]), ("a", a[i]), ("a_acc", a_acc[i])):
                series[f"{feed}/{axis}/{name}"] = arr[::3]

    def worst(per_axis: dict, key: str):
        vals = [v[key] for v in per_axis.values()]
        return None if None in vals else max(vals)

    readings: dict = {}
    for reading, by_feed in lanes.items():
        for feed, per_axis in by_feed.items():
            tilt, rel = worst(per_axis, "swing_max_tilt_rad"), worst(per_axis,
                                                                     "relative_base_motion_rad")
            ratio = [v["swing_max_tilt_rad"] / v["relative_base_motion_rad"]
                     for v in per_axis.values()
                     if v["swing_max_tilt_rad"] is not None and v["relative_base_motion_rad"]]
            readings.setdefault(reading, {})[feed] = {
                "unstable": any(v["unstable"] for v in per_axis.values()),
                "swing_max_tilt_rad": tilt,
                # the base's swing relative to the platform, the larger axis (F: 40–50°)
                "relative_base_motion_deg": None if rel is None else float(np.degrees(rel)),
                "tilt_over_relative_motion": max(ratio) if len(ratio) == len(per_axis) else None,
                "translation_phase_max_tilt_rad": worst(per_axis,
                                                        "translation_phase_max_tilt_rad"),
                "max_inclinometer_reading_deg": worst(per_axis, "max_inclinometer_reading_deg"),
                "max_estimation_error_rad": worst(per_axis, "max_estimation_error_rad"),
                "by_axis": per_axis,
            }
    # F Fig. 5.9 is its own test (the platform translated, the base still): the loops from rest
    # under the translation alone, with an ideal accelerometer and with each error
    t_rows, t_cfg = _translation_lanes()
    n_t = int(round(accel_s / LOOP_DT_S))
    th_t = np.asarray(simulate_batch(t_cfg, n_t, 0.0)[0])
    t_t = np.arange(n_t) * LOOP_DT_S
    transl_only: dict = {}
    for i, (feed, err, axis) in enumerate(t_rows):
        transl_only.setdefault(err, {}).setdefault(feed, {})[axis] = _finite_max(
            th_t[i][t_t >= SETTLE_S])
    worst_t = {err: {feed: None if None in v.values() else max(v.values())
                     for feed, v in by.items()} for err, by in transl_only.items()}
    seed = readings[f"drag_{SEED_DRAG_SHARE}"]
    acc = seed["accelerometer_fed"]
    metrics = {
        "base_drag_share": SEED_DRAG_SHARE,
        "unstable": {k: seed[k]["unstable"] for k in FEEDS},
        "swing": {k: {key: seed[k][key] for key in ("swing_max_tilt_rad",
                                                    "relative_base_motion_deg",
                                                    "tilt_over_relative_motion",
                                                    "max_inclinometer_reading_deg")}
                  for k in FEEDS},
        "readings": readings,
        "fig_5_9": {"translation_only_max_tilt_rad": worst_t["none"],
                    "translation_only_max_tilt_rad_by_axis": transl_only["none"],
                    "accelerometer_errors": {err: worst_t[err] for err in FRAGILITY}},
        "checks": {
            "sensor_unstable": check(float(seed["sensor_feedback"]["unstable"]), 0.0,
                                     seed["sensor_feedback"]["unstable"]),
            "accelerometer_fed_stable": check(float(acc["unstable"]), 0.0, not acc["unstable"]),
            "swing_tilt_le_half_relative_motion": check(
                acc["tilt_over_relative_motion"], 0.5,
                acc["tilt_over_relative_motion"] is not None
                and acc["tilt_over_relative_motion"] <= 0.5),
            "translation_alone_le_0.1": check(
                worst_t["none"]["accelerometer_fed"], 0.1,
                worst_t["none"]["accelerometer_fed"] is not None
                and worst_t["none"]["accelerometer_fed"] <= 0.1),
        },
    }
    paper = {"unstable": {"sensor_feedback": True, "accelerometer_fed": False},
             "swing": {"accelerometer_fed": {"relative_base_motion_deg": "40–50",
                                             "tilt_over_relative_motion": "significantly < 1",
                                             "max_inclinometer_reading_deg": 20.0}},
             "fig_5_9": {"translation_only_max_tilt_rad": {"sensor_feedback": 0.5,
                                                           "accelerometer_fed": 0.1}}}
    return Result(metrics=metrics, paper=paper, series=series,
                  simulated_s=duration * len(rows) + accel_s * len(t_rows))


def figures(result: Result, out_dir: Path) -> list[Path]:
    """F Fig. 5.7/5.8 (base swing) and 5.9 (translation): tilt, reading, estimate, base, command,
    for the three feeds (inclinometer; observer given the true acceleration; observer given the
    platform accelerometer's reading)."""
    from verticality.core.plots import new_figure, published_line, save

    s = result.series
    t = s["t"]
    fig, axes = new_figure(3, 6, width=21)
    seed = result.metrics["readings"][f"drag_{s.get('drag_share', SEED_DRAG_SHARE)}"]
    unstable = {f: {a: seed[f]["by_axis"][a]["unstable"] for a in AXES} for f in FEEDS}
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
        ax.set_title(f"{axis}, {feed.replace('_', ' ')}: {'UNSTABLE' if uns else 'stable'}"
                     f" (drag share {s.get('drag_share', SEED_DRAG_SHARE)})", fontsize=8)
        ax.set_ylabel("rad")
        ax = axes[1, j]
        ax.plot(t, np.abs(s[f"{k}/tilt"]), color="C1", lw=0.8, label="|platform tilt|")
        published_line(ax, 0.1, label="F Fig. 5.9: < 0.1 rad (translation)")
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
