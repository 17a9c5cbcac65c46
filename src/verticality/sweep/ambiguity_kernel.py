"""Sweep kernel ``ambiguity-walking``: the closed loop of the ambiguity-* experiments (F §4.5.2).

The runs are those of the `ambiguity-*` experiments (:mod:`verticality.simulation.ambiguity_loop`):
F §4.5.2's head carrying the medial otolith (critically damped at 300 Hz, head inertia
0.0174 kg·m²), walking from :func:`verticality.simulation.trajectories.walking` (the steady gait),
10 kHz, an observer on the internal model estimating the head's tilt and a PD on the estimate
holding the head at the desired tilt,
computed by the experiments' :func:`~verticality.simulation.ambiguity_loop.sweep` (its
``closed_loop``, vmapped over the runs). Knobs:

- ``feed``: how the observer gets the head's horizontal acceleration (the experiment's
  :data:`~verticality.simulation.ambiguity_loop.KINDS`): ``known`` (the true one, F Fig. 4.11),
  ``luenberger`` (reconstructed from the reading with F 3.17, Fig. 4.12), ``luenberger_exact``
  (with F 3.16), ``ekf`` (an EKF on the nonlinear model with the acceleration a random-walk
  state), ``ekf_gauss_markov`` (a Gauss–Markov state of time constant 0.2 s);
- ``initial_tilt_deg``: the head's initial tilt (default 5°, the experiment's θ₀);
- ``desired_tilt_deg``: the PD's reference (default 0°);
- ``walking_scale``: the walking acceleration × this (0: a head that only rotates);
- ``otolith_frequency_rel_error``, ``otolith_damping_rel_error``, ``head_inertia_rel_error``: the
  internal model's relative error, with sign, of the otolith's natural frequency (300 Hz), its
  damping ratio (1) and the head's inertia. The internal model is the plant's model value
  (:func:`~verticality.simulation.ambiguity_loop.plant`) built with the wrong values; the
  Luenberger observer is designed on it (F 4.10, its poles at twice the *assumed* natural
  frequency) and the EKF runs on it; the PD's gains are designed on the assumed inertia;
- ``head_loop_rad_s``: the PD's bandwidth ω (default 10 rad/s): ``k_p = Ĵ ω²``, ``k_d = 2 Ĵ ω``
  with Ĵ the assumed head inertia (the experiment's gains at the defaults);
- ``noise_rad``: σ of a white noise on each 0.1 ms reading (default 0: the experiment has none),
  drawn from the run's seed (``jax.random.PRNGKey(seed)``); the EKF's R stays the experiment's
  (1e-3 rad)².

Option ``duration_s`` (default 10 s, the experiment's full mode; 3 s is its quick mode). Metrics,
by the experiments' :func:`~verticality.analysis.ambiguity_outcome.summarize`: over the last second
the mean ``|θ̂_H − θ_H|`` (``final_tilt_error_deg``) and the mean ``|θ_H − θ_ref|``
(``final_head_error_deg``), and the RMS of ``â_h − a_h`` after the first second
(``rms_acc_error_m_s2``; NaN for ``known``, whose acceleration is the true one, as the experiment
reports none); a run **diverged** when it did not converge by the experiment's rule (a quantity
non-finite, or either final error above ``CONVERGED_DEG`` = 10°); non-finite metrics are NaN.

Batching: the feed is static in the compiled loop, and the experiment's loop shares one walking
acceleration, one internal model, one observer and one PD among the runs of a vmap, so the runs
of a batch are grouped by (``feed``, ``walking_scale``, the three model errors,
``head_loop_rad_s``), and each group is one vmap over its initial tilts, desired tilts, noise
levels and seeds; only a new feed, duration or group size compiles again (the models, poles
and gains are traced). A spec whose batch holds one group (those knobs outermost in the grid,
``batch`` = the runs of one group) uses full batches and compiles once per feed. A run computed
alone or in a batch gives the same numbers to the bit with the Luenberger feeds, and to rounding
(2e-12 relative measured) with the EKF's, whose batched matrix algebra rounds otherwise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from verticality.analysis.ambiguity_outcome import summarize
from verticality.models.params import F452_HEAD_INERTIA_KG_M2, F452_OTOLITH_DAMPING_RATIO
from verticality.simulation import ambiguity_loop
from verticality.sweep.kernels import Kernel, Knob, grouped_rows

MODEL_ERRORS = ("otolith_frequency_rel_error", "otolith_damping_rel_error",
                "head_inertia_rel_error")
GROUP_KNOBS = ("feed", "walking_scale", *MODEL_ERRORS, "head_loop_rad_s")
METRICS = ("final_tilt_error_deg", "final_head_error_deg", "rms_acc_error_m_s2")


def internal_model(otolith_frequency_rel_error: float, otolith_damping_rel_error: float,
                   head_inertia_rel_error: float):
    """The internal model (the plant's value with the assumed parameters) and the assumed
    natural frequency (rad/s) and head inertia (kg·m²)."""
    omega_n = ambiguity_loop.OMEGA_N_RAD_S * (1.0 + otolith_frequency_rel_error)
    J = F452_HEAD_INERTIA_KG_M2 * (1.0 + head_inertia_rel_error)
    model = ambiguity_loop.plant(
        omega_n, F452_OTOLITH_DAMPING_RATIO * (1.0 + otolith_damping_rel_error), J)
    return model, omega_n, J


def run_group(key: tuple, initial_tilt_deg, desired_tilt_deg, noise_rad, seeds, *,
              duration_s: float) -> dict[str, np.ndarray]:
    """The metrics of the runs of one group ``key`` (:data:`GROUP_KNOBS`' values), one vmap."""
    feed, walking_scale, e_omega, e_zeta, e_J, loop = key
    model, omega_n, J = internal_model(e_omega, e_zeta, e_J)
    s = ambiguity_loop.sweep(feed, initial_tilt_deg, desired_tilt_deg, duration_s, walking_scale,
                             model=model, gains=ambiguity_loop.pd_gains(J, loop),
                             poles=ambiguity_loop.luenberger_poles(omega_n),
                             noise_rad=noise_rad, seeds=seeds)
    rows = summarize(s, desired_tilt_deg, known=(feed == "known"))
    out = {m: np.array([np.nan if r[m] is None else r[m] for r in rows], dtype=np.float64)
           for m in METRICS}
    return out | {"diverged": np.array([not r["converged"] for r in rows], dtype=bool)}


def run_batch(columns: dict[str, np.ndarray], seeds: np.ndarray, *,
              duration_s: float) -> dict[str, np.ndarray]:
    """The metrics of the runs ``columns`` × ``seeds``, one vmap per group, in row order."""
    n = seeds.shape[0]
    out = {m: np.full(n, np.nan) for m in METRICS} | {"diverged": np.zeros(n, dtype=bool)}
    keys = [(str(columns["feed"][i]), *(float(columns[k][i]) for k in GROUP_KNOBS[1:]))
            for i in range(n)]
    for key, rows in grouped_rows(keys):
        got = run_group(key, np.asarray(columns["initial_tilt_deg"][rows], dtype=np.float64),
                        np.asarray(columns["desired_tilt_deg"][rows], dtype=np.float64),
                        np.asarray(columns["noise_rad"][rows], dtype=np.float64),
                        np.asarray(seeds[rows], dtype=np.int64), duration_s=duration_s)
        for k, v in got.items():
            out[k][rows] = v
    return out


def _check_options(o: dict[str, Any]) -> str | None:
    d = o["duration_s"]
    if isinstance(d, bool) or not isinstance(d, int | float) or not 2.0 <= d <= 60.0:
        return f"duration_s must be a number of seconds in [2, 60] (got {d!r})"
    if abs(d / ambiguity_loop.DT_S - round(d / ambiguity_loop.DT_S)) > 1e-6:
        return f"duration_s must be a multiple of the 0.1 ms sample (got {d!r})"
    return None


_ERROR = dict(lo=-0.9, hi=1.0)
_TILT = dict(lo=-45.0, hi=45.0)

AMBIGUITY_WALKING = Kernel(
    name="ambiguity-walking",
    doc="F §4.5.2's observer-based head stabilization while walking, the acceleration known or "
        "reconstructed from the otolith",
    knobs={
        "feed": Knob("luenberger", "the observer's horizontal acceleration: known, reconstructed "
                     "(F 3.17 or exact F 3.16) or an EKF state", choices=ambiguity_loop.KINDS),
        "initial_tilt_deg": Knob(ambiguity_loop.THETA0_DEG, "the head's initial tilt (deg)",
                                 **_TILT),
        "desired_tilt_deg": Knob(0.0, "the PD's reference tilt (deg)", **_TILT),
        "walking_scale": Knob(1.0, "the walking acceleration × this (0: rotation only)",
                              lo=0.0, hi=3.0),
        "otolith_frequency_rel_error": Knob(0.0, "the internal model's relative error of the "
                                            "otolith's natural frequency (signed)", **_ERROR),
        "otolith_damping_rel_error": Knob(0.0, "the internal model's relative error of the "
                                          "otolith's damping ratio (signed)", **_ERROR),
        "head_inertia_rel_error": Knob(0.0, "the internal model's (and the PD design's) relative "
                                       "error of the head's inertia (signed)", **_ERROR),
        "head_loop_rad_s": Knob(ambiguity_loop.HEAD_LOOP_RAD_S, "the PD's bandwidth: k_p = Ĵω², "
                                "k_d = 2Ĵω (rad/s)", lo=0.0, lo_open=True, hi=100.0),
        "noise_rad": Knob(0.0, "σ of the white noise on each 0.1 ms reading (rad)", lo=0.0,
                          hi=0.1),
    },
    options={"duration_s": 10.0},
    metrics=METRICS,
    run_batch=run_batch,
    check_options=_check_options,
)
