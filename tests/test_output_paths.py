"""Output paths are checked before the work: a folder or an unwritable place is refused in one
line, and the check leaves nothing behind."""

import pytest

from verticality import cli
from verticality.core.errors import InputError
from verticality.io.paths import check_writable_file


def test_check_writable_file(tmp_path):
    with pytest.raises(InputError, match="--out .*: is a folder; give a file name"):
        check_writable_file(tmp_path)
    blocker = tmp_path / "plain.txt"
    blocker.write_text("keep")
    with pytest.raises(InputError, match="--plot .*cannot write"):
        check_writable_file(blocker / "x.png", "--plot")  # a file where a folder should be
    assert check_writable_file(blocker) == blocker and blocker.read_text() == "keep"
    new = tmp_path / "sub" / "new.csv"
    assert check_writable_file(new) == new
    assert not new.exists() and new.parent.is_dir()


@pytest.mark.parametrize("argv", [
    ["motion", "impact", "--out", "{dir}"],
    ["estimate", "{csv}", "--out", "{dir}"],
    ["estimate", "{csv}", "--out", "{dir}/e.csv", "--plot", "{dir}"],
    ["otolith", "{csv}", "--out", "{dir}"],
    ["stabilize", "{csv}", "--out", "{dir}"],
    ["perceive", "{csv}", "--out", "{dir}"],
    ["perceive", "{csv}", "--plot", "{dir}"],
])
def test_commands_refuse_a_folder_as_output_before_working(tmp_path, capsys, argv):
    csv = tmp_path / "in.csv"
    csv.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.81\n0.01,0,0,0,0,0,9.81\n")
    args = [a.format(dir=tmp_path, csv=csv) for a in argv]
    assert cli.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "is a folder; give a file name" in err and len(err.splitlines()) == 1


def test_an_os_error_during_a_command_is_one_line(tmp_path, capsys, monkeypatch):
    """What the early check cannot foresee (a full disk) still ends in one line, status 2."""
    import errno

    from verticality.io import motion

    def full_disk(path, rec):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(motion, "write_motion_csv", full_disk)
    assert cli.main(["motion", "still", "--duration", "0.1", "--out", str(tmp_path / "m.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"verticality motion: error: No space left on device ({tmp_path / 'm.csv'})"


@pytest.mark.parametrize("command", [["estimate", "{f}", "--out", "{d}/e.csv"], ["stream", "{f}"],
                                     ["otolith", "{f}", "--out", "{d}/o.csv"], ["stabilize", "{f}"],
                                     ["perceive", "{f}"]])
def test_a_binary_file_is_one_line_not_a_traceback(tmp_path, capsys, command):
    f = tmp_path / "binary.csv"
    f.write_bytes(b"\xff\xfe\x00\x01 not text")
    assert cli.main([a.format(f=f, d=tmp_path) for a in command]) == 2
    err = capsys.readouterr().err.strip()
    # the line is named: "FILE: line 1: not UTF-8 text (byte 0xff at character 1)"
    assert "line 1: not UTF-8 text" in err and len(err.splitlines()) == 1


IMU_ROWS = "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n" + "".join(
    f"{k / 100:.2f},0,0,0,0,0,9.81\n" for k in range(300))


def _motion_csv(path):
    path.write_text("t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az\n"
                    + "".join(f"{k / 100:.2f},1,0,0,0,0,0,0,0,0,0\n" for k in range(100)))


@pytest.mark.parametrize("spelling", ["same", "dotdot", "symlink", "hardlink"])
@pytest.mark.parametrize("command", [
    ["estimate", "{inp}", "--out", "{out}"],
    ["estimate", "{inp}", "--out", "{d}/ok.csv", "--plot", "{out}"],
    ["otolith", "{motion}", "--out", "{out}"],
    ["stabilize", "{motion}", "--out", "{out}"],
    ["stabilize", "{motion}", "--plot", "{out}"],
])
def test_an_output_that_reaches_the_input_is_refused_before_any_work(tmp_path, capsys, spelling,
                                                                     command):
    """Under any spelling (the same path, ``sub/../``, a symlink, a hard link) an output that is
    the input is refused in one line, exit 2, and the input is left byte for byte."""
    import os

    (tmp_path / "sub").mkdir()
    inp = tmp_path / "rec.csv"
    inp.write_text(IMU_ROWS)
    motion = tmp_path / "motion.csv"
    _motion_csv(motion)
    target = motion if "{motion}" in command else inp
    out = {"same": str(target), "dotdot": f"{tmp_path}/sub/../{target.name}",
           "symlink": str(tmp_path / "link"), "hardlink": str(tmp_path / "hard")}[spelling]
    if spelling == "symlink":
        os.symlink(target, out)
    elif spelling == "hardlink":
        os.link(target, out)
    before = inp.read_bytes(), motion.read_bytes()
    argv = [a.format(inp=inp, motion=motion, out=out, d=tmp_path) for a in command]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "would destroy the input" in err, err
    assert (inp.read_bytes(), motion.read_bytes()) == before
    assert not (tmp_path / "ok.csv").exists()


def test_two_outputs_on_one_file_and_an_unknown_figure_format_are_refused(tmp_path, capsys):
    inp = tmp_path / "rec.csv"
    inp.write_text(IMU_ROWS)
    assert cli.main(["estimate", str(inp), "--out", str(tmp_path / "e.csv"),
                     "--plot", f"{tmp_path}/./e.csv"]) == 2
    assert "--out and --plot name the same file" in capsys.readouterr().err
    assert cli.main(["estimate", str(inp), "--out", str(tmp_path / "e.csv"),
                     "--plot", str(tmp_path / "e.xyz")]) == 2
    err = capsys.readouterr().err.strip()
    assert "extension .xyz, not a figure format" in err and ".png" in err
    assert not (tmp_path / "e.csv").exists()


def test_a_motion_recording_and_a_report_keep_their_inputs(tmp_path, capsys):
    motion = tmp_path / "m.csv"
    _motion_csv(motion)
    results = tmp_path / "res"
    results.mkdir()
    (results / "results.json").write_text('{"experiments": {}}')
    keep = motion.read_bytes()
    assert cli.main(["report", str(results), "--out", str(results / "results.json")]) == 2
    assert "would destroy the input" in capsys.readouterr().err
    assert (results / "results.json").read_text() == '{"experiments": {}}'
    assert cli.main(["reproduce", "--out", str(motion), "--quick", "separation"]) == 2
    assert "is a file; give a folder" in capsys.readouterr().err
    assert motion.read_bytes() == keep


def test_a_directory_is_named_as_one(tmp_path, capsys):
    for argv in (["otolith", str(tmp_path), "--out", str(tmp_path / "o.csv")],
                 ["stabilize", str(tmp_path)], ["stream", str(tmp_path)]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "is a directory" in err and len(err.splitlines()) == 1, err
    # estimate takes a folder of recordings (tests/test_folder_eval.py): an empty one is refused
    assert cli.main(["estimate", str(tmp_path), "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no recordings found" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "e").exists()
