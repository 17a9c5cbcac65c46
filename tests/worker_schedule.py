"""How the test files are dealt to the xdist workers (``--dist loadfile``, pyproject's addopts).

The suite is compile-bound: a worker process compiles a kernel once and every later test of that
process reuses it. So

* files that build the same expensive things (a session fixture, the same compiled closed loops)
  are one work unit (:data:`UNITS`): they run in one worker, which builds them once;
* the units are dealt most expensive first (:data:`COST_S`), so that no long file starts last
  while the other worker has finished: the cheap files fill the gaps at the end. (xdist's own
  order is by number of tests, which puts a file of a few slow tests last.)

A file missing from the table gets :data:`DEFAULT_COST_S`. The costs are CPU seconds of each file
run alone on a cold compilation cache (docs/development.md): only their order matters.
"""

from __future__ import annotations

from pathlib import PurePosixPath

# Files whose tests share what is expensive to build, run in one worker.
UNITS = {
    # the quick ekf-jump sweeps (`quick_sweeps`) and the quick ekf-* closed loops (6 s, batch 1)
    "test_ekf_sensitivity.py": "ekf-quick-loops",
    "test_stabilize.py": "ekf-quick-loops",
    "test_sweep_ekf.py": "ekf-quick-loops",
    # `ambiguity-known-acc --quick`'s closed loop (known feed, 3 s, batch 3): compiled once
    "test_ambiguity_experiments.py": "ambiguity-loops",
    "test_sweep_ambiguity.py": "ambiguity-loops",
    # the tiny newton-lissajous sweep (tests/test_sweep.py's TINY): its kernel compiled once
    "test_sweep.py": "newton-tiny-sweep",
    "test_reliability_commands.py": "newton-tiny-sweep",
    # the medial EKF (the same value, run of 30 steps, step and predict) and the op-by-op kernels
    # of the estimators' models (kept in the process's memory, not in the session's cache)
    "test_ekf.py": "ekf-estimators",
    "test_estimator_contract.py": "ekf-estimators",
}

# CPU seconds of each file (or unit) run alone on a cold cache, measured (docs/development.md); the
# files marked ~ from their tests' times in a loaded full run, scaled to CPU seconds. A unit costs
# less than the sum of its files: they share what is expensive.
COST_S = {
    # one `reproduce --quick` of every experiment and the pages opened in Chromium: dealt first,
    # or it is the last file of a worker
    "test_report_browser.py": 399.0,
    "ekf-estimators": 163.0,
    "test_reliability.py": 153.0,
    "ekf-quick-loops": 152.0,
    "ambiguity-loops": 86.0,
    "test_tilt_smoother.py": 85.0,
    "newton-tiny-sweep": 72.0,
    "test_architecture.py": 70.0,
    "test_observability_otolith.py": 42.0,  # ~
    "test_reproduce_parallel.py": 39.0,
    "test_broad.py": 34.0,
    "test_cli_tables.py": 34.0,
    "test_docs_examples.py": 33.0,
    "test_model_checks.py": 28.0,  # ~
    "test_tilt_limits.py": 25.0,  # ~
    "test_tilt_saturation.py": 25.0,
    "test_cli_perceive.py": 24.0,
    "test_ambiguity_upright.py": 23.0,
    "test_observability.py": 20.0,  # ~
    "test_ambiguity.py": 20.0,
    "test_disturbance.py": 19.0,
    "test_control.py": 19.0,
    "test_tilt.py": 19.0,  # ~
    "test_body.py": 17.0,
    "test_ambiguity_cli.py": 17.0,
    "test_perception.py": 17.0,  # ~
    "test_reliability_hostile.py": 15.0,
    "test_sweep_knobs.py": 14.0,  # ~
    "test_logs_cli.py": 13.0,
    "test_logs.py": 10.0,
    "test_tilt_clip_excess.py": 10.0,
    "test_tilt_shock_recovery.py": 5.0,
    "test_newton.py": 28.0,
    "test_tahboub_experiments.py": 26.0,
    "test_cli_reproduce.py": 8.0,
    "test_tilt_noise.py": 3.4,
    "test_tilt_gap_bridge.py": 35.0,  # ~
}
DEFAULT_COST_S = 8.0


def unit_of(nodeid: str) -> str:
    """The work unit of a test: its file's group in :data:`UNITS`, else its file."""
    path = nodeid.split("::", 1)[0]
    return UNITS.get(PurePosixPath(path).name, path)


def cost_s(unit: str) -> float:
    return COST_S.get(PurePosixPath(unit).name, DEFAULT_COST_S)


def make_scheduler(config, log):
    """xdist's file scheduler with the work units above, most expensive first."""
    from xdist.scheduler import LoadFileScheduling

    class CostFirstScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return unit_of(nodeid)

        def _assign_work_unit(self, node) -> None:
            first = max(self.workqueue, key=lambda unit: (cost_s(unit), unit))
            self.workqueue.move_to_end(first, last=False)
            super()._assign_work_unit(node)

    return CostFirstScheduling(config, log)
