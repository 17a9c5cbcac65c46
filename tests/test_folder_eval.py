"""`verticality estimate FOLDER` and `evaluate broad --workers/--scheduler`: one output per
recording equal to the single-file estimate, a bad file as a row with its error, the summary
table, resume, and a real local Dask cluster of two worker processes."""

from __future__ import annotations

import csv
import json
import sys

import h5py
import numpy as np
import pytest

from imu_cases import tumbling
from verticality import cli
from verticality.core.errors import InputError
from verticality.io import imu
from verticality.tilt import folder
from verticality.tilt.evaluation.broad import evaluate_trials
from verticality.tilt.files import estimate_file, settled_samples
from verticality.tilt.flags import FLAG_NAMES

BAD = "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.81\nnot a number,0,0,0,0,0,9.81\n"


def _recordings(folder_path):
    """Three short tumbling recordings (the second with five missing accelerometer samples and a
    0.5 s gap: the 50 samples the sensor took while it turned on are missing, so its readings
    jump across the gap) and one file that is not an IMU CSV."""
    folder_path.mkdir()
    for i, n in enumerate((400, 400, 400)):
        lost = 50 if i == 1 else 0
        gyr, acc, _ = tumbling(np.array([0.01, -0.02, 0.0]), n + lost, seed=i)
        gone = np.s_[200:200 + lost]
        gyr, acc = np.delete(gyr, gone, axis=0), np.delete(acc, gone, axis=0)
        t = np.arange(n) * 0.01
        if i == 1:
            acc[100:105] = np.nan
            t[200:] += 0.5
        imu.write_imu_csv(folder_path / f"rec{i}.csv", imu.ImuRecording(t, gyr, acc))
    (folder_path / "broken.csv").write_text(BAD)
    (folder_path / "notes.txt").write_text("not a recording")  # not picked up
    return sorted(folder_path.glob("rec*.csv"))


@pytest.fixture(scope="module")
def in_process(tmp_path_factory):
    """The folder estimated in this process (with σ), and each recording's single-file estimate."""
    root = tmp_path_factory.mktemp("folder")
    recs = _recordings(root / "in")
    summary = folder.estimate_folder(root / "in", root / "out", sigma=True, progress=False)
    singles = {}
    for p in recs:
        estimate_file(p, root / "single" / p.name, sigma=True)
        singles[p.name] = (root / "single" / p.name).read_bytes()
    return root, summary, singles


def test_one_output_per_recording_equal_to_the_single_file_estimate(in_process):
    root, summary, singles = in_process
    assert sorted(p.name for p in (root / "out").glob("*.csv")) == sorted(
        ["rec0.csv", "rec1.csv", "rec2.csv", "summary.csv"])
    for name, single in singles.items():
        assert (root / "out" / name).read_bytes() == single  # bit for bit, σ column included
    assert [r["file"] for r in summary.rows] == [str(root / "in" / n) for n in
                                                  ("broken.csv", "rec0.csv", "rec1.csv",
                                                   "rec2.csv")]


def test_bad_file_is_a_row_with_its_error(in_process):
    root, summary, _ = in_process
    bad = summary.rows[0]
    assert (bad["status"] == "error" and "non-numeric cells at lines [3]" in bad["error"]
            and bad["output"] == "")
    assert bad["rows"] is None and bad["wall_s"] >= 0
    assert summary.n_errors == 1
    assert not (root / "out" / "broken.csv").exists()


def test_summary_table_columns_and_numbers(in_process):
    root, summary, _ = in_process
    with open(root / "out" / "summary.csv", encoding="utf-8") as fh:
        table = list(csv.DictReader(fh))
    assert tuple(table[0]) == folder.SUMMARY_COLUMNS
    assert json.loads((root / "out" / "summary.json").read_text()) == list(summary.rows)
    assert set(folder.FLAG_COLUMNS) == set(FLAG_NAMES)  # a column per flag bit
    for row, line in zip(summary.rows[1:], table[1:], strict=True):
        est = imu.read_estimate_csv(root / "out" / row["output"])
        assert row["status"] == line["status"] == "ok"
        assert row["rows"] == int(line["rows"]) == est.t_s.size
        assert row["duration_s"] == pytest.approx(est.t_s[-1] - est.t_s[0], rel=1e-12)
        for bit, col in folder.FLAG_COLUMNS.items():
            assert row[col] == np.count_nonzero(est.flags & bit), col
        assert row["share_flagged"] == pytest.approx(np.mean(est.flags != 0), rel=1e-12)
        sig = est.tilt_sigma_rad[settled_samples(est.flags)]
        assert row["mean_sigma_deg"] == pytest.approx(np.degrees(np.mean(sig)), rel=1e-6)
    rec1 = summary.rows[2]
    assert rec1["n_acc_missing"] == 5 and rec1["n_dt_gap"] == 1 and rec1["n_init"] == 1
    assert rec1["duration_s"] == pytest.approx(3.99 + 0.5, rel=1e-12)


