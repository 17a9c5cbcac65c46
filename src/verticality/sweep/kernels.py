"""Sweep kernels: an experiment's closed loop as a batch function
``(knob columns, seeds) -> metrics``.

A :class:`Kernel` declares its knobs (:class:`Knob`: default, allowed values), its options (fixed
settings of a sweep, e.g. the simulated duration) and its metrics, and runs a batch of runs at
once with ``jax.vmap`` inside one compiled function. Every run carries its own seed. Kernels are
registered by name in :data:`verticality.sweep.registry.KERNELS`.

``newton-lissajous`` — the closed loop of the `newton-lissajous` experiment
(:func:`verticality.simulation.newton_loop.simulate`: P11's plant, PD and Newton observer, Lissajous
trunk motion). The plant is :func:`verticality.models.lissajous_plant.p11_head`; the observer's
model is the same :class:`~verticality.models.planar.PlanarHead` value with every parameter
scaled by ``1 + <name>_rel_error`` (the parameters are the value's leaves, so an error with sign
is a scaled value, not a second model). The seed draws the reading noise (σ = ``noise_rad``) as
in the experiment (``jax.random.PRNGKey(seed)``). Metrics after t ≥ 1 s: the max and RMS tilt
error in degrees and the share of observer samples that converged; a run **diverged** if its
estimate became non-finite or its max error exceeds 30° (the experiment's rule); the errors of a
non-finite run are NaN.

The knob ``error_level`` (default 0) adds, on top of each parameter's ``<name>_rel_error``, a
random error ``error_level × u`` with ``u`` uniform on [−1, 1], drawn per parameter from the run's
seed on a stream of its own (``jax.random.fold_in(jax.random.PRNGKey(seed), ERROR_STREAM)``, so
the reading noise is the same with or without it): a level is a bound on every parameter's error,
"uncertainties of up to ±level". The drawn parts are columns of the table (``m_drawn_error``, …;
the observer's error of ``m`` is ``m_rel_error + m_drawn_error``); at level 0 they are zero and
every run gives the numbers it gave before the knob existed (to the bit).

The knobs of the trunk motion and of the controller, all traced (per run, inside one compiled
batch), are keywords of :func:`~verticality.simulation.newton_loop.simulate`:

- ``amplitude_scale`` (≥ 0, default 1): the Lissajous amplitude A = 0.25 times this (x, z and Θ
  all scale with A; 0 is a trunk at rest);
- ``frequency_scale`` (> 0, default 1): the motion's time scale, the trunk at t being the published
  motion at ``frequency_scale · t`` (:func:`verticality.models.lissajous_plant.trunk`); the fixed
  head starts with that motion's rate Θ̇(0);
- ``kp_Nm_rad``, ``kd_Nms_rad`` (> 0, default P11's 230 and 15): the stabilized head's PD gains;
  the fixed head has no controller and does not use them.

The names and meaning of the scales are those of the ``ekf-*`` kernels; their ranges and the
gains' are justified in ``_check_newton_knobs``. A batch whose runs are all at the published motion
(both scales 1) leaves the scales out of the compiled function: the motion's samples are then
constants, as before the knobs existed, and the runs are today's to the bit; scales of 1 in a batch
with other scales give the same runs within ~2e-15 relative (XLA then computes the motion at run
time instead of folding it into constants, and the runs differ in the last bits).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import newton_errors
from verticality.models import lissajous_plant as lp
from verticality.models.planar import PlanarHead
from verticality.simulation import newton_loop


@dataclass(frozen=True)
class Knob:
    """One knob of a kernel: its default and its allowed values (``choices`` for a categorical
    knob, else a numeric interval)."""

    default: Any
    doc: str = ""
    choices: tuple[str, ...] = ()
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False

    def problem(self, v) -> str | None:
        """Why ``v`` is not an allowed value (None if it is)."""
        if self.choices:
            return None if v in self.choices else f"{v!r} is not one of {', '.join(self.choices)}"
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return f"{v!r} is not a finite number"
        if v < self.lo or (self.lo_open and v == self.lo) or v > self.hi:
            left = "(" if self.lo_open else "["
            return f"{v!r} is outside {left}{self.lo}, {self.hi}]"
        return None

    def column(self, values) -> np.ndarray:
        """The knob's column of the results table (strings or float64)."""
        return np.asarray(values, dtype=str if self.choices else np.float64)


