"""`reproduce --jobs N`: experiments in worker processes give the results of the in-process run,
in the same order; the order and the time left come from expected costs; `--jobs` is checked; the
progress prints one plain line per finished experiment when standard error is not a terminal;
Ctrl-C ends the workers with one line and status 130."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from verticality import cli
from verticality.report import costs as experiment_costs
from verticality.report.progress import Tracker
from verticality.report.runs import run_experiments

CHEAP = ["tahboub-step", "tahboub-gains", "perception-yaw"]  # deliberately not in registry order


def _strip_runtime(results: dict) -> dict:
    """The results without what may differ between two runs: wall times and figure folders."""
    out = {}
    for name, entry in results["experiments"].items():
        out[name] = {k: v for k, v in entry.items() if k not in ("runtime", "figures")}
        out[name]["simulated_s"] = entry["runtime"]["simulated_s"]
        out[name]["figures"] = sorted(Path(f).relative_to(Path(f).parents[1]).as_posix()
                                      for f in entry.get("figures", []))
    return out


def test_parallel_run_gives_the_serial_results_in_the_same_order(tmp_path):
    serial = run_experiments(CHEAP, quick=True, out_dir=tmp_path / "serial", jobs=1)
    stages = []
    parallel = run_experiments(CHEAP, quick=True, out_dir=tmp_path / "parallel", jobs=2,
                               on_stage=lambda n, s: stages.append((n, s)))
    assert list(parallel["experiments"]) == CHEAP == list(serial["experiments"])
    assert _strip_runtime(parallel) == _strip_runtime(serial)  # every metric, bit for bit
    assert parallel["registry"] == serial["registry"]
    saved = json.loads((tmp_path / "parallel" / "results.json").read_text())
    assert saved["experiments"].keys() == parallel["experiments"].keys()
    assert _strip_runtime(saved) == _strip_runtime(serial)
    for name in CHEAP:  # each told running, then done, figures drawn by the worker
        told = [s for n, s in stages if n == name]
        assert told[0] == "running" and told[-1] == "done"
        figures = parallel["experiments"][name].get("figures", [])
        assert all(Path(f).is_file() and Path(f).parent == tmp_path / "parallel" / name
                   for f in figures)


def test_expected_costs_previous_run_then_table_then_median(tmp_path):
    table = {"a": 10.0, "b": 2.0, "c": 4.0}
    assert experiment_costs.expected_wall_s(["a", "new"], True, None, table) == {"a": 10.0,
                                                                                  "new": 4.0}
    # the previous run into the same folder, same mode, comes first
    (tmp_path / "results.json").write_text(json.dumps({
        "provenance": {"mode": "quick"},
        "experiments": {"new": {"runtime": {"wall_s": 30.0, "simulated_s": 1.0}}}}))
    assert experiment_costs.expected_wall_s(["a", "new"], True, tmp_path, table) == {
        "a": 10.0, "new": 30.0}
    # ... but not a run of the other mode, nor a file that is not a results object
    assert experiment_costs.expected_wall_s(["new"], False, tmp_path, table) == {"new": 4.0}
    (tmp_path / "results.json").write_text("[1, 2")
    assert experiment_costs.expected_wall_s(["new"], True, tmp_path, table) == {"new": 4.0}
    # every registered experiment gets a positive estimate from the stored tables
    from verticality import experiments

    for quick in (False, True):
        costs = experiment_costs.expected_wall_s(experiments.discover(), quick)
        assert all(v > 0 for v in costs.values())


def test_longest_first_and_time_left():
    expected = {"a": 10.0, "b": 6.0, "c": 4.0, "d": 3.0}
    order = experiment_costs.longest_first(expected)
    assert order == ["a", "b", "c", "d"]
    assert experiment_costs.longest_first({"x": 1.0, "w": 1.0}) == ["w", "x"]
    # two workers: a | b, c (10) | d on the first free: 13
    assert experiment_costs.time_left(expected, {}, order, jobs=2) == 13.0
    assert experiment_costs.time_left(expected, {}, order, jobs=1) == 23.0
    # a running 4 s, b 6 s (its estimate used up: ends now), c and d waiting
    assert experiment_costs.time_left(expected, {"a": 4.0, "b": 6.0}, ["c", "d"], 2) == 7.0
    assert experiment_costs.time_left(expected, {}, [], jobs=2) == 0.0


def test_tracker_says_what_is_done_running_and_left():
    now = [0.0]
    names = ["a", "b", "c"]
    t = Tracker(names, quick=True, jobs=2, clock=lambda: now[0])
    t.expected = {"a": 10.0, "b": 4.0, "c": 2.0}
    assert t.headline() == "reproduce: 0/3 done, 0 running"
    assert t.pace() == 1.0 and t.time_left() == 10.0
    t.stage("a", "running")
    t.stage("b", "running")
    now[0] = 8.0
    t.stage("b", "done")  # 8 s where 4 were expected, with a typical one (4 s) at pace 1: 1.5
    assert t.pace() == 1.5
    assert t.headline() == "reproduce: 1/3 done, 1 running"
    assert t.time_left() == 7.0  # a: 15 - 8; c (3) on the free worker meanwhile
    assert t.done_line("b") == "done 1/3: b (8 s); about 7 s left"
    t.stage("c", "running")
    now[0] = 75.0
    t.stage("a", "figures")
    t.stage("a", "done")
    t.stage("c", "done")
    assert t.done_line("c") == "done 3/3: c (1 min 07 s)"


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", ""])
def test_jobs_must_be_a_whole_number_at_least_1(value, capsys):
    assert cli.main(["reproduce", "tahboub-gains", "--jobs", value, "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and "--jobs" in captured.err


def test_progress_is_one_plain_line_per_finished_experiment_when_piped(capsys):
    names = ["tahboub-gains", "perception-post-rotatory-tilt"]
    assert cli.main(["reproduce", *names, "--quick", "--json", "--jobs", "1"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(":")[0] for line in lines] == ["done 1/2", "done 2/2"]
    assert lines[0].startswith("done 1/2: tahboub-gains (") and " left" in lines[0]
    assert lines[1].startswith("done 2/2: perception-post-rotatory-tilt (")  # never cut
    assert lines[1].endswith(" s)")


def _group_members(pgid: int, only: str = "") -> list[int]:
    """The live processes of process group ``pgid`` (whose command line holds ``only``)."""
    members = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                cmdline = (entry / "cmdline").read_bytes().decode(errors="replace")
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] != "Z" and only in cmdline:
                members.append(int(entry.name))
    return members


def _start_parallel_run(tmp_path) -> subprocess.Popen:
    """`reproduce ekf-impact ekf-jump --jobs 2` (minutes each) in a session of its own, once its
    two workers exist."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parents[1] / "src"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "verticality", "reproduce", "ekf-impact", "ekf-jump",
         "--jobs", "2", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=env, cwd=tmp_path, start_new_session=True)
    deadline = time.monotonic() + 120
    while (len(_group_members(proc.pid, "spawn_main")) < 2 and proc.poll() is None
           and time.monotonic() < deadline):
        time.sleep(0.2)
    if len(_group_members(proc.pid, "spawn_main")) != 2:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("the two workers did not start")
    return proc