def test_resume_recomputes_nothing_complete_and_refuses_other_options(in_process, tmp_path):
    root, summary, _ = in_process
    out = root / "out"
    stamps = {p.name: p.stat().st_mtime_ns for p in out.glob("rec*.csv")}
    again = folder.estimate_folder(root / "in", out, sigma=True, resume=True, progress=False)
    assert again.computed == (str(root / "in" / "broken.csv"),)  # only the one without output
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("rec*.csv")} == stamps
    assert [r["wall_s"] for r in again.rows[1:]] == [r["wall_s"] for r in summary.rows[1:]]
    with pytest.raises(InputError, match="already holds"):
        folder.estimate_folder(root / "in", out, sigma=True, progress=False)
    with pytest.raises(InputError, match="other options"):
        folder.estimate_folder(root / "in", out, resume=True, progress=False)
    # a torn output (its row not yet written) is computed again
    (out / "rows" / "rec2.csv.json").unlink()
    (out / "rec2.csv").write_text("t,roll")
    third = folder.estimate_folder(root / "in", out, sigma=True, resume=True, progress=False)
    assert third.computed == (str(root / "in" / "broken.csv"), str(root / "in" / "rec2.csv"))
    assert (out / "rec2.csv").read_bytes() == (root / "single" / "rec2.csv").read_bytes()