@dataclass(frozen=True)
class Kernel:
    name: str
    doc: str
    knobs: dict[str, Knob]
    options: dict[str, Any]  # defaults
    metrics: tuple[str, ...]  # float64 columns, besides the bool column ``diverged``
    run_batch: Callable[..., dict[str, np.ndarray]]  # (columns, seeds, **options) -> metrics
    check_options: Callable[[dict[str, Any]], str | None] = field(default=lambda o: None)
    # (numeric knob → (least, greatest) value of the design) -> why the knobs together are not
    # allowed (None if they are): a limit on a combination of knobs that no one knob has
    check_knobs: Callable[[dict[str, tuple[float, float]]], str | None] = field(
        default=lambda extents: None)
    # (batch, design columns, **options) -> None: compile the batch functions the design's
    # batches need without running them (ahead of time, so that JAX's persistent compilation
    # cache holds them before worker processes need them)
    compile_batch: Callable[..., None] = field(default=lambda batch, columns, **options: None)
    # float64 columns a run draws from its seed (written between the seed and the metrics)
    drawn: tuple[str, ...] = ()
    # a published single point in the knobs (knob → value) and what was published there
    published: dict[str, float] = field(default_factory=dict)
    published_label: str = ""


def grouped_rows(keys: list) -> list[tuple[Any, np.ndarray]]:
    """The rows of a batch grouped by their key (``keys[i]`` is row i's, hashable): ``(key,
    rows)`` per distinct key in order of first appearance, the rows ascending. For kernels whose
    closed loop shares something among the runs of one vmap (a trajectory, a model), so that each
    group is one compiled batch."""
    rows: dict[Any, list[int]] = {}
    for i, k in enumerate(keys):
        rows.setdefault(k, []).append(i)
    return [(k, np.asarray(r)) for k, r in rows.items()]


# ----------------------------------------------------------------------- newton-lissajous
PARAMETERS = ("m_kg", "l_m", "J_kg_m2", "beta_Nms", "K_kg_m2")  # PlanarHead leaves with errors


ERROR_STREAM = 0x45525252  # fold_in data of the drawn parameter errors' stream (not the noise's)


def _rel_name(leaf: str) -> str:
    return leaf.split("_")[0] + "_rel_error"


def _drawn_name(leaf: str) -> str:
    return leaf.split("_")[0] + "_drawn_error"


@jax.jit
def drawn_errors(error_level, seeds):
    """The random relative errors ``error_level × u`` of the five :data:`PARAMETERS` per run,
    ``u`` uniform on [−1, 1] from the run's seed on the stream :data:`ERROR_STREAM`; (B, 5)."""

    def one(level, seed):
        key = jax.random.fold_in(jax.random.PRNGKey(seed), ERROR_STREAM)
        u = jax.random.uniform(key, (len(PARAMETERS),), minval=-1.0, maxval=1.0)
        return jnp.where(level == 0.0, 0.0, level * u)  # level 0: +0, not −0, in the table

    return jax.vmap(one)(error_level, seeds)


MOTION_KNOBS = ("amplitude_scale", "frequency_scale", "kp_Nm_rad", "kd_Nms_rad")  # simulate's
SCALE_HI = 4.0  # the greatest amplitude and frequency scales (see _check_newton_knobs)
KP_HI = 2000.0  # N·m/rad: ω_n = √(K_p / K) = 200 rad/s, 0.2 rad per 1 ms step (K = 0.05 kg·m²)
KD_HI = 50.0  # N·m·s/rad: K_d·Δt / K = 1, the rate loop's per-step limit (see _check_newton_knobs)


@partial(jax.jit, static_argnames=("n_blocks",))
def newton_lissajous_batch(rel_errors, fixed, noise_rad, seeds, motion=None, *, n_blocks: int):
    """vmap over runs of the `newton-lissajous` closed loop; ``rel_errors`` is a
    :class:`~verticality.models.planar.PlanarHead` of (B,) relative errors (the observer's value is
    the plant's, leaf by leaf, times ``1 + error``); ``motion`` maps each of :data:`MOTION_KNOBS`
    to its (B,) values (keywords of :func:`~verticality.simulation.newton_loop.simulate`, traced;
    None or a knob left out: simulate's default); returns the per-run metrics."""
    p_true = lp.p11_head(1.0)
    motion = {} if motion is None else motion

    def one(rel, f, sigma, seed, mo):
        p_obs = jax.tree_util.tree_map(lambda v, e: v * (1.0 + e), p_true, rel)
        s = newton_loop.simulate(p_true, p_obs, f, sigma, jax.random.PRNGKey(seed), n_blocks, **mo)
        err = newton_errors.tilt_error_deg(s)
        scored = s.t_s >= newton_errors.SETTLE_S - 1e-9
        finite = jnp.all(jnp.isfinite(jnp.where(scored, err, 0.0))) & jnp.all(
            jnp.isfinite(s.theta_H_hat_rad))
        max_err = jnp.max(jnp.where(scored, err, -jnp.inf))
        rms = jnp.sqrt(jnp.sum(jnp.where(scored, err**2, 0.0)) / jnp.sum(scored))
        t_obs = s.t_s[newton_loop.SUBSTEPS - 1::newton_loop.SUBSTEPS]
        obs_scored = t_obs >= newton_errors.SETTLE_S
        conv = jnp.sum(s.converged & obs_scored) / jnp.sum(obs_scored)
        nan = jnp.nan
        return {"max_error_deg": jnp.where(finite, max_err, nan),
                "rms_error_deg": jnp.where(finite, rms, nan),
                "converged_fraction": conv,
                "diverged": ~finite | (max_err > newton_errors.DIVERGED_DEG)}

    return jax.vmap(one)(rel_errors, fixed, noise_rad, seeds, motion)


