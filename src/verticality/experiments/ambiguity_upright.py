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
- **Walking at the step frequency** (``harmonics=0`` of
  :func:`verticality.simulation.trajectories.walking`): 0.32 g vertical, 0.16 g fore–aft at 2
  steps/s, the bounce a quarter step behind the forward sway; F Fig. 4.13 gives no numbers, and the
  built-in walking's 2nd harmonics are a grid parameter.

Runs last 20 s from the gait's steady part; "converged" is the sibling's (mean ``|θ̂ − θ|`` and
``|θ − θ_ref|`` over the last second ≤ 10°). The grid moves one parameter of :data:`NOMINAL` at a
time: PD bandwidth, walking amplitude, the bounce's lag behind the forward acceleration ``a_x``
(``vertical_lag_deg``, by shifting the bounce in time) and the 2nd harmonics.
"""

from __future__ import annotations

from verticality.analysis.ambiguity_outcome import (
    largest_converging,
    smallest_failing,
    summarize_upright,
)
from verticality.simulation.ambiguity_loop import THETA0_DEG
from verticality.simulation.ambiguity_upright_loop import (
    NOMINAL_LAG_DEG,
    PD_LOOP_RAD_S,
    LoopSummary,
    runs,
)

DURATION_S = 20.0
QUICK_DURATION_S = 10.0

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

def sweeps(swept: str, duration_s: float, grid: dict | None = None) -> tuple[dict, LoopSummary]:
    """The initial-tilt (``swept = "initial_tilt"``, upright target) or desired-tilt (from 5°)
    sweep of the upright feed at the :data:`NOMINAL` setting and, with ``grid``, the boundary
    with one parameter moved at a time over ``grid`` (``entry["boundary"][param]``: the values and
    the largest converging and smallest failing sweep values); one batch of runs. Returns the
    entry and the nominal setting's :class:`LoopSummary`."""
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
    rows = summarize_upright(s, cols["ref"])
    lo, hi = f"largest_converging_{swept}_deg", f"smallest_failing_{swept}_deg"
    nominal = rows[:len(values)]
    entry = {f"{swept}_deg": list(values), "per_value": nominal,
             lo: largest_converging(values, nominal), hi: smallest_failing(values, nominal)}
    if grid:
        entry["boundary"] = {}
        for j, (name, v) in enumerate(settings[1:], start=1):
            chunk = rows[j * len(values):(j + 1) * len(values)]
            b = entry["boundary"].setdefault(name, {"values": [], lo: [], hi: []})
            b["values"].append(v)
            b[lo].append(largest_converging(values, chunk))
            b[hi].append(smallest_failing(values, chunk))
        for name, b in entry["boundary"].items():  # the nominal point in every row, sorted
            order = sorted(range(len(b["values"]) + 1),
                           key=lambda i: (b["values"] + [NOMINAL[name]])[i])
            for key, nominal_value in (("values", NOMINAL[name]), (lo, entry[lo]), (hi, entry[hi])):
                b[key] = [(b[key] + [nominal_value])[i] for i in order]
    return entry, LoopSummary(*(v[:len(values)] for v in s))
