"""What a vestibular perception model perceives for a head motion: sensors, then the model.

:func:`perceive` takes a head motion (a :class:`verticality.io.motion.MotionRecord`: MOTION.csv
rows, recorded or from :mod:`verticality.perception.paradigms`) and returns the perceived gravity
(tilt), angular velocity, linear acceleration and velocity on the same rows, beside the true ones.

Sensors (the ``canal`` and ``otolith`` options):

* canals — ``high-pass``: the model's own first-order canal (τ and adaptation of the perception
  model's parameters: Merfeld–Zupan τ, τ_a; Laurens–Angelaki τc); ``torsion``: the torsion
  pendulum of F eq. 1.2 with the same long time constant and a 5 ms short one
  (:mod:`verticality.models.canal`). Integrated by RK4, ω_H held over each interval.
* otolith — ``unity``: the papers' sensor, the gravito-inertial force ``f_H = R_HI (g_I − a_I)/g₀``
  (in g); ``pendulum``: the project's damped otolith pendulum (medial, P13 parameters) under the
  same motion (:func:`verticality.simulation.closed_loop.otolith_replay`): its arm direction ``s_H``
  (unit, from pivot to mass, i.e. along the GIF). Reading: the pendulum reports a direction only, so
  its signal has length 1 g.

Tilt angles (degrees) are the angles between the perceived (or true) gravity and the head's −z
axis; :func:`pitch_up_deg` is the pitch (nose up positive) that gravity implies.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2, gravity_I
from verticality.core.errors import InputError
from verticality.core.sizing import check_work_size
from verticality.io.motion import MotionRecord
from verticality.models import canal as canal_models
from verticality.models.base import step_rk4
from verticality.models.otolith_presets import otolith_pendula
from verticality.perception.laurens import laurens_angelaki
from verticality.perception.merfeld import MerfeldZupan
from verticality.perception.params import LaurensParams, MerfeldParams, check_params, model_name

MODELS = ("merfeld", "laurens")
OTOLITHS = ("unity", "pendulum")
CANALS = ("high-pass", "torsion")


class Perception(NamedTuple):
    t_s: np.ndarray  # (N,)
    g_H_perceived: np.ndarray  # (N, 3) unit, head frame
    g_H_true: np.ndarray  # (N, 3) unit
    omega_H_perceived_rad_s: np.ndarray  # (N, 3)
    omega_H_true_rad_s: np.ndarray  # (N, 3)
    a_H_perceived_m_s2: np.ndarray  # (N, 3)
    a_H_true_m_s2: np.ndarray  # (N, 3)
    v_H_perceived_m_s: np.ndarray  # (N, 3)


def canal_model(params, canal: str = "high-pass"):
    """The sensor canal that goes with the perception model's parameters."""
    if canal not in CANALS:
        raise InputError(f"unknown canal {canal!r}; known: {', '.join(CANALS)}")
    tau = params.tau_s if isinstance(params, MerfeldParams) else params.tau_c_s
    if canal == "torsion":
        return canal_models.torsion_pendulum(tau, 0.005)
    tau_a = params.tau_a_s if isinstance(params, MerfeldParams) else float("inf")
    return canal_models.high_pass(tau, None if np.isinf(tau_a) else tau_a)


def estimator(params):
    """The perception model of the parameter value ``params``."""
    if isinstance(params, MerfeldParams):
        return MerfeldZupan(params)
    if isinstance(params, LaurensParams):
        return laurens_angelaki(params)
    raise InputError(f"not the parameters of a perception model: {params!r}")


@jax.jit
def _canal_signals(canal, omega, dts):
    def body(x, inp):
        w, dt = inp
        return step_rk4(canal, x, w, dt), canal.output(x, w)

    return jax.lax.scan(body, canal.rest_state(), (omega, dts))[1]


CANAL_SUBSTEP_BYTES = 64  # per RK4 sub-step: ω (24 B), its length (8 B), the signal (24 B), index
GRID_STEP_BYTES = 256  # per step of the Laurens–Angelaki grid: signals, percepts, interpolation


