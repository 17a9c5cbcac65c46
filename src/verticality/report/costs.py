"""How long each experiment of ``verticality reproduce`` is expected to take: the order the worker
processes take them in (longest first, so that no long one starts last) and the time left that the
progress shows.

An experiment's expected wall time is the one it took in the previous run of the same mode into the
same results folder (its ``results.json``), else the stored table of typical costs below (full
runs; also the order of a quick one), else (an experiment added since the table was measured) the
table's median.
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Iterable, Mapping
from pathlib import Path

# Estimated wall seconds of each experiment in a full run, one after the other in one process,
# cold (no compilation cache), on a quiet 2-core machine: a run reported 487 s of experiment time,
# the two ambiguity sweeps 100 s of it (split as their ratio in a busy machine's run, which also
# gives ambiguity-known-acc's share), observability 46 s, the rest about 3 s each. The ekf-* share
# compiled closed loops (compiling is most of their time): ekf-impact compiles six, ekf-jump and
# ekf-sensitivity none (they run on ekf-impact's 10 s loops, from the worker's memory or the
# compilation cache: the jump's 8 s are the first 400 ticks of a 10 s loop), so they are placed
# after it, when its loops are compiled; ekf-jump's estimate is its runs alone. Only the ratios
# matter: they set the order (a quick run shortens the same experiments, so it keeps about the
# same order), and the progress scales them by the pace of the experiments done for the time left.
TYPICAL_WALL_S: dict[str, float] = {
    "ekf-impact": 62.0, "ekf-jump": 15.0, "ekf-sensitivity": 35.0,
    "ambiguity-initial-tilt": 55.0, "ambiguity-desired-tilt": 45.0, "observability": 46.0,
    "ambiguity-known-acc": 13.0,
    **dict.fromkeys(
        ("ground-edo", "ground-kf", "model-checks", "newton-lissajous", "newton-uncertainty",
         "perception-centrifuge", "perception-ovar", "perception-post-rotatory-tilt",
         "perception-roll-swing", "perception-somatogravic", "perception-stabilized-head",
         "perception-yaw", "platform", "separation", "tahboub-gains", "tahboub-prts",
         "tahboub-sine", "tahboub-step"), 3.0),
}


def _mode(quick: bool) -> str:
    return "quick" if quick else "full"


def previous_runtimes(out_dir: Path | None, quick: bool) -> dict[str, float]:
    """Each experiment's wall seconds in the previous run of this mode into ``out_dir`` (its
    ``results.json``); empty when there is none or it cannot be read."""
    if out_dir is None:
        return {}
    from verticality.report import read_results_text
    from verticality.report.entries import RESULTS_NAME

    try:
        saved = json.loads(read_results_text(Path(out_dir) / RESULTS_NAME))
        if saved["provenance"]["mode"] != _mode(quick):
            return {}
        return {str(n): float(e["runtime"]["wall_s"]) for n, e in saved["experiments"].items()}
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return {}


def expected_wall_s(names: Iterable[str], quick: bool, out_dir: Path | None = None,
                    table: Mapping[str, float] | None = None) -> dict[str, float]:
    """``{name: expected wall seconds}``: the previous run's into ``out_dir``, else the table's,
    else the table's median (1 s for an empty table)."""
    previous = previous_runtimes(out_dir, quick)
    table = TYPICAL_WALL_S if table is None else table
    typical = statistics.median(table.values()) if table else 1.0
    return {n: float(previous.get(n, table.get(n, typical))) for n in names}


def longest_first(expected: Mapping[str, float]) -> list[str]:
    """The names, longest expected first (ties by name, so the order is reproducible)."""
    return sorted(expected, key=lambda n: (-expected[n], n))


def time_left(expected: Mapping[str, float], running: Mapping[str, float],
              waiting: Iterable[str], jobs: int) -> float:
    """Seconds until the last experiment ends, if each takes its expected time: the running ones
    (name: seconds elapsed; one that overran its estimate is taken to end soon) finish, and the
    waiting ones, in their order, go to whichever worker is free first."""
    free_at = sorted(max(expected[n] - elapsed, 0.0) for n, elapsed in running.items())
    free_at += [0.0] * max(jobs - len(free_at), 0)
    for name in waiting:
        free_at.sort()
        free_at[0] += expected[name]
    return max(free_at, default=0.0)