def _wait_group_gone(pgid: int, timeout_s: float = 20.0) -> list[int]:
    deadline = time.monotonic() + timeout_s
    while _group_members(pgid) and time.monotonic() < deadline:
        time.sleep(0.2)
    return _group_members(pgid)


needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="needs /proc to see the workers")


@needs_proc
def test_ctrl_c_ends_the_workers_with_one_line_and_status_130(tmp_path):
    proc = _start_parallel_run(tmp_path)
    try:
        time.sleep(3.0)  # importing, compiling: well before either experiment ends
        os.killpg(proc.pid, signal.SIGINT)  # what a terminal does on Ctrl-C
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    assert err.splitlines()[-1] == "verticality reproduce: interrupted"  # the CLI's one line
    assert "Traceback" not in err and out == ""
    assert _wait_group_gone(proc.pid) == []  # no worker left behind


@needs_proc
def test_the_workers_end_when_the_command_is_killed(tmp_path):
    proc = _start_parallel_run(tmp_path)
    try:
        proc.kill()  # the command only: no chance to end its workers itself
        proc.wait(timeout=60)
        assert _wait_group_gone(proc.pid) == []
    finally:
        for pid in _group_members(proc.pid):
            os.kill(pid, signal.SIGKILL)
        proc.communicate()


def test_default_jobs_one_per_core_as_memory_allows(monkeypatch):
    from verticality.report import pool as experiment_pool

    monkeypatch.setattr(experiment_pool.os, "sched_getaffinity", lambda pid: {0, 1, 2, 3},
                        raising=False)
    gib = 2**30
    for available, jobs in ((64 * gib, 4), (9 * gib, 2), (5 * gib, 1), (1 * gib, 1), (None, 4)):
        monkeypatch.setattr(experiment_pool, "_available_memory_bytes", lambda a=available: a)
        assert experiment_pool.default_jobs() == jobs
