"""Reliability when a command is pointed at a hostile folder or input, one test (or a few) per
class, run in-process as :mod:`tests.test_reliability`'s cases:

* confinement: nothing outside the output is written (a symlink or hard link planted where an
  output goes, a folder link out of it) or shown (a report's figures named outside its folder);
  an existing output keeps its permissions;
* memory bounded by design: an HDF5 file declaring 10¹² rows, a line longer than any row (the
  limit lowered here so that the lines stay small), a sparse file of NULs, a results.json of
  gigabytes, a device or a pipe as input: each refused in one line before it is read;
* rows not lost: a line that is not UTF-8 text in a stream (standard input or a file) is one
  flagged row; concurrent runs on one output cannot mix (the second is refused);
* time: a clock that jumps (forward or back) is a break the stream re-acquires after, in
  ``tilt.Stream`` as in ``verticality stream``; date-times (NumPy, pandas, Python) are seconds;
  ``Stream.step`` takes any sequence of three numbers;
* edges: file names that are not valid in the locale are printed escaped; a scheduler address is
  checked before use, and one that never answers is refused within a timeout.
"""

from __future__ import annotations

import datetime as dt
import io
import math
import os
import socket
import stat
import sys
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from test_reliability import IMU_HEADER, MOTION_HEADER, imu_rows, motion_rows, run_cli
from test_reliability_commands import fake_experiments, one_line_refusal
from verticality import tilt
from verticality.core.errors import InputError
from verticality.io import lines as text_lines
from verticality.io.paths import atomic_output, folder_lock, write_atomic

PRIVATE = b"\x89PNG\r\n\x1a\nPRIVATE-PIXELS" * 4


def imu_csv(path: Path, n: int = 300, seed: int = 0) -> Path:
    import random

    path.write_text("\n".join([IMU_HEADER, *imu_rows(random.Random(seed), n)]) + "\n")
    return path


def motion_csv(path: Path, n: int = 120) -> Path:
    import random

    path.write_text("\n".join([MOTION_HEADER, *motion_rows(random.Random(1), n)]) + "\n")
    return path


def victim(d: Path) -> Path:
    v = d / "victim.txt"
    v.write_bytes(b"VICTIM")
    return v


# ------------------------------------------------------------------ the report's figures
def results_folder(d: Path, name: str = "alpha", figures=None) -> Path:
    """A results folder of one experiment ``name`` (its own figure drawn), the figures recorded
    as ``figures`` (default: its own)."""
    import json

    res = d / "res"
    (res / "alpha").mkdir(parents=True)
    own = res / "alpha" / "own.png"
    own.write_bytes(b"\x89PNG\r\n\x1a\nOWN")
    entry = {"metrics": {"x": 1.0}, "runtime": {"wall_s": 1.0},
             "figures": [str(own)] if figures is None else figures}
    (res / "results.json").write_text(json.dumps(
        {"experiments": {name: entry}, "provenance": {"mode": "quick"}}))
    return res


def private(d: Path) -> Path:
    (d / "private").mkdir()
    p = d / "private" / "holiday.png"
    p.write_bytes(PRIVATE)
    return p


@pytest.mark.parametrize("how", ["absolute", "dotdot", "experiment named ../private",
                                 "link in the folder"])
def test_the_report_shows_nothing_from_outside_its_folder(tmp_path, how):
    import base64

    secret = private(tmp_path)
    if how == "absolute":
        res = results_folder(tmp_path, figures=[str(secret)])
    elif how == "dotdot":
        res = results_folder(tmp_path, figures=["../private/holiday.png"])
    elif how == "experiment named ../private":
        res = results_folder(tmp_path, name="../private", figures=["holiday.png"])
    else:
        res = results_folder(tmp_path)
        (res / "alpha" / "own.png").unlink()
        (res / "alpha" / "own.png").symlink_to("../../private/holiday.png")
    code, out, err = run_cli(["report", str(res)])
    page = (res / "report.html").read_text()
    assert code == 0, err
    assert "PRIVATE-PIXELS" not in page and base64.b64encode(PRIVATE).decode()[:40] not in page
    assert "figure not shown" in page or "figure missing" in page
    # each figure that was not read for where it lies is named on stderr, one line each
    assert err and all(line.startswith("warning: ") for line in err.strip().splitlines())