def canal_substep_s(canal) -> float:
    """The longest RK4 sub-step for ``canal``: half its fastest time constant (the torsion
    pendulum's fastest rate is Π/Θ, the sum of its two), and at most 1 ms for the torsion
    pendulum."""
    if isinstance(canal, canal_models.TorsionPendulumCanal):
        return min(1e-3, 0.5 / float(canal.Pi_over_Theta_s_inv))
    return 0.5 * min(float(canal.tau_s), float(canal.tau_a_s))


def canal_signals(canal, omega_H_rad_s, t_s) -> np.ndarray:
    """The canal signals on the rows: ``y_k = output(x_k, ω_k)``, then ``x_{k+1}`` by RK4 with
    ``ω_k`` held, in ⌈Δt / h⌉ equal sub-steps of at most ``h`` (:func:`canal_substep_s`), so that a
    long interval between rows stays inside RK4's stability region. The work is sized before
    anything is allocated (:func:`verticality.core.sizing.check_work_size`)."""
    t = np.asarray(t_s, float)
    dt = np.diff(t)
    h = canal_substep_s(canal)
    n_sub = np.maximum(np.ceil(dt / h - 1e-9), 1.0)
    k = int(np.argmax(dt))
    check_work_size(float(np.sum(n_sub)) + 1.0, CANAL_SUBSTEP_BYTES,
                    f"canal RK4 sub-steps of {h:.3g} s",
                    f"the largest time step is {dt[k]:.6g} s (data row {k + 2}); cut the recording "
                    "into shorter files or remove the jump")
    n_sub = n_sub.astype(int)
    counts = np.append(n_sub, 1)  # the last row's step is not used
    fine_w = jnp.asarray(np.repeat(np.asarray(omega_H_rad_s, float), counts, axis=0))
    fine_dt = jnp.asarray(np.repeat(np.append(dt / n_sub, dt[-1] / n_sub[-1]), counts))
    y = _canal_signals(canal, fine_w, fine_dt)
    return np.asarray(y)[np.concatenate([[0], np.cumsum(n_sub)])]


def otolith_signals(record: MotionRecord, otolith: str = "unity") -> np.ndarray:
    """The otolith signal (N, 3), head frame, in g (see the module doc)."""
    R = np.asarray(so3.matrix_from_quat(jnp.asarray(record.q_I_H_wxyz)))
    if otolith == "unity":
        f_I = (np.asarray(gravity_I()) - record.a_I_m_s2) / G_M_S2
        return np.einsum("nji,nj->ni", R, f_I)
    if otolith == "pendulum":
        from verticality.simulation import closed_loop as simulation

        pendula, _ = otolith_pendula("medial")
        s_H, _ = simulation.otolith_replay(record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s,
                                           record.a_I_m_s2, pendula)
        return np.asarray(s_H)[:, 0, :]
    raise InputError(f"unknown otolith {otolith!r}; known: {', '.join(OTOLITHS)}")


@jax.jit
def _run(est, ys, dts):
    return est.run(est.init(None), None, ys, dts)[1]


@jax.jit
def _run_held(est, ys, dts, n_sub):
    """:func:`_run` with row ``k``'s interval taken in ``n_sub[k]`` equal steps, ``y_k`` held; the
    output of its last step is the row's (memory stays one output per row)."""
    def row(x, inp):
        y, dt, n = inp
        h = dt / n
        first = est.step(x, None, y, h)
        return jax.lax.fori_loop(1, n, lambda _, c: est.step(c[0], None, y, h), first)

    return jax.lax.scan(row, est.init(None), (ys, dts, n_sub))[1]


MAX_MODEL_STEPS = 10**8  # steps of a perception model in one run: about a minute of one core


def run_model(est, ys, dts) -> tuple:
    """The model's outputs on the rows (``ys`` held over the interval ``dts`` before each). An
    estimator with a longest step (``max_step_s``: the Merfeld–Zupan observer's RK4) takes an
    interval longer than that (a gap in the time stamps) in ⌈Δt / h⌉ equal steps, so that the gap
    is integrated at the model's own step size, never as one step that leaves RK4's stability
    region; the count of steps is sized first."""
    dts = np.asarray(dts, float)
    h = float(est.max_step_s()) if hasattr(est, "max_step_s") else math.inf
    n_sub = np.maximum(np.ceil(dts / h - 1e-9), 1.0)
    if not np.any(n_sub > 1):
        return _run(est, jnp.asarray(ys), jnp.asarray(dts))
    total = float(np.sum(n_sub))
    if not total <= MAX_MODEL_STEPS:
        k = int(np.argmax(dts))
        raise InputError(f"the model steps at most {h:.3g} s at a time, so this recording needs "
                         f"{total:.3g} steps (more than {MAX_MODEL_STEPS:.0e}): its largest time "
                         f"step is {dts[k]:.6g} s (data row {k + 1}); cut the recording into "
                         "shorter files or remove the jump")
    return _run_held(est, jnp.asarray(ys), jnp.asarray(dts), jnp.asarray(n_sub.astype(np.int64)))


