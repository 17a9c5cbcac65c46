"""Output paths are checked before the work: a folder or an unwritable place is refused in one
line, and the check leaves nothing behind."""

import pytest

from verticality import cli
from verticality.errors import InputError
from verticality.io.output import check_writable_file


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
                                     ["otolith", "{f}", "--out", "{d}/o.csv"], ["stabilize", "{f}"]])
def test_a_binary_file_is_one_line_not_a_traceback(tmp_path, capsys, command):
    f = tmp_path / "binary.csv"
    f.write_bytes(b"\xff\xfe\x00\x01 not text")
    assert cli.main([a.format(f=f, d=tmp_path) for a in command]) == 2
    err = capsys.readouterr().err.strip()
    assert "the input is not UTF-8 text" in err and len(err.splitlines()) == 1
