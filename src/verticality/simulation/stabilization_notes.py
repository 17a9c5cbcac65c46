"""What ``verticality stabilize`` tells the user beside the metrics of a
:func:`verticality.simulation.stabilization.compare_heads` comparison: notes on what was
simulated, warnings about the file and errors about heads that diverged. The thresholds that decide
them live here, with the comparison's library, so the command only prints."""

from __future__ import annotations

from typing import NamedTuple

from verticality.simulation import recorded as rt
from verticality.simulation.stabilization import EKF_PERIOD_S

CUT_NOTED_S = 1e-9
"""A cut of the recording's end shorter than this is rounding of the EKF period, not worth a
note."""


class Note(NamedTuple):
    level: str  # "note", "warning" or "error"
    text: str


def input_notes(c) -> list[Note]:
    """Before the results: the recording's end that does not fill an EKF period, ω and q that
    disagree, rows further apart than the EKF's period."""
    notes = []
    if c.cut_s > CUT_NOTED_S:
        notes.append(Note("note", f"simulating {c.report['duration_s']:g} s of the "
                                  f"{c.recorded_s:g} s recorded: the last "
                                  f"{1e3 * c.cut_s:.1f} ms do not fill an EKF period"))
    if c.rate_mismatch_warning:
        notes.append(Note("warning", f"the file's ω and q disagree: over the "
                                     f"{rt.RATE_MISMATCH_WINDOW_S:g} s from t = "
                                     f"{c.rate_mismatch_t_s:g} s, ω integrates to a rotation "
                                     f"{c.rate_mismatch_rad:.3g} rad away from q's; the trunk then "
                                     "follows neither exactly between rows (check ω's frame and "
                                     "units)"))
    if c.max_gap_s > EKF_PERIOD_S:
        notes.append(Note("note", f"rows up to {c.max_gap_s:g} s apart, longer than the EKF's "
                                  f"{EKF_PERIOD_S:g} s period: between rows the trunk's "
                                  "acceleration is interpolated linearly and its rotation by "
                                  "cubic Hermite"))
    return notes


def diverged_notes(c) -> list[Note]:
    """One error per head whose simulation became non-finite (its metrics are left out)."""
    return [Note("error", f"{cond} head: the simulated {what} became non-finite at t = {t_bad:g} s "
                          "(first seed); its metrics are left out. The trunk's motion may be too "
                          "violent for the simulated plant (2-DOF gimbal, 1 ms RK4 step), or its q "
                          "and ω may disagree")
            for cond, (t_bad, what) in c.diverged.items()]


def rejected_notes(c) -> list[Note]:
    """A warning when the EKF refused updates that would have made its state non-finite."""
    rejected = sum(c.report["rejected_updates"].values())
    if not rejected:
        return []
    return [Note("warning", f"the EKF refused {rejected} update(s) that would have made its state "
                            "non-finite (first seed); the estimates there are predictions")]
