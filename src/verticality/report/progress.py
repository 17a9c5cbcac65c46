"""The progress of a ``verticality reproduce`` run: which experiments are done, which run and
which wait, and the time left, estimated from their expected times
(:mod:`verticality.report.costs`) at this machine's pace."""

from __future__ import annotations

import statistics
import time
from pathlib import Path


def duration_text(seconds: float) -> str:
    """``"3 min 05 s"`` or ``"42 s"``: a duration as the progress lines print it."""
    seconds = max(round(seconds), 0)
    minutes, s = divmod(seconds, 60)
    return f"{minutes} min {s:02d} s" if minutes else f"{s} s"


class Tracker:
    """Which experiments are done, which run (since when) and which wait; the time left if each
    takes its expected time (:mod:`verticality.report.costs`) scaled by the pace of those
    done."""

    def __init__(self, names: list[str], *, quick: bool, jobs: int, out_dir: Path | None = None,
                 clock=time.monotonic):
        from verticality.report import costs as experiment_costs

        self._costs = experiment_costs
        self.expected = experiment_costs.expected_wall_s(names, quick, out_dir)
        self.jobs = max(1, min(jobs, len(names)))
        self.names = list(names)
        self.clock = clock
        self.started: dict[str, float] = {}
        self.finished: dict[str, float] = {}  # name: wall seconds, as seen from here

    def stage(self, name: str, stage: str) -> None:
        now = self.clock()
        if name not in self.started:
            self.started[name] = now
        if stage == "done":
            self.finished[name] = now - self.started[name]

    def running(self) -> dict[str, float]:
        now = self.clock()
        return {n: now - t for n, t in self.started.items() if n not in self.finished}

    def pace(self) -> float:
        """How much longer than expected the finished experiments took: this machine's speed,
        applied to the others' expected times. A typical experiment's worth of pace 1 weighs in,
        so that one short experiment done does not set it alone."""
        prior = statistics.median(self.expected.values()) if self.expected else 0.0
        expected = sum(self.expected[n] for n in self.finished) + prior
        return (sum(self.finished.values()) + prior) / expected if expected > 0 else 1.0

    def time_left(self) -> float:
        pace = self.pace()
        expected = {n: e * pace for n, e in self.expected.items()}
        waiting = [n for n in self._costs.longest_first(expected) if n not in self.started]
        return self._costs.time_left(expected, self.running(), waiting, self.jobs)

    def headline(self) -> str:
        return (f"reproduce: {len(self.finished)}/{len(self.names)} done, "
                f"{len(self.running())} running")

    def done_line(self, name: str) -> str:
        left = len(self.names) - len(self.finished)
        tail = f"; about {duration_text(self.time_left())} left" if left else ""
        return (f"done {len(self.finished)}/{len(self.names)}: {name} "
                f"({duration_text(self.finished[name])}){tail}")