def _interp(t_new, t, a) -> np.ndarray:
    """Columns of ``a`` (N, k) on times ``t``, linearly interpolated to ``t_new``."""
    return np.column_stack([np.interp(t_new, t, col) for col in np.asarray(a, float).T])


def perceive(record: MotionRecord, params, otolith: str = "unity",
             canal: str = "high-pass") -> Perception:
    """Perceived gravity, rotation, acceleration and velocity for the head motion ``record`` by the
    perception model of the parameter value ``params`` (:class:`MerfeldParams` or
    :class:`LaurensParams`, e.g. :func:`verticality.perception.params.perception_params` of a
    model and preset; checked by :func:`~verticality.perception.params.check_params`). The model
    starts upright and still.

    The Merfeld–Zupan observer runs on the record's rows (any sampling). The Laurens–Angelaki
    filter runs on its own time step δt: for a record sampled otherwise, the sensor signals are
    interpolated linearly onto a δt grid and the percepts back onto the rows (perceived gravity
    renormalized)."""
    if otolith not in OTOLITHS:
        raise InputError(f"unknown otolith {otolith!r}; known: {', '.join(OTOLITHS)}")
    if len(record.t_s) < 2:
        raise InputError("perceive: the motion needs at least two rows")
    check_params(params)
    p = params
    est = estimator(p)
    alpha = canal_signals(canal_model(p, canal), record.omega_H_rad_s, record.t_s)
    f = otolith_signals(record, otolith)
    t = np.asarray(record.t_s, float)
    ys = np.concatenate([alpha, f], axis=1)
    grid = t
    if isinstance(p, LaurensParams) and np.max(np.abs(np.diff(t) - p.dt_s)) > 1e-9 * p.dt_s:
        # the filter's gains are those of its own time step: run it on that grid
        n_grid = np.floor((t[-1] - t[0]) / p.dt_s + 1e-9) + 1.0
        check_work_size(n_grid, GRID_STEP_BYTES, f"steps of the filter's {p.dt_s:g} s grid",
                        f"the recording spans {t[-1] - t[0]:.6g} s; cut it into shorter files or "
                        "remove its time jumps")
        grid = t[0] + np.arange(int(n_grid)) * p.dt_s
        ys = _interp(grid, t, ys)
    dts = np.diff(grid, prepend=grid[0] - (grid[1] - grid[0]) if grid.size > 1 else p.dt_s)
    outs = run_model(est, ys, dts)
    check_finite_percepts(grid, outs, record)
    if grid is not t:
        outs = type(outs)(*(_interp(t, grid, np.asarray(a, float)) if a.dtype != bool else a
                            for a in outs))
        outs = outs._replace(g_H=outs.g_H / np.linalg.norm(outs.g_H, axis=1, keepdims=True))
    R = np.asarray(so3.matrix_from_quat(jnp.asarray(record.q_I_H_wxyz)))
    g_true = np.einsum("nji,j->ni", R, np.array([0.0, 0.0, -1.0]))
    a_true = np.einsum("nji,nj->ni", R, record.a_I_m_s2)
    return Perception(t, np.asarray(outs.g_H), g_true, np.asarray(outs.omega_H_rad_s),
                      np.asarray(record.omega_H_rad_s, float), np.asarray(outs.a_H_m_s2), a_true,
                      np.asarray(outs.v_H_m_s))


