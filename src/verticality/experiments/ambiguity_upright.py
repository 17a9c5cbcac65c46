"""F §4.5.2 under the Fig. 4.12 caption's reading, for `ambiguity-initial-tilt` and
`ambiguity-desired-tilt`: the acceleration fed to the internal model is "estimated based on the
otoliths measurements and assumption of the head up-right stabilization" (also F §4.6 item 4, "if
the neural system assumes that the head is always aligned with gravity, the otolith measurements
will provide information on the linear acceleration"): F 3.14 with the saccule's ``a_z`` and the
head taken as upright, ``â_h = −(a_z + g) tan r`` in the planar model's signs
(:func:`verticality.analysis.ambiguity.planar_head_acceleration` at ``θ_H = 0``).

The head, otolith, internal model, observer and walking are those of
:mod:`verticality.experiments.ambiguity`. Two things differ, both readings of F's silence:

- **Continuous time.** F's simulations are continuous-time block diagrams (Fig. 4.11–4.12); here
  the plant, the observer ODE (F 4.10), the PD and the reconstruction are one ODE integrated by
  RK4 at 10 kHz with the walking acceleration at every stage. The sampled loop of the sibling
  module (reading and reconstruction held over each 0.1 ms) adds one sample of delay inside the
  reconstruction, and both loops of this section sit on a marginal mode (the still tilt is read as
  acceleration, :func:`loop_eigenvalues`): the sampled upright loop drifts at +0.6 s⁻¹ where the
  continuous one has 0 and −0.02 s⁻¹, and the sampled F 3.17 loop is stable at 10 kHz where the
  continuous one is not.
- **A soft PD.** F gives no gains; the head's loop is critically damped at 4 rad/s
  (:data:`PD_LOOP_RAD_S`, the middle of 3–5 rad/s) instead of the sibling's 10 rad/s; the grid of
  :func:`sweeps` reports how the outcome moves with it.
- **Walking at the step frequency** (``harmonics=0`` of :func:`verticality.simulation.trajectories.walking`):
  0.32 g vertical, 0.16 g fore–aft at 2 steps/s, the bounce a quarter step behind the forward sway;
  F Fig. 4.13 gives no numbers, and the built-in walking's 2nd harmonics are a grid parameter.

Runs last 20 s from the gait's steady part; "converged" is the sibling's (mean ``|θ̂ − θ|`` and
``|θ − θ_ref|`` over the last second ≤ 10°). The grid moves one parameter of :data:`NOMINAL` at a
time: PD bandwidth, walking amplitude, the bounce's lag behind the forward acceleration ``a_x``
(``vertical_lag_deg``, by shifting the bounce in time) and the 2nd harmonics.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import ambiguity as am
from verticality.core.integrate import rk4_step_staged
from verticality.estimators import luenberger as lu
from verticality.models.planar import HeadInput, PlanarState
from verticality.simulation import trajectories as tr

DT_S = 1e-4
DURATION_S = 20.0
QUICK_DURATION_S = 10.0
PD_LOOP_RAD_S = 4.0
STEP_HZ = 2.0  # the walking's cadence (trajectories.walking)
NOMINAL_LAG_DEG = 90.0  # trajectories.walking: the bounce lags the fore–aft sway by a quarter step
OUT_EVERY = 100  # series kept at 100 Hz

INITIAL_TILTS_DEG = (0.0, 4.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0)
DESIRED_TILTS_DEG = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0)
# one parameter moved at a time from NOMINAL (whose own runs give the grid's middle point)
GRID = {"pd_loop_rad_s": (2.0, 3.0, 5.0, 7.0, 10.0),
        "walking_scale": (0.5, 0.75, 1.25, 1.5),
        "vertical_lag_deg": (0.0, 45.0, 135.0, 180.0, 270.0),
        "harmonics": (0.25, 0.5, 1.0)}
QUICK_GRID = {"pd_loop_rad_s": (3.0, 5.0), "walking_scale": (0.5, 1.5),
              "vertical_lag_deg": (45.0,), "harmonics": (1.0,)}
NOMINAL = {"pd_loop_rad_s": PD_LOOP_RAD_S, "walking_scale": 1.0,
           "vertical_lag_deg": NOMINAL_LAG_DEG, "harmonics": 0.0}


def fed_acceleration(feed: str, reading_rad, a_z_m_s2, theta_hat_rad, a_h_true_m_s2):
    """The horizontal head-frame acceleration the internal model is fed: ``upright`` F 3.14 with
    the head taken as upright (the Fig. 4.12 caption), ``luenberger`` F 3.17 with the estimated
    tilt (F's text before Fig. 4.12), ``known`` the true one (Fig. 4.11)."""
    if feed == "upright":
        return am.planar_head_acceleration(reading_rad, a_z_m_s2, 0.0)
    if feed == "luenberger":
        return am.planar_head_acceleration(reading_rad, a_z_m_s2, theta_hat_rad, small_angle=True)
    if feed == "known":
        return a_h_true_m_s2
    raise ValueError(f"unknown feed {feed!r}")


def _vertical_shift_samples(lag_deg: float) -> int:
    """Half-samples by which the bounce is read later than the sway for a lag of ``lag_deg``
    (relative to the walking's own quarter step), in [0, one step)."""
    period_half_samples = int(round(2.0 / (STEP_HZ * DT_S)))
    shift = -(lag_deg - NOMINAL_LAG_DEG) / 360.0 * period_half_samples
    return int(round(shift)) % period_half_samples


def walking_half_steps(n_steps: int, t0_s: float = 2.0):
    """The walking's ``(a_h, a_z)`` on a grid of half samples from its steady gait (``t0_s``), each
    (2, ·): the step frequency alone (``harmonics=0``) and the 2nd harmonics' part; ``2 n + 1``
    values for the sway, one step's period more for the bounce (to shift it)."""
    period_s = 1.0 / STEP_HZ
    n_half = 2 * n_steps + 1
    extra = int(round(2.0 * period_s / DT_S))
    t = t0_s + np.arange(n_half + extra) * (DT_S / 2.0)
    a = [np.asarray(tr.sample(tr.walking(duration_s=t0_s + n_steps * DT_S + period_s + 1.0,
                                         harmonics=h), t).a_I_m_s2) for h in (0.0, 1.0)]
    a_h = -np.stack([a[0][:n_half, 0], a[1][:n_half, 0] - a[0][:n_half, 0]])  # sagittal: h = −x
    a_z = np.stack([a[0][:, 2], a[1][:, 2] - a[0][:, 2]])
    return a_h, a_z


class LoopSummary(NamedTuple):
    """Per run, at 100 Hz: the head's tilt, its estimate, the fed and true accelerations."""

    theta_H: jnp.ndarray
    theta_hat: jnp.ndarray
    a_hat: jnp.ndarray
    a_true: jnp.ndarray


def closed_loop(feed: str, theta0_rad, ref_rad, kp, kd, scale, harmonics, shift, a_h_half,
                a_z_half, n_steps: int, obs, truth):
    """One continuous-time closed loop (plant, observer ODE F 4.10, PD on the estimate, the fed
    acceleration of ``feed``) by RK4 at :data:`DT_S`; the walking (:func:`walking_half_steps`)
    with its 2nd harmonics scaled by ``harmonics``, all scaled by ``scale``, its bounce read
    ``shift`` half-samples later. Returns :class:`LoopSummary` every :data:`OUT_EVERY` steps."""
    A, B, C, D, L = (jnp.asarray(m) for m in (obs.A, obs.B, obs.C, obs.D, obs.L))

    def field(w, z):
        x, xh = z
        a_h, a_z = w
        y = truth.output(x)
        tau = kp * (ref_rad - xh[2]) - kd * xh[3]
        a_hat = fed_acceleration(feed, y[0], a_z, xh[2], a_h)
        u = jnp.stack([tau, a_hat])
        dx = truth.dynamics(x, HeadInput(tau, a_h, a_z))
        dxh = A @ xh + B @ u + L @ (y - C @ xh - D @ u)
        return (dx, dxh), a_hat

    mix = scale * jnp.stack([1.0, harmonics])
    a_h_all, a_z_all = mix @ a_h_half, mix @ a_z_half

    def acc3(k):
        j = 2 * k + jnp.arange(3)
        return a_h_all[j], a_z_all[j + shift]

    def step(z, k):
        w = acc3(k)
        z_new, a_hat = rk4_step_staged(field, w, z, DT_S)
        return z_new, (a_hat, w[0][0])

    def block(z, b):
        z_end, (a_hat, a_true) = jax.lax.scan(step, z, b * OUT_EVERY + jnp.arange(OUT_EVERY))
        x, xh = z
        return z_end, LoopSummary(x.theta_H_rad, xh[2], a_hat.mean(), a_true.mean())

    th0 = jnp.asarray(theta0_rad, float)
    r0 = am.planar_reading(a_h_all[0], a_z_all[shift], th0)
    x0 = PlanarState(th0 + r0, 0.0 * th0, th0, 0.0 * th0)
    return jax.lax.scan(block, (x0, jnp.zeros(4)), jnp.arange(n_steps // OUT_EVERY))[1]


_batch = jax.jit(jax.vmap(closed_loop, in_axes=(None, 0, 0, 0, 0, 0, 0, 0, None, None, None, None,
                                                None)),
                 static_argnums=(0, 10))


def runs(feed: str, theta0_deg, ref_deg, pd_loop_rad_s, walking_scale, vertical_lag_deg,
         harmonics, duration_s: float) -> LoopSummary:
    """A batch of runs (the arguments broadcast to one length); numpy :class:`LoopSummary` with a
    leading run axis."""
    from verticality.experiments import ambiguity as sib

    th0, ref, w, scale, lag, harm = np.broadcast_arrays(*(np.asarray(v, float) for v in (
        theta0_deg, ref_deg, pd_loop_rad_s, walking_scale, vertical_lag_deg, harmonics)))
    n = int(round(duration_s / DT_S))
    kp, kd = sib.pd_gains(loop_rad_s=w)
    shift = np.array([_vertical_shift_samples(v) for v in lag.ravel()], np.int64)
    a_h_half, a_z_half = walking_half_steps(n)
    obs = lu.design(sib.linear_model(), sib.LUENBERGER_POLES)
    out = _batch(feed, jnp.radians(th0.ravel()), jnp.radians(ref.ravel()), jnp.asarray(kp.ravel()),
                 jnp.asarray(kd.ravel()), jnp.asarray(scale.ravel()), jnp.asarray(harm.ravel()),
                 jnp.asarray(shift),
                 jnp.asarray(a_h_half), jnp.asarray(a_z_half), n, obs, sib.plant())
    return LoopSummary(*(np.asarray(v) for v in out))


def summarize(s: LoopSummary, ref_deg) -> list[dict]:
    """Per run: converged (the sibling's rule), final tilt and head errors (deg), RMS error of the
    fed acceleration after the first second."""
    from verticality.experiments.ambiguity import CONVERGED_DEG, finite_or_none

    n = s.theta_H.shape[1]
    last1 = np.arange(n) >= n - int(round(1.0 / (OUT_EVERY * DT_S)))
    after1 = np.arange(n) >= int(round(1.0 / (OUT_EVERY * DT_S)))
    rows = []
    for i, ref in enumerate(np.radians(np.broadcast_to(np.asarray(ref_deg, float), (len(s.theta_H),)))):
        est = np.degrees(np.abs(s.theta_hat[i] - s.theta_H[i]))
        head = np.degrees(np.abs(s.theta_H[i] - ref))
        finite = all(np.all(np.isfinite(v[i])) for v in s)
        e, h = est[last1].mean(), head[last1].mean()
        rows.append({"converged": bool(finite and e <= CONVERGED_DEG and h <= CONVERGED_DEG),
                     "final_tilt_error_deg": finite_or_none(e),
                     "final_head_error_deg": finite_or_none(h),
                     "rms_acc_error_m_s2": finite_or_none(
                         np.sqrt(np.mean((s.a_hat[i] - s.a_true[i])[after1] ** 2)))})
    return rows


def _largest(values, rows):
    from verticality.experiments.ambiguity import largest_converging

    return largest_converging(values, rows)


def _smallest(values, rows):
    from verticality.experiments.ambiguity import smallest_failing

    return smallest_failing(values, rows)


def sweeps(swept: str, duration_s: float, grid: dict | None = None) -> tuple[dict, LoopSummary]:
    """The initial-tilt (``swept = "initial_tilt"``, upright target) or desired-tilt (from 5°)
    sweep of the upright feed at the :data:`NOMINAL` setting and, with ``grid``, the boundary
    with one parameter moved at a time over ``grid`` (``entry["boundary"][param]``: the values and
    the largest converging and smallest failing sweep values); one batch of runs. Returns the
    entry and the nominal setting's :class:`LoopSummary`."""
    from verticality.experiments.ambiguity import THETA0_DEG

    values = INITIAL_TILTS_DEG if swept == "initial_tilt" else DESIRED_TILTS_DEG
    settings = [(None, None)] + [(name, v) for name, vs in (grid or {}).items() for v in vs]
    cols = {k: [] for k in ("th0", "ref", *NOMINAL)}
    for name, v in settings:
        p = NOMINAL if name is None else {**NOMINAL, name: v}
        for sv in values:
            cols["th0"].append(sv if swept == "initial_tilt" else THETA0_DEG)
            cols["ref"].append(0.0 if swept == "initial_tilt" else sv)
            for k in NOMINAL:
                cols[k].append(p[k])
    s = runs("upright", cols["th0"], cols["ref"], cols["pd_loop_rad_s"], cols["walking_scale"],
             cols["vertical_lag_deg"], cols["harmonics"], duration_s)
    rows = summarize(s, cols["ref"])
    lo, hi = f"largest_converging_{swept}_deg", f"smallest_failing_{swept}_deg"
    nominal = rows[:len(values)]
    entry = {f"{swept}_deg": list(values), "per_value": nominal,
             lo: _largest(values, nominal), hi: _smallest(values, nominal)}
    if grid:
        entry["boundary"] = {}
        for j, (name, v) in enumerate(settings[1:], start=1):
            chunk = rows[j * len(values):(j + 1) * len(values)]
            b = entry["boundary"].setdefault(name, {"values": [], lo: [], hi: []})
            b["values"].append(v)
            b[lo].append(_largest(values, chunk))
            b[hi].append(_smallest(values, chunk))
        for name, b in entry["boundary"].items():  # the nominal point in every row, sorted
            order = sorted(range(len(b["values"]) + 1),
                           key=lambda i: (b["values"] + [NOMINAL[name]])[i])
            for key, nominal_value in (("values", NOMINAL[name]), (lo, entry[lo]), (hi, entry[hi])):
                b[key] = [(b[key] + [nominal_value])[i] for i in order]
    return entry, LoopSummary(*(v[:len(values)] for v in s))


def _loop_map(z, feed: str, sampled: bool, kp, kd, dt_s, disc, obs, truth):
    """The loop of ``feed`` linearized in :func:`loop_eigenvalues`: ``ż`` (continuous) or the state
    one sample later (``sampled``), ``z`` = (plant state, observer state), head only rotating."""
    zero = jnp.asarray(0.0)
    x, xh = PlanarState(*z[:4]), z[4:]
    y = truth.output(x)
    tau = -kp * xh[2] - kd * xh[3]
    u = jnp.stack([tau, fed_acceleration(feed, y[0], zero, xh[2], zero)])
    if not sampled:
        dx = truth.dynamics(x, HeadInput(tau, zero, zero))
        dxh = obs.A @ xh + obs.B @ u + obs.L @ (y - obs.C @ xh - obs.D @ u)
        return jnp.concatenate([jnp.stack(list(dx)), dxh])
    xh_new = obs.step_discrete(obs.init(xh), u, y, disc)[0].x
    stages = HeadInput(jnp.broadcast_to(tau, (3,)), jnp.zeros(3), jnp.zeros(3))
    x_new = rk4_step_staged(lambda w, xx: (truth.dynamics(xx, w), None), stages, x, dt_s)[0]
    return jnp.concatenate([jnp.stack(list(x_new)), xh_new])


_loop_jacobian = jax.jit(jax.jacfwd(_loop_map), static_argnums=(1, 2))


def loop_eigenvalues(feed: str, pd_loop_rad_s: float, dt_s: float | None = None) -> np.ndarray:
    """Eigenvalues (1/s) of the loop of ``feed`` linearized at upright, head only rotating: the
    continuous-time Jacobian (``dt_s`` None) or the sampled loop of
    :func:`verticality.experiments.ambiguity.closed_loop` (reading and fed acceleration held over
    ``dt_s``, observer stepped exactly, plant by RK4), its multipliers μ mapped to ``log μ / dt``;
    sorted by decreasing real part."""
    from verticality.experiments import ambiguity as sib

    obs = lu.design(sib.linear_model(), sib.LUENBERGER_POLES)
    kp, kd = sib.pd_gains(loop_rad_s=pd_loop_rad_s)
    sampled = dt_s is not None
    dt = jnp.asarray(dt_s if sampled else 1.0)
    disc = obs.discretize(dt)
    J = np.asarray(_loop_jacobian(jnp.zeros(8), feed, sampled, kp, kd, dt, disc, obs, sib.plant()))
    lam = np.linalg.eigvals(J).astype(complex)
    if sampled:
        lam = np.log(lam) / dt_s
    return lam[np.argsort(-lam.real)]


def stability_report(pd_loops=(PD_LOOP_RAD_S, 10.0), steps=(1e-4, 2.5e-5, 1e-5)) -> dict:
    """The upright-linearized loops, F 3.17 with the estimated tilt (``luenberger``) and F 3.14
    upright, head only rotating, in continuous time and sampled at ``steps``: the largest real part
    of any eigenvalue (1/s) and the oscillatory pair with the largest real part (1/s, Hz)."""
    out: dict = {}
    for feed in ("luenberger", "upright"):
        for w in pd_loops:
            entry = {}
            for dt in (None, *steps):
                lam = loop_eigenvalues(feed, w, dt)
                osc = lam[np.abs(lam.imag) > 1.0]
                key = "continuous" if dt is None else f"sampled_{1.0 / dt / 1e3:g}_kHz"
                entry[key] = {"max_real_1_s": float(lam[0].real),
                              "oscillatory_real_1_s": float(osc[0].real),
                              "oscillatory_hz": float(abs(osc[0].imag) / (2.0 * math.pi))}
            out.setdefault(feed, {})[f"pd_{w:g}_rad_s"] = entry
    return out