def test_a_figure_inside_the_folder_is_embedded_wherever_it_was_recorded(tmp_path):
    """The recorded path of a normal run (absolute, or relative to where reproduce ran) still
    finds the figure beside results.json."""
    res = results_folder(tmp_path)
    code, _, err = run_cli(["report", str(res)])
    assert code == 0 and err == ""
    assert (res / "report.html").read_text().count("data:image/png;base64,") == 1


# ------------------------------------------------------------------ links where outputs go
@pytest.fixture(scope="module")
def planted(tmp_path_factory):
    """Each output of an ``estimate --plot`` run planted with a link to a file outside (the
    estimate) and to a missing one (the figure); one run for both (one compilation)."""
    d = tmp_path_factory.mktemp("planted")
    v = victim(d)
    csv = imu_csv(d / "in.csv")
    (d / "out").mkdir()
    (d / "out" / "e.csv").symlink_to("../victim.txt")
    (d / "out" / "p.png").symlink_to("../created-outside.png")
    code, out, err = run_cli(["estimate", str(csv), "--out", str(d / "out" / "e.csv"),
                              "--plot", str(d / "out" / "p.png")])
    return d, v, code, err


def test_an_estimate_replaces_a_planted_link_and_leaves_its_target(planted):
    d, v, code, err = planted
    assert code == 0, err
    assert v.read_bytes() == b"VICTIM" and not (d / "created-outside.png").exists()
    for name in ("e.csv", "p.png"):
        assert not (d / "out" / name).is_symlink() and (d / "out" / name).is_file()
    assert len((d / "out" / "e.csv").read_text().splitlines()) == 301
    assert sorted(p.name for p in (d / "out").iterdir()) == ["e.csv", "p.png"]  # no .part left


@pytest.mark.parametrize("argv", [
    ["report", "{res}"],
    ["report", "{res}", "--out", "{d}/page.html"],
    ["motion", "still", "--duration", "0.1", "--out", "{d}/page.html"],
])
@pytest.mark.parametrize("link", ["symlink", "hard link"])
def test_no_output_is_written_through_a_link(tmp_path, argv, link):
    v = victim(tmp_path)
    res = results_folder(tmp_path)
    target = res / "report.html" if argv[-1] == "{res}" else tmp_path / "page.html"
    if link == "symlink":
        target.symlink_to(os.path.relpath(v, target.parent))
    else:
        os.link(v, target)
    code, _, err = run_cli([a.format(res=res, d=tmp_path) for a in argv])
    assert code == 0, err
    assert v.read_bytes() == b"VICTIM"
    assert target.is_file() and not target.is_symlink() and target.stat().st_size > 6


def test_a_folder_link_out_of_the_output_is_refused(tmp_path):
    """A link planted where a command makes a folder inside its output (reproduce's figure
    folder, a folder run's rows, a sweep's parts) would take its files out: refused in one line,
    nothing written there."""
    from test_sweep import TINY
    from verticality.sweep import distribute
    from verticality.sweep import spec as S

    (tmp_path / "elsewhere").mkdir()
    res = tmp_path / "res"
    res.mkdir()
    (res / "alpha").symlink_to("../elsewhere")
    from verticality.io.paths import confined_folder

    with pytest.raises(InputError, match="leads out of the folder"):
        confined_folder(res, "alpha")
    recs = tmp_path / "recs"
    recs.mkdir()
    imu_csv(recs / "a.csv")
    out = tmp_path / "o"
    out.mkdir()
    (out / "rows").symlink_to("../elsewhere")
    code, _, err = run_cli(["estimate", str(recs), "--out", str(out)])
    assert one_line_refusal(code, err) and "leads out of the folder" in err
    sw = tmp_path / "sw"
    sw.mkdir()
    (sw / "parts").symlink_to("../elsewhere")
    with pytest.raises(InputError, match="leads out of the folder"):
        distribute.run(S.parse(TINY), sw, workers=1, progress=False)
    assert list((tmp_path / "elsewhere").iterdir()) == []