def check_finite_percepts(t_run_s, outs, record: MotionRecord) -> None:
    """Refuse (:class:`InputError`) percepts that are not finite (``outs`` on the times
    ``t_run_s`` the model ran at), naming the record's row at the first such time: the head's
    motion is beyond what the model integrates; no row is written as NaN."""
    t_run = np.asarray(t_run_s, float)
    ok = np.ones(t_run.size, bool)
    for a in outs:
        a = np.asarray(a)
        if a.dtype != bool:
            ok &= np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1)
    # perceived gravity is a direction: of length 1 (a vector that collapsed has no tilt)
    ok &= np.abs(np.linalg.norm(np.asarray(outs.g_H, float), axis=1) - 1.0) < 1e-6
    if np.all(ok):
        return
    t = np.asarray(record.t_s, float)
    k = min(int(np.searchsorted(t, t_run[int(np.argmin(ok))], side="left")), t.size - 1)
    a = np.asarray(record.a_I_m_s2, float)[:k + 1]
    w = np.asarray(record.omega_H_rad_s, float)[:k + 1]
    dt = np.diff(t[:k + 1])
    raise InputError(f"the perception model became non-finite at row {k + 1} (t = {t[k]:g} s): "
                     "the head's motion is beyond what the model integrates (an acceleration of "
                     f"{np.max(np.abs(a)):.3g} m/s², a rate of {np.max(np.abs(w)):.3g} rad/s or a "
                     f"time step of {np.max(dt, initial=0.0):.3g} s by then); no row is written")


def tilt_deg(g_H) -> np.ndarray:
    """The angle (deg) between gravity ``g_H`` (N, 3) and the head's −z axis."""
    g = np.asarray(g_H, float)
    g = g / np.linalg.norm(g, axis=-1, keepdims=True)
    return np.degrees(np.asarray(so3.angle_between_unit_vectors(g, np.array([0.0, 0.0, -1.0]))))


def tilt_error_deg(r: Perception) -> np.ndarray:
    """The angle (deg) between perceived and true gravity, per row."""
    return np.degrees(np.asarray(so3.angle_between_unit_vectors(r.g_H_perceived, r.g_H_true)))


def pitch_up_deg(g_H) -> np.ndarray:
    """Pitch (deg, nose up positive) of the head for gravity ``g_H``: atan2(−g_x, −g_z)."""
    g = np.asarray(g_H, float)
    return np.degrees(np.arctan2(-g[..., 0], -g[..., 2]))


def fit_time_constant(t_s, y) -> float:
    """Time constant (s) of an exponential decay ``y(t) > 0``: log-linear least squares."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    ok = y > 0
    if np.count_nonzero(ok) < 2:
        return float("nan")
    return float(-1.0 / np.polyfit(t[ok], np.log(y[ok]), 1)[0])


def e_fold_time(t_s, y, t0_s: float) -> float:
    """The time (s) from ``t0_s`` until ``y`` first falls below ``y(t0)/e`` (NaN if it does not)."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    m = t >= t0_s - 1e-9
    below = np.nonzero(y[m] < y[m][0] / np.e)[0]
    return float(t[m][below[0]] - t[m][0]) if below.size else float("nan")


def _omega_deg_s(w, omega: str):
    w = np.degrees(np.asarray(w, float))
    return w[:, 2] if omega == "axis" else np.linalg.norm(w, axis=1)


def series(runs: dict, omega: str = "axis", decimate: int = 1) -> dict:
    """Figure series of perceived (each run of ``runs``: {name: Perception}) against actual
    motion: tilt (deg), angular velocity (deg/s: about the head's z for ``omega="axis"``, its
    magnitude for ``"speed"``), |linear acceleration| (m/s²) and the perceived speed in the head's
    x–y plane (m/s), every ``decimate``-th row."""
    first = next(iter(runs.values()))
    k = slice(None, None, decimate)
    s = {"t": first.t_s[k],
         "actual/tilt_deg": tilt_deg(first.g_H_true)[k],
         "actual/omega_deg_s": _omega_deg_s(first.omega_H_true_rad_s, omega)[k],
         "actual/accel_m_s2": np.linalg.norm(first.a_H_true_m_s2, axis=1)[k]}
    for name, r in runs.items():
        s[f"{name}/tilt_deg"] = tilt_deg(r.g_H_perceived)[k]
        s[f"{name}/omega_deg_s"] = _omega_deg_s(r.omega_H_perceived_rad_s, omega)[k]
        s[f"{name}/accel_m_s2"] = np.linalg.norm(r.a_H_perceived_m_s2, axis=1)[k]
        s[f"{name}/speed_m_s"] = np.linalg.norm(r.v_H_perceived_m_s[:, :2], axis=1)[k]
    return s