def newton_lissajous_args(columns: dict[str, np.ndarray], seeds: np.ndarray, duration_s: float):
    """The batch function's arguments and the drawn errors (B, 5) of the runs."""
    n = seeds.shape[0]
    seeds = jnp.asarray(seeds, dtype=jnp.int64)
    drawn = drawn_errors(jnp.asarray(columns["error_level"], dtype=jnp.float64), seeds)
    # at level 0 the drawn part is ±0 and the sum is the knob's value exactly
    rel = PlanarHead(**{leaf: jnp.asarray(columns[_rel_name(leaf)], dtype=jnp.float64) + drawn[:, i]
                        for i, leaf in enumerate(PARAMETERS)}, g_m_s2=jnp.zeros(n))
    n_blocks = int(round(duration_s / (newton_loop.SUBSTEPS * newton_loop.DT_S)))
    # a batch of the published motion leaves the scales out (simulate's constants 1): the motion's
    # samples are then known when compiling and XLA folds them, as it did before the scales were
    # knobs (traced scales of 1 give the same runs within ~2e-15 relative, not to the bit)
    published = bool(np.all(at_published_motion(columns)))
    motion = {k: jnp.asarray(columns[k], dtype=jnp.float64) for k in MOTION_KNOBS
              if not (published and k in ("amplitude_scale", "frequency_scale"))}
    return (rel, jnp.asarray(columns["head"] == "fixed"),
            jnp.asarray(columns["noise_rad"], dtype=jnp.float64), seeds, motion, n_blocks), drawn


def _newton_lissajous(columns: dict[str, np.ndarray], seeds: np.ndarray, *,
                      duration_s: float) -> dict[str, np.ndarray]:
    args, drawn = newton_lissajous_args(columns, seeds, duration_s)
    out = {k: np.asarray(v) for k, v in newton_lissajous_batch(*args[:-1],
                                                                n_blocks=args[-1]).items()}
    return out | {_drawn_name(leaf): np.asarray(drawn[:, i]) for i, leaf in enumerate(PARAMETERS)}


def at_published_motion(columns: dict[str, np.ndarray]) -> np.ndarray:
    """Per run: both motion scales are 1 (P11's motion)."""
    return ((np.asarray(columns["amplitude_scale"], dtype=np.float64) == 1.0)
            & (np.asarray(columns["frequency_scale"], dtype=np.float64) == 1.0))


def published_batches(columns: dict[str, np.ndarray], batch: int) -> set[bool]:
    """Which of the two compiled forms of :func:`newton_lissajous_batch` the design's batches of
    ``batch`` runs need: True for a batch wholly at the published motion (the scales are left
    out), False for one that varies the motion (the scales traced)."""
    at = at_published_motion(columns)
    return {bool(np.all(at[a:a + batch])) for a in range(0, at.size, batch)}


def _compile_newton_lissajous(batch: int, columns: dict[str, np.ndarray], *,
                              duration_s: float) -> None:
    for published in published_batches(columns, batch):
        cols = {k: np.full(batch, v.default, dtype=object if v.choices else np.float64)
                for k, v in NEWTON_LISSAJOUS.knobs.items()}
        if not published:
            cols["amplitude_scale"] = np.full(batch, 2.0)
        args, _ = newton_lissajous_args(cols, np.zeros(batch, dtype=np.int64), duration_s)
        newton_lissajous_batch.lower(*args[:-1], n_blocks=args[-1]).compile()