def test_an_output_keeps_its_permissions_and_a_new_one_follows_the_umask(tmp_path):
    out = tmp_path / "private.csv"
    write_atomic(out, lambda tmp: tmp.write_text("one"))
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~_umask()
    out.chmod(0o600)
    write_atomic(out, lambda tmp: tmp.write_text("two"))
    assert stat.S_IMODE(out.stat().st_mode) == 0o600 and out.read_text() == "two"
    res = results_folder(tmp_path)
    assert run_cli(["report", str(res)])[0] == 0
    (res / "report.html").chmod(0o640)
    assert run_cli(["report", str(res)])[0] == 0
    assert stat.S_IMODE((res / "report.html").stat().st_mode) == 0o640


def _umask() -> int:
    old = os.umask(0o022)
    os.umask(old)
    return old


def test_a_figure_never_goes_through_a_link(tmp_path):
    """Every figure is drawn by ``core.plots.save`` (estimate --plot, sweep-plot, reproduce)."""
    from verticality.core import plots

    v = victim(tmp_path)
    (tmp_path / "f.svg").symlink_to("victim.txt")
    fig, axes = plots.new_figure()
    axes[0, 0].plot([0, 1], [0, 1])
    plots.save(fig, tmp_path / "f.svg")
    assert v.read_bytes() == b"VICTIM" and (tmp_path / "f.svg").read_text().startswith("<?xml")