def plot_series(s: dict, path, title: str = ""):
    """The figure of :func:`series`: four panels over time, actual in black."""
    from pathlib import Path

    from verticality.core.plots import new_figure, save

    t = s["t"]
    names = [k.split("/")[0] for k in s if k.endswith("/tilt_deg") and not k.startswith("actual/")]
    rows = (("tilt_deg", "tilt (°)"), ("omega_deg_s", "angular velocity (°/s)"),
            ("accel_m_s2", "|linear acceleration| (m/s²)"), ("speed_m_s", "perceived speed (m/s)"))
    fig, axes = new_figure(len(rows), 1, width=9, height_per_row=2.2)
    for ax, (key, label) in zip(axes[:, 0], rows, strict=True):
        if f"actual/{key}" in s:
            ax.plot(t, s[f"actual/{key}"], color="k", lw=1.2, label="actual")
        for name in names:
            ax.plot(t, s[f"{name}/{key}"], lw=1.0, label=f"perceived: {name}")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0, 0].set_title(title)
    axes[0, 0].legend(fontsize=8, loc="best")
    axes[-1, 0].set_xlabel("time (s)")
    return save(fig, Path(path))


PERCEPTION_COLUMNS = ("t", "gx", "gy", "gz", "tilt_deg", "tilt_true_deg", "pitch_up_deg",
                      "wx", "wy", "wz", "ax", "ay", "az", "vx", "vy", "vz")
"""OUT.csv of ``perceive``: perceived gravity (unit, head frame), perceived and true tilt (deg),
the pitch perceived gravity implies (deg, nose up), perceived angular velocity (rad/s), linear
acceleration (m/s²) and velocity (m/s), all in the head frame."""


def perception_table(r: Perception) -> np.ndarray:
    """The rows of OUT.csv (:data:`PERCEPTION_COLUMNS`)."""
    return np.column_stack([r.t_s, r.g_H_perceived, tilt_deg(r.g_H_perceived), tilt_deg(r.g_H_true),
                            pitch_up_deg(r.g_H_perceived), r.omega_H_perceived_rad_s,
                            r.a_H_perceived_m_s2, r.v_H_perceived_m_s])


def perceive_file(motion_path, params, otolith: str = "unity", canal: str = "high-pass",
                  out_csv=None, plot_png=None) -> dict:
    """``verticality perceive``: :func:`perceive` by the model of ``params`` on a MOTION.csv (or a
    BROAD-layout recording); writes OUT.csv and the figure when asked; returns a summary
    (JSON-ready). The caller checks the paths first (:func:`verticality.io.paths.check_paths`, as
    the command does)."""
    from verticality.io.motion import load_motion, write_columns_csv

    model = model_name(params)
    rec = load_motion(motion_path)
    r = perceive(rec, params, otolith, canal)
    if out_csv is not None:
        write_columns_csv(out_csv,
                          dict(zip(PERCEPTION_COLUMNS, perception_table(r).T, strict=True)))
    if plot_png is not None:
        plot_series(series({model: r}, "axis"), plot_png, f"{model}: {motion_path}")
    tilt_err = tilt_error_deg(r)
    return {
        "model": model, "otolith": otolith, "canal": canal,
        "rows": int(r.t_s.size), "duration_s": float(r.t_s[-1] - r.t_s[0]),
        "final": {"tilt_deg": float(tilt_deg(r.g_H_perceived)[-1]),
                  "tilt_true_deg": float(tilt_deg(r.g_H_true)[-1]),
                  "omega_deg_s": np.degrees(r.omega_H_perceived_rad_s[-1]).tolist(),
                  "a_m_s2": r.a_H_perceived_m_s2[-1].tolist(),
                  "v_m_s": r.v_H_perceived_m_s[-1].tolist()},
        "max_tilt_error_deg": float(tilt_err.max()),
        "out": None if out_csv is None else str(out_csv),
        "plot": None if plot_png is None else str(plot_png),
    }