def test_folder_inputs_refused_before_work(tmp_path, capsys):
    d = tmp_path / "in"
    d.mkdir()
    (d / "a.csv").write_text(BAD)
    (d / "a.h5").write_text("x")
    with pytest.raises(InputError, match="would both be written to a.csv"):
        folder.estimate_folder(d, tmp_path / "out", progress=False)
    (d / "a.h5").unlink()
    with pytest.raises(InputError, match="is the input"):  # OUT/a.csv would be the recording
        folder.estimate_folder(d, d, progress=False)
    (d / "summary.csv").write_text(BAD)
    with pytest.raises(InputError, match="name of the summary table"):
        folder.estimate_folder(d, tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()
    for argv, words in ((["estimate", str(d), "--out", str(tmp_path / "o"), "--plot", "x.png"],
                         "--plot"),
                        (["estimate", str(d / "a.csv"), "--out", str(tmp_path / "e.csv"),
                          "--workers", "2"], "for a folder of recordings"),
                        (["estimate", str(d), "--out", str(tmp_path / "o"), "--workers", "0"],
                         "at least 1"),
                        (["estimate", str(d), "--out", str(tmp_path / "o"), "--filter", "vqf",
                          "--sigma"], "reports no uncertainty")):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err


def test_a_file_name_as_the_folder_output_is_refused(tmp_path, capsys):
    d = tmp_path / "in"
    d.mkdir()
    gyr, acc, _ = tumbling(np.zeros(3), 200)
    imu.write_imu_csv(d / "r.csv", imu.ImuRecording(np.arange(200) * 0.01, gyr, acc))
    assert cli.main(["estimate", str(d), "--out", str(tmp_path / "est.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "names a folder, not a .csv file" in err[0], err
    assert not (tmp_path / "est.csv").exists()
    assert cli.main(["estimate", str(d), "--out", str(tmp_path / "est")]) == 0
    assert (tmp_path / "est" / "r.csv").is_file()


def test_without_the_extra_the_distributed_path_says_what_to_install(tmp_path, monkeypatch,
                                                                     capsys):
    d = tmp_path / "in"
    d.mkdir()
    gyr, acc, _ = tumbling(np.zeros(3), 200)
    imu.write_imu_csv(d / "r.csv", imu.ImuRecording(np.arange(200) * 0.01, gyr, acc))
    (tmp_path / "b").mkdir()
    _broad_trial(tmp_path / "b" / "t.hdf5", 200, 0)
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` fails
    for argv in (["estimate", str(d), "--out", str(tmp_path / "o"), "--workers", "2"],
                 ["evaluate", "broad", str(tmp_path / "b"), "--workers", "2",
                  "--filters", "verticality"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "pip install 'verticality[sweep]'" in err[0], err
    assert not (tmp_path / "o").exists()
    # the serial path does not need it
    assert cli.main(["estimate", str(d), "--out", str(tmp_path / "o")]) == 0
    assert "1 recordings (1 computed now" in capsys.readouterr().out
    assert (tmp_path / "o" / "r.csv").is_file()


def test_engine_turns_a_failed_task_into_on_error():
    from verticality.sweep.engine import map_tasks

    calls = {"a": ("3",), "b": ("x",), "c": ("5",)}
    with pytest.raises(ValueError):
        map_tasks(int, calls, progress=False)
    got = map_tasks(int, calls, progress=False, on_error=lambda key, exc: type(exc).__name__)
    assert list(got.items()) == [("a", 3), ("b", "ValueError"), ("c", 5)]


def _broad_trial(path, n, seed):
    """A BROAD-layout trial: a sensor turning about x from 25° off the vertical, its optical
    orientation the truth, the second half scored."""
    from verticality.core import so3

    gyr, acc, _ = tumbling(np.array([0.005, 0.0, 0.0]), n, seed=seed)
    t = np.arange(n) * 0.01
    q0 = np.asarray(so3.quat_exp(np.array([0.0, np.radians(25.0), 0.0])))
    quat = np.stack([np.asarray(so3.quat_multiply(q0, so3.quat_exp(np.array([0.4 * tk, 0.0,
                                                                             0.0]))))
                     for tk in t])
    with h5py.File(path, "w") as f:
        f["imu_gyr"] = gyr
        f["imu_acc"] = acc
        f["opt_quat"] = quat
        f["movement"] = np.arange(n) >= n // 2
        f.attrs["sampling_rate"] = 100.0


def test_local_cluster_of_two_workers(in_process, tmp_path, capsys):
    """One real LocalCluster of two worker processes, reached by its address: the folder's
    outputs and table equal the in-process run's, and `evaluate broad` gives the serial table
    to the bit."""
    from distributed import LocalCluster

    root, summary, _ = in_process
    broad_dir = tmp_path / "broad"
    broad_dir.mkdir()
    _broad_trial(broad_dir / "a_trial.hdf5", 600, 1)
    _broad_trial(broad_dir / "b_trial.hdf5", 600, 2)
    filters = ["verticality", "verticality-offline"]
    serial = evaluate_trials(sorted(broad_dir.glob("*.hdf5")), filters)
    assert serial["trials"]["a_trial"]["verticality"] < 2.0  # a real estimate, scored
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        address = cluster.scheduler_address
        assert cli.main(["estimate", str(root / "in"), "--out", str(tmp_path / "out"), "--sigma",
                         "--scheduler", address]) == 1  # one recording failed
        dist = evaluate_trials(sorted(broad_dir.glob("*.hdf5")), filters, scheduler=address)
        from verticality.sweep.engine import map_tasks

        got = map_tasks(int, {"a": ("3",), "b": ("x",)}, scheduler=address, progress=False,
                        on_error=lambda key, exc: f"{key}: {type(exc).__name__}")
        assert got == {"a": 3, "b": "b: ValueError"}  # a failed task, the run goes on
        assert cli.main(["evaluate", "broad", str(broad_dir), "--json", "--filters", *filters,
                         "--scheduler", address]) == 0
    out = capsys.readouterr()
    assert "4 recordings (4 computed now" in out.out and "broken.csv" in out.err
    for name in ("rec0.csv", "rec1.csv", "rec2.csv"):
        assert (tmp_path / "out" / name).read_bytes() == (root / "out" / name).read_bytes()
    rows = json.loads((tmp_path / "out" / "summary.json").read_text())
    strip = [{k: v for k, v in r.items() if k not in ("wall_s", "file")} for r in rows]
    assert strip == [{k: v for k, v in r.items() if k not in ("wall_s", "file")}
                     for r in summary.rows]
    for key in ("trials", "mean", "sigma", "sigma_offline", "samples"):
        assert dist[key] == serial[key], key  # == on floats: bit for bit
    printed = json.loads(out.out[out.out.index("{"):])
    sigmas = {name: serial[key] for name, key in (("verticality", "sigma"),
                                                  ("verticality-offline", "sigma_offline"))
              if serial[key]}
    assert printed == {"trials": serial["trials"], "mean": serial["mean"], "sigma": sigmas}