# ------------------------------------------------------------------ memory bounded by design
def huge_hdf5(path: Path, huge: tuple[str, ...]) -> Path:
    """A BROAD-layout HDF5 file (a few kB) whose datasets ``huge`` declare 10¹² rows (chunked,
    never written: the fill value), the others 100."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, cols in (("imu_gyr", 3), ("imu_acc", 3), ("opt_quat", 4)):
            if name in huge:
                f.create_dataset(name, shape=(10**12, cols), dtype="f8", chunks=(1024, cols),
                                 fillvalue=0.0)
            else:
                f.create_dataset(name, data=np.zeros((100, cols)))
        f.attrs["sampling_rate"] = 100.0
    return path


@pytest.mark.parametrize("huge, argv, what", [
    (("imu_gyr", "imu_acc", "opt_quat"), ["estimate", "{f}", "--out", "{d}/o.csv"], "GiB"),
    (("imu_acc",), ["motion", "{f}", "--out", "{d}/m.csv"], "shape (1000000000000, 3)"),
    (("opt_quat",), ["estimate", "{f}", "--out", "{d}/o.csv"], "shape (1000000000000, 4)"),
])
def test_an_hdf5_file_declaring_1e12_rows_is_refused_before_it_is_read(tmp_path, huge, argv,
                                                                      what):
    f = huge_hdf5(tmp_path / "huge.hdf5", huge)
    code, _, err = run_cli([a.format(f=f, d=tmp_path) for a in argv])
    assert one_line_refusal(code, err) and what in err, err
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "m.csv").exists()


@pytest.fixture
def short_lines(monkeypatch):
    """Lines longer than 2000 characters are too long (the default is 1 Mi characters)."""
    monkeypatch.setattr(text_lines, "MAX_LINE_CHARS", 2000)
    return 2000


def _with_line(path: Path, line: bytes, at: int = 150, n: int = 300) -> Path:
    import random

    rows = imu_rows(random.Random(2), n)
    raw = [(IMU_HEADER + "\n").encode()] + [(r + "\n").encode() for r in rows]
    raw.insert(1 + at, line + b"\n")
    path.write_bytes(b"".join(raw))
    return path


@pytest.mark.parametrize("command", ["estimate", "otolith"])
def test_a_line_longer_than_any_row_is_refused_naming_it(tmp_path, short_lines, command):
    if command == "estimate":
        f = _with_line(tmp_path / "in.csv", b"1," * 5000 + b"1")
        argv = ["estimate", str(f), "--out", str(tmp_path / "o.csv")]
    else:
        f = motion_csv(tmp_path / "m.csv")
        f.write_bytes(f.read_bytes() + b"0.5," * 3000 + b"\n")
        argv = ["otolith", str(f), "--out", str(tmp_path / "o.csv")]
    code, _, err = run_cli(argv)
    assert one_line_refusal(code, err) and "longer than any row" in err
    assert "line 152" in err if command == "estimate" else "line 122" in err


def test_a_sparse_file_of_nuls_a_device_and_a_pipe_are_refused_at_once(tmp_path):
    """A 2 GiB sparse file (no disk used) is one line of NULs: refused after its first
    mebi-character, not read whole; a device and a named pipe (which would block until a writer
    comes) are no recording files; a results.json of 2 GiB is no results file."""
    zeros = tmp_path / "zeros.csv"
    with open(zeros, "wb") as fh:
        fh.truncate(2 * 2**30)
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    for src, what in ((zeros, "longer than any row"), ("/dev/zero", "character device"),
                      (fifo, "pipe")):
        code, _, err = run_cli(["estimate", str(src), "--out", str(tmp_path / "o.csv")])
        assert one_line_refusal(code, err) and what in err, err
    code, _, err = run_cli(["stream", "/dev/zero"])  # a stream may be a device: its header is not
    assert one_line_refusal(code, err) and "line 1: longer than any row" in err
    res = tmp_path / "res"
    res.mkdir()
    with open(res / "results.json", "wb") as fh:
        fh.truncate(2 * 2**30)
    code, _, err = run_cli(["report", str(res)])
    assert one_line_refusal(code, err) and "larger than any results file" in err


def test_read_line_holds_at_most_its_limit():
    fh = io.StringIO("a,b\n" + "x" * 10_000 + "\n1,2\n" + "y" * 50 + "\n")
    got = list(text_lines.lines(fh, limit=100, skip_rest=True))
    assert [len(g.text) for g in got] == [3, 100, 3, 50]
    assert got[1].problem.startswith("a line of 10000 characters")
    assert [g.problem for g in got[2:]] == [None, None]
    fh = io.StringIO("a,b\n" + "x" * 10_000 + "\n1,2\n")
    got = list(text_lines.lines(fh, limit=100))  # a file's reader stops at the refused line
    assert len(got) == 2 and got[1].left and fh.tell() < 200


# ------------------------------------------------------------------ rows not lost
def _stream_bytes(argv: list[str], raw: bytes):
    """``verticality stream`` reading ``raw`` as bytes on its standard input."""
    stdin = io.TextIOWrapper(io.BytesIO(raw), encoding="utf-8", errors="strict")
    old = sys.stdin
    sys.stdin = stdin
    try:
        return run_cli(["stream", *argv])
    finally:
        sys.stdin = old


def _rows_and_flags(out: str) -> np.ndarray:
    return np.array([int(r.split(",")[9]) for r in out.splitlines()[1:] if r])


@pytest.mark.parametrize("source", ["stdin", "file"])
def test_a_line_that_is_not_utf8_is_one_flagged_row_of_a_stream(tmp_path, short_lines, source):
    """A binary line and a line too long after the held-back head: each is written as a flagged
    row and named; no row is lost (standard input read as bytes, like a file)."""
    import random

    rows = [r.encode() for r in imu_rows(random.Random(2), 300)]
    rows.insert(200, b"\xff\xfe\x00\x81garbage\xc3\x28,1,2")
    rows.insert(250, b"7," * 3000)  # too long, mid-stream
    raw = b"\n".join([IMU_HEADER.encode(), *rows]) + b"\n"
    f = tmp_path / "in.csv"
    f.write_bytes(raw)
    code, out, err = (_stream_bytes([], raw) if source == "stdin"
                      else run_cli(["stream", str(f)]))
    assert code == 0, err
    flags = _rows_and_flags(out)
    assert flags.size == 302
    assert np.flatnonzero(flags & tilt.BAD_DT).tolist() == [200, 250]
    assert "line 202: not UTF-8 text (byte 0xff" in err and "line 252: a line of 6000" in err


def test_an_estimate_names_the_line_that_is_not_utf8(tmp_path):
    f = _with_line(tmp_path / "in.csv", b"0.5,\xff,0,0,0,0,9.8", at=100)
    code, _, err = run_cli(["estimate", str(f), "--out", str(tmp_path / "o.csv")])
    assert one_line_refusal(code, err) and "line 102: not UTF-8 text (byte 0xff" in err
    assert not (tmp_path / "o.csv").exists()
    comment = _with_line(tmp_path / "c.csv", "# Messung von Jürgen".encode("latin-1"), at=50)
    code, _, err = run_cli(["estimate", str(comment), "--out", str(tmp_path / "o.csv")])
    assert code == 0, err  # a comment line is skipped, whatever its encoding


def test_two_writers_of_one_output_never_mix(tmp_path):
    """While one run writes an output (its temporary file locked), a second one is refused in one
    line and the output is left as it was; a temporary file left by a killed run (not locked) is
    taken over."""
    out = tmp_path / "o.csv"
    out.write_text("EARLIER")
    csv = imu_csv(tmp_path / "in.csv")
    with atomic_output(out) as tmp:
        tmp.write_text("half of the first run's rows")
        with pytest.raises(InputError, match="another run is writing this file"):
            with atomic_output(out):
                pass
        code, _, err = run_cli(["estimate", str(csv), "--out", str(out)])
        assert one_line_refusal(code, err) and "another run is writing" in err
        assert out.read_text() == "EARLIER"
    assert out.read_text() == "half of the first run's rows"
    (tmp_path / "o.csv.part").write_text("left by a run that was killed")
    code, _, err = run_cli(["estimate", str(csv), "--out", str(out)])
    assert code == 0, err
    assert len(out.read_text().splitlines()) == 301 and not (tmp_path / "o.csv.part").exists()


def test_a_link_or_a_pipe_planted_as_the_temporary_file_is_refused(tmp_path):
    v = victim(tmp_path)
    out = tmp_path / "o.csv"
    (tmp_path / "o.csv.part").symlink_to("victim.txt")
    with pytest.raises(InputError, match="not a file this program wrote"):
        write_atomic(out, lambda tmp: tmp.write_text("x"))
    (tmp_path / "o.csv.part").unlink()
    os.mkfifo(tmp_path / "o.csv.part")
    with pytest.raises(InputError, match="not a file this program wrote"):
        write_atomic(out, lambda tmp: tmp.write_text("x"))
    assert v.read_bytes() == b"VICTIM" and not out.exists()


def test_two_runs_into_one_output_folder_never_mix(tmp_path, monkeypatch):
    """reproduce, sweep and a folder's estimate hold their output folder: a second run into it
    is refused in one line before it starts."""
    from test_sweep import TINY

    fake_experiments(monkeypatch, ["alpha"])
    recs = tmp_path / "recs"
    recs.mkdir()
    imu_csv(recs / "a.csv")
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY)
    out = tmp_path / "out"
    out.mkdir()
    with folder_lock(out):
        for argv in (["reproduce", "alpha", "--quick", "--jobs", "1", "--out", str(out)],
                     ["estimate", str(recs), "--out", str(out)],
                     ["sweep", str(spec), "--out", str(out), "--workers", "1"]):
            code, _, err = run_cli(argv)
            assert one_line_refusal(code, err) and "another run is writing this folder" in err
        assert list(out.iterdir()) == []


# ------------------------------------------------------------------ time and the API
def _acc(deg: float) -> list[float]:
    a = math.radians(deg)
    return [0.0, 9.81 * math.sin(a), 9.81 * math.cos(a)]


@pytest.mark.parametrize("jump_s", [1.7e9, 1e7, -1000.0, -0.5])
def test_a_clock_jump_is_a_break_the_stream_reacquires_after(jump_s):
    """A device that sets its clock: 10 s upright, then the clock jumps (forward by more than
    any step, or back) while the sensor is tilted 58°. The stamp at the jump is skipped, the
    next one confirms the new clock and is taken as a gap: the tilt is re-acquired."""
    s = tilt.Stream(period_s=0.01)
    t = 0.0
    for _ in range(1000):
        s.step([0, 0, 0], _acc(0.0), t)
        t += 0.01
    t += jump_s
    flags = []
    for _ in range(800):
        e = s.step([0, 0, 0], _acc(58.0), t)
        flags.append(e.flags)
        t += 0.01
    assert flags[0] & tilt.BAD_DT and flags[1] & tilt.DT_GAP
    assert any(f & tilt.REACQUIRED for f in flags)
    assert abs(math.degrees(e.roll_rad) - 58.0) < 0.5


def test_verticality_stream_reacquires_after_a_clock_set_back(tmp_path):
    import random

    rows = imu_rows(random.Random(3), 400)
    later = [",".join([f"{float(r.split(',')[0]) - 5000:.2f}"] + r.split(",")[1:])
             for r in imu_rows(random.Random(4), 400)]
    code, out, err = run_cli(["stream"], "\n".join([IMU_HEADER, *rows, *later]) + "\n")
    assert code == 0, err
    flags = _rows_and_flags(out)
    assert flags.size == 800 and flags[400] & tilt.BAD_DT and flags[401] & tilt.DT_GAP


def test_stream_step_takes_any_sequence_of_three_numbers():
    df = pd.DataFrame({"gx": [0.01] * 50, "gy": 0.0, "gz": 0.0, "ax": 0.0,
                       "ay": 9.81 * math.sin(0.5), "az": 9.81 * math.cos(0.5)})
    a, b = tilt.Stream(period_s=0.01), tilt.Stream(period_s=0.01)
    for _, row in df.iterrows():  # labelled rows: read by position, not by label
        ea = a.step(row[["gx", "gy", "gz"]], row[["ax", "ay", "az"]])
        eb = b.step(row.to_numpy()[:3].tolist(), tuple(row.to_numpy()[3:]))
    assert ea.roll_rad == eb.roll_rad and ea.flags == eb.flags
    s = tilt.Stream(period_s=0.01)
    s.step(np.zeros((1, 3)), np.array([[0.0, 0.0, 9.81]]))  # (1, 3): three numbers
    for bad in ([0, 0], [0, 0, 0, 0], "abc", None, {"x": 1}, [["a", "b", "c"]]):
        with pytest.raises(InputError, match="three numbers") as info:
            s.step(bad, [0, 0, 9.81])
        assert "\n" not in str(info.value)


N_STAMPS = 600


@pytest.fixture(scope="module")
def swinging():
    k = np.arange(N_STAMPS)
    ang = math.radians(30) + math.radians(15) * np.sin(2 * np.pi * 0.3 * k * 0.01)
    rate = math.radians(15) * 2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * k * 0.01)
    gyr = np.stack([rate, 0 * k, 0 * k], 1)
    acc = np.stack([0 * k, 9.81 * np.sin(ang), 9.81 * np.cos(ang)], 1)
    ref = tilt.estimate(gyr, acc, k * 0.01)  # (steps of 0.01 s to ~1e-18 s)
    return gyr, acc, ref


START = "2024-05-01 12:00"
SECONDS = pd.Timestamp(START, tz="UTC").timestamp()


@pytest.mark.parametrize("stamps", [
    lambda: pd.date_range(START, periods=N_STAMPS, freq="10ms"),
    lambda: pd.Series(pd.date_range(START, periods=N_STAMPS, freq="10ms")),
    lambda: pd.date_range("2024-05-01 14:00", periods=N_STAMPS, freq="10ms", tz="Europe/Berlin"),
    lambda: np.datetime64(START) + np.arange(N_STAMPS) * np.timedelta64(10, "ms"),
    lambda: [dt.datetime(2024, 5, 1, 12, tzinfo=dt.UTC) + dt.timedelta(milliseconds=10 * i)
             for i in range(N_STAMPS)],
    lambda: pd.timedelta_range(0, periods=N_STAMPS, freq="10ms"),
], ids=["DatetimeIndex", "datetime64 Series", "tz-aware", "numpy datetime64",
        "Python datetime", "TimedeltaIndex"])
def test_date_times_are_seconds(swinging, stamps):
    gyr, acc, ref = swinging
    out = tilt.estimate(gyr, acc, stamps())
    assert not np.any(out.flags & tilt.BAD_DT)
    np.testing.assert_allclose(out.roll_rad, ref.roll_rad, rtol=0, atol=1e-9)
    start = 0.0 if isinstance(stamps(), pd.TimedeltaIndex) else SECONDS
    np.testing.assert_allclose(out.t_s, start + np.arange(N_STAMPS) * 0.01, rtol=0, atol=1e-6)


def test_stream_stamps_may_be_date_times_and_bad_ones_are_one_line():
    s = tilt.Stream()
    t0 = pd.Timestamp(START, tz="UTC")
    for k in range(5):
        e = s.step((0, 0, 0), _acc(10.0), t0 + pd.Timedelta(milliseconds=10 * k))
    e = s.step((0, 0, 0), _acc(10.0), np.datetime64(START) + np.timedelta64(50, "ms"))
    assert not e.flags & tilt.BAD_DT and e.t_s == pytest.approx(SECONDS + 0.05)
    for bad in (np.datetime64("NaT"), "noon", dt.time(12)):
        with pytest.raises(InputError) as info:
            s.step((0, 0, 0), _acc(10.0), bad)
        assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="NaT"):
        tilt.estimate(np.zeros((3, 3)), np.ones((3, 3)),
                      np.array(["2024-01-01", "NaT", "2024-01-02"], dtype="datetime64[ns]"))


# ------------------------------------------------------------------ edges
def test_a_file_name_not_valid_in_the_locale_is_printed_escaped(tmp_path, monkeypatch):
    out = Path(os.fsdecode(os.fsencode(tmp_path) + b"/out\xff.csv"))
    csv = imu_csv(tmp_path / "in.csv")
    raw = io.BytesIO()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(raw, encoding="utf-8", errors="strict"))
    from verticality import cli

    code = cli.main(["motion", "still", "--duration", "0.1", "--out", str(out)])
    sys.stdout.flush()
    assert code == 0 and b"out\\udcff.csv" in raw.getvalue()
    assert sys.stdout.errors == "strict"  # the stream as it was
    assert out.exists() and csv.exists()


BAD_ADDRESSES = ["127.0.0.1", "tcp://127.0.0.1", "127.0.0.1:abc", "tcp://127.0.0.1:99999",
                 "tcp://:8786", "foo://x:1"]


@pytest.mark.parametrize("address", BAD_ADDRESSES)
def test_a_scheduler_address_is_checked_before_anything_is_written(tmp_path, address):
    recs = tmp_path / "recs"
    recs.mkdir()
    imu_csv(recs / "a.csv")
    code, _, err = run_cli(["estimate", str(recs), "--out", str(tmp_path / "o"),
                            "--scheduler", address])
    assert one_line_refusal(code, err) and "--scheduler" in err
    assert not (tmp_path / "o").exists()


def test_a_scheduler_that_never_answers_is_refused_within_the_timeout(tmp_path, monkeypatch):
    """A server that accepts and never answers, and an address where nothing listens: one line
    each within the (here shortened) timeout, before the output folder is made."""
    from test_sweep import TINY
    from verticality.sweep import engine

    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held = []
    threading.Thread(target=lambda: held.extend(server.accept() for _ in range(4)),
                     daemon=True).start()
    closed = socket.socket()
    closed.bind(("127.0.0.1", 0))
    free_port = closed.getsockname()[1]
    closed.close()
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY)
    try:
        for port, what in ((server.getsockname()[1], "no answer within 1 s"),
                           (free_port, "cannot connect (Connection refused)")):
            code, _, err = run_cli(["sweep", str(spec), "--out", str(tmp_path / "sw"),
                                    "--scheduler", f"127.0.0.1:{port}"])
            assert code == 2 and what in err and "--scheduler" in err, err
            assert len(err.strip().splitlines()) == 1
            assert not (tmp_path / "sw").exists()
    finally:
        server.close()