def _check_newton_knobs(extents: dict[str, tuple[float, float]]) -> str | None:
    """Every parameter's total error, its knob plus a draw down to −error_level, must stay > −1
    (a positive parameter).

    The motion's and the gains' own ranges keep the runs within what the 1 ms simulation and the
    25 ms observer resolve (no combination of them needs a further limit: a fixed head that cannot
    follow a fast, wide motion diverges, which the table says):

    - ``frequency_scale`` ≤ :data:`SCALE_HI` = 4: Θ's fastest component, 1 Hz in P11's motion,
      becomes 4 Hz, still 10 observer samples per period and 250 plant steps of 1 ms (whose inputs
      are held over the step: a relative error of (2π·4 Hz·1 ms)²/24 ≈ 3e-5);
    - ``amplitude_scale`` ≤ 4: the trunk tilts up to ±4 × P11's 45° = ±180°;
    - ``kp_Nm_rad`` ≤ :data:`KP_HI`, ``kd_Nms_rad`` ≤ :data:`KD_HI`: the PD torque is computed from
      the 1 ms estimate and held over each 1 ms step of a head of inertia K = 0.05 kg·m², so
      K_d·Δt/K must stay below 2 for the rate loop not to overshoot and grow; at 50 N·m·s/rad it is
      1 (the rate is cancelled in one step), and at 2000 N·m/rad the loop's natural frequency
      √(K_p/K) is 200 rad/s, 0.2 rad per step."""
    level = extents["error_level"][1]
    for leaf in PARAMETERS:
        least = extents[_rel_name(leaf)][0]
        if least - level <= -1.0:
            return (f"{_rel_name(leaf)} down to {least:g} with error_level up to {level:g} can "
                    f"make the observer's {leaf} zero or negative (the sum must stay above −1)")
    return None


def _check_newton_options(o: dict[str, Any]) -> str | None:
    d = o["duration_s"]
    if isinstance(d, bool) or not isinstance(d, int | float) or not 1.5 <= d <= 600.0:
        return f"duration_s must be a number of seconds in [1.5, 600] (got {d!r})"
    if abs(d / 0.025 - round(d / 0.025)) > 1e-9:
        return f"duration_s must be a multiple of the observer's 25 ms interval (got {d!r})"
    return None


_PUBLISHED_MAX_DEG = newton_errors.PAPER_LISSAJOUS["max_tilt_error_deg"]

NEWTON_LISSAJOUS = Kernel(
    name="newton-lissajous",
    doc="P11's Newton observer, fixed or stabilized head, Lissajous trunk motion",
    knobs={"head": Knob("fixed", "fixed (rigid on the trunk) or stabilized (PD on the estimate)",
                        choices=("fixed", "stabilized"))}
    | {_rel_name(leaf): Knob(0.0, f"observer's relative error of {leaf} (signed)", lo=-1.0,
                             lo_open=True, hi=10.0) for leaf in PARAMETERS}
    | {"noise_rad": Knob(1e-4, "σ of the white noise on each 25 ms reading (rad)", lo=0.0, hi=1.0)}
    | {"error_level": Knob(0.0, "bound of a random error, uniform in ±level, drawn from the seed "
                                "for every parameter on top of its own", lo=0.0, hi=0.99)}
    | {"amplitude_scale": Knob(1.0, "the Lissajous amplitude A = 0.25 × this (x, z and Θ)",
                               lo=0.0, hi=SCALE_HI),
       "frequency_scale": Knob(1.0, "the motion's time scale, t → this × t (frequencies × this)",
                               lo=0.0, lo_open=True, hi=SCALE_HI),
       "kp_Nm_rad": Knob(newton_loop.KP, "the stabilized head's PD gain on θ̂_H (N·m/rad; not "
                                         "the fixed head's)", lo=0.0, lo_open=True, hi=KP_HI),
       "kd_Nms_rad": Knob(newton_loop.KD, "the stabilized head's PD gain on ω̂_H (N·m·s/rad; not "
                                          "the fixed head's)", lo=0.0, lo_open=True, hi=KD_HI)},
    options={"duration_s": 10.0},
    metrics=("max_error_deg", "rms_error_deg", "converged_fraction"),
    drawn=tuple(_drawn_name(leaf) for leaf in PARAMETERS),
    run_batch=_newton_lissajous,
    check_options=_check_newton_options,
    check_knobs=_check_newton_knobs,
    compile_batch=_compile_newton_lissajous,
    # P11's perturbed Lissajous run: m, b, J, K 10 % high (l exact), σ = 1e-4 rad
    published={_rel_name(leaf): (0.0 if leaf == "l_m" else 0.1) for leaf in PARAMETERS}
    | {"noise_rad": newton_loop.NOISE_RAD},
    published_label=("P11 (+10 %): max error fixed "
                     f"{_PUBLISHED_MAX_DEG['fixed']['perturbed']:g}°, "
                     "stabilized "
                     f"{_PUBLISHED_MAX_DEG['stabilized']['perturbed']:g}°"),
)
