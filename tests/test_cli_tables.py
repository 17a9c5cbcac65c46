"""The tables the commands print are whole, piped or at an 80-column terminal: a name or a number
copied from them is the program's own (`verticality list` feeds `reproduce`); `--json` gives the
same as data."""

import io
import json
import re

import h5py
import numpy as np
import pytest
from rich.console import Console
from rich.table import Table

from verticality import cli, experiments
from verticality.cli.commands import list_experiments, print_table


def _names_in_first_column(text: str) -> list[str]:
    return re.findall(r"^│ (\S+)\s+│", text, flags=re.M)


def test_list_piped_at_80_columns_keeps_every_name_whole(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "80")  # what a pipe gets by default; the table ignores it
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    names = sorted(experiments.discover())
    assert _names_in_first_column(text) == names
    assert "…" not in text
    # one line per experiment: its title whole on the name's line
    for name, row in list_experiments.rows().items():
        line = next(line for line in text.splitlines() if line.startswith(f"│ {name} "))
        assert row["what"] in line and row["source"] in line


def test_list_at_an_80_column_terminal_wraps_the_text_not_the_names():
    out = io.StringIO()
    console = Console(file=out, force_terminal=True, width=80, color_system=None)
    print_table(list_experiments.table(list_experiments.rows()), console)
    text = out.getvalue()
    assert max(len(line) for line in text.splitlines()) <= 80
    assert _names_in_first_column(text) == sorted(experiments.discover())
    assert "…" not in text
    assert "perception-post-rotatory-tilt" in experiments.discover()  # the longest name today


def test_list_json_names_every_experiment_with_its_source():
    out = io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(out):
        assert cli.main(["list", "--json"]) == 0
    got = json.loads(out.getvalue())["experiments"]
    found = experiments.discover()
    assert list(got) == sorted(found)
    for name, exp in found.items():
        assert got[name] == {"source": exp.source, "what": exp.title}


def test_a_table_narrower_than_its_cells_folds_them_instead_of_cutting():
    """At a terminal too narrow for every column, a long cell is folded onto the next lines:
    every character is still there, in order."""
    table = Table()
    table.add_column("trial", no_wrap=True)
    for k in range(8):
        table.add_column(f"filter-{k}", justify="right", no_wrap=True)
    cells = [f"{1000 * k + 0.123456789:.6f}" for k in range(8)]
    table.add_row("18_undisturbed_fast_translation_with_breaks_B", *cells)
    out = io.StringIO()
    print_table(table, Console(file=out, force_terminal=True, width=80, color_system=None))
    lines = [line for line in out.getvalue().splitlines() if line.startswith("│")]
    assert max(len(line) for line in lines) <= 80
    columns = zip(*[line.split("│")[1:-1] for line in lines], strict=True)
    read = ["".join(piece.strip() for piece in col) for col in columns]
    assert read == ["18_undisturbed_fast_translation_with_breaks_B", *cells]


def _trial(path, n=600):
    """A BROAD-layout trial: a sensor turning about x from 25° off the vertical."""
    from imu_cases import tumbling
    from verticality.core import so3

    gyr, acc, _ = tumbling(np.zeros(3), n, dt=0.01)
    angle = 0.4 * np.arange(n) * 0.01
    R = np.einsum("ij,njk->nik", np.asarray(so3.rot_y(np.radians(25.0))),
                  np.asarray(so3.exp(np.outer(angle, [1.0, 0.0, 0.0]))))
    with h5py.File(path, "w") as f:
        f["imu_gyr"], f["imu_acc"] = gyr, acc
        f["opt_quat"] = np.asarray(so3.quat_from_matrix(R))
        f["movement"] = np.arange(n) >= 100
        f.attrs["sampling_rate"] = 100.0


@pytest.mark.parametrize("filters", [["verticality", "vqf", "madgwick", "mahony",
                                      "verticality-offline", "vqf-offline"]])
def test_evaluate_piped_at_80_columns_prints_every_number_whole(tmp_path, monkeypatch, capsys,
                                                                 filters):
    d = tmp_path / "b"
    d.mkdir()
    _trial(d / "a_trial_with_a_rather_long_name.hdf5")
    monkeypatch.setenv("COLUMNS", "80")
    assert cli.main(["evaluate", "broad", str(d), "--json", "--filters", *filters]) == 0
    res = json.loads(capsys.readouterr().out)
    assert cli.main(["evaluate", "broad", str(d), "--filters", *filters]) == 0
    text = capsys.readouterr().out
    assert "…" not in text
    row = next(line for line in text.splitlines()
               if line.startswith("│ a_trial_with_a_rather_long_name "))
    cells = [c.strip().strip("*") for c in row.split("│")[2:-1]]
    assert cells[:len(filters)] == [f"{res['trials']['a_trial_with_a_rather_long_name'][f]:.3f}"
                                    for f in filters]
