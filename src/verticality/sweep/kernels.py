"""Sweep kernels: an experiment's closed loop as a batch function ``(knob columns, seeds) -> metrics``.

A :class:`Kernel` declares its knobs (:class:`Knob`: default, allowed values), its options (fixed
settings of a sweep, e.g. the simulated duration) and its metrics, and runs a batch of runs at
once with ``jax.vmap`` inside one compiled function. Every run carries its own seed. Kernels are
registered by name in :data:`verticality.sweep.registry.KERNELS`.

``newton-lissajous`` — the closed loop of the `newton-lissajous` experiment
(:func:`verticality.experiments.newton.simulate`: P11's plant, PD and Newton observer, Lissajous
trunk motion). The plant is :func:`verticality.models.lissajous_plant.p11_head`; the observer's
model is the same :class:`~verticality.models.planar.PlanarHead` value with every parameter
scaled by ``1 + <name>_rel_error`` (the parameters are the value's leaves, so an error with sign
is a scaled value, not a second model). The seed draws the reading noise (σ = ``noise_rad``) as
in the experiment (``jax.random.PRNGKey(seed)``). Metrics after t ≥ 1 s: the max and RMS tilt
error in degrees and the share of observer samples that converged; a run **diverged** if its
estimate became non-finite or its max error exceeds 30° (the experiment's rule); the errors of a
non-finite run are NaN.
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

from verticality.experiments import newton as E
from verticality.models import lissajous_plant as lp
from verticality.models.planar import PlanarHead


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
    # (batch, **options) -> None: compile the batch function without running it (ahead of time,
    # so that JAX's persistent compilation cache holds it before worker processes need it)
    compile_batch: Callable[..., None] = field(default=lambda batch, **options: None)
    # a published single point in the knobs (knob → value) and what was published there
    published: dict[str, float] = field(default_factory=dict)
    published_label: str = ""


# ----------------------------------------------------------------------- newton-lissajous
PARAMETERS = ("m_kg", "l_m", "J_kg_m2", "beta_Nms", "K_kg_m2")  # PlanarHead leaves with errors


def _rel_name(leaf: str) -> str:
    return leaf.split("_")[0] + "_rel_error"


@partial(jax.jit, static_argnames=("n_blocks",))
def newton_lissajous_batch(rel_errors, fixed, noise_rad, seeds, n_blocks: int):
    """vmap over runs of the `newton-lissajous` closed loop; ``rel_errors`` is a
    :class:`~verticality.models.planar.PlanarHead` of (B,) relative errors (the observer's value is
    the plant's, leaf by leaf, times ``1 + error``); returns the per-run metrics."""
    p_true = lp.p11_head(1.0)

    def one(rel, f, sigma, seed):
        p_obs = jax.tree_util.tree_map(lambda v, e: v * (1.0 + e), p_true, rel)
        s = E.simulate(p_true, p_obs, f, sigma, jax.random.PRNGKey(seed), n_blocks)
        err = E.tilt_error_deg(s)
        scored = s.t_s >= E.SETTLE_S - 1e-9
        finite = jnp.all(jnp.isfinite(jnp.where(scored, err, 0.0))) & jnp.all(
            jnp.isfinite(s.theta_H_hat_rad))
        max_err = jnp.max(jnp.where(scored, err, -jnp.inf))
        rms = jnp.sqrt(jnp.sum(jnp.where(scored, err**2, 0.0)) / jnp.sum(scored))
        t_obs = s.t_s[E.SUBSTEPS - 1::E.SUBSTEPS]
        obs_scored = t_obs >= E.SETTLE_S
        conv = jnp.sum(s.converged & obs_scored) / jnp.sum(obs_scored)
        nan = jnp.nan
        return {"max_error_deg": jnp.where(finite, max_err, nan),
                "rms_error_deg": jnp.where(finite, rms, nan),
                "converged_fraction": conv,
                "diverged": ~finite | (max_err > E.DIVERGED_DEG)}

    return jax.vmap(one)(rel_errors, fixed, noise_rad, seeds)


def _newton_lissajous_args(columns: dict[str, np.ndarray], seeds: np.ndarray, duration_s: float):
    n = seeds.shape[0]
    rel = PlanarHead(**{leaf: jnp.asarray(columns[_rel_name(leaf)], dtype=jnp.float64)
                        for leaf in PARAMETERS}, g_m_s2=jnp.zeros(n))
    n_blocks = int(round(duration_s / (E.SUBSTEPS * E.DT_S)))
    return (rel, jnp.asarray(columns["head"] == "fixed"),
            jnp.asarray(columns["noise_rad"], dtype=jnp.float64),
            jnp.asarray(seeds, dtype=jnp.int64), n_blocks)


def _newton_lissajous(columns: dict[str, np.ndarray], seeds: np.ndarray, *,
                      duration_s: float) -> dict[str, np.ndarray]:
    out = newton_lissajous_batch(*_newton_lissajous_args(columns, seeds, duration_s))
    return {k: np.asarray(v) for k, v in out.items()}


def _compile_newton_lissajous(batch: int, *, duration_s: float) -> None:
    columns = {k: np.full(batch, v.default, dtype=object if v.choices else np.float64)
               for k, v in NEWTON_LISSAJOUS.knobs.items()}
    args = _newton_lissajous_args(columns, np.zeros(batch, dtype=np.int64), duration_s)
    newton_lissajous_batch.lower(*args[:-1], n_blocks=args[-1]).compile()


def _check_newton_options(o: dict[str, Any]) -> str | None:
    d = o["duration_s"]
    if isinstance(d, bool) or not isinstance(d, int | float) or not 1.5 <= d <= 600.0:
        return f"duration_s must be a number of seconds in [1.5, 600] (got {d!r})"
    if abs(d / 0.025 - round(d / 0.025)) > 1e-9:
        return f"duration_s must be a multiple of the observer's 25 ms interval (got {d!r})"
    return None


NEWTON_LISSAJOUS = Kernel(
    name="newton-lissajous",
    doc="P11's Newton observer, fixed or stabilized head, Lissajous trunk motion",
    knobs={"head": Knob("fixed", "fixed (rigid on the trunk) or stabilized (PD on the estimate)",
                        choices=("fixed", "stabilized"))}
    | {_rel_name(leaf): Knob(0.0, f"observer's relative error of {leaf} (signed)", lo=-1.0,
                             lo_open=True, hi=10.0) for leaf in PARAMETERS}
    | {"noise_rad": Knob(1e-4, "σ of the white noise on each 25 ms reading (rad)", lo=0.0, hi=1.0)},
    options={"duration_s": 10.0},
    metrics=("max_error_deg", "rms_error_deg", "converged_fraction"),
    run_batch=_newton_lissajous,
    check_options=_check_newton_options,
    compile_batch=_compile_newton_lissajous,
    # P11's perturbed Lissajous run: m, b, J, K 10 % high (l exact), σ = 1e-4 rad
    published={_rel_name(leaf): (0.0 if leaf == "l_m" else 0.1) for leaf in PARAMETERS}
    | {"noise_rad": E.NOISE_RAD},
    published_label=("P11 (+10 %): max error fixed "
                     f"{E.PAPER_LISSAJOUS['max_tilt_error_deg']['fixed']['perturbed']:g}°, "
                     "stabilized "
                     f"{E.PAPER_LISSAJOUS['max_tilt_error_deg']['stabilized']['perturbed']:g}°"),
)
