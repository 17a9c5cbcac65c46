"""The `reproduce` and `list` commands: the JSON contract of docs/reproduction.md, figures, exit
codes."""

import json
import math

import numpy as np

from verticality import cli, experiments
from verticality.report.entries import to_jsonable
from verticality.report.runs import flatten, format_value


def test_reproduce_json_contract_and_figures(tmp_path, capsys):
    rc = cli.main(["reproduce", "tahboub-gains", "--json", "--out", str(tmp_path)])
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert rc == 0
    entry = out["experiments"]["tahboub-gains"]
    assert set(entry) >= {"metrics", "paper", "runtime"}
    assert set(entry["runtime"]) == {"wall_s", "simulated_s"}
    assert len(entry["metrics"]["gain"]) == 3 and len(entry["metrics"]["gain"][0]) == 2
    assert entry["paper"]["gain"][1][0] == 99.0
    assert (tmp_path / "results.json").exists()
    figures = list((tmp_path / "tahboub-gains").glob("*.png"))
    assert figures and all(f.stat().st_size > 1000 for f in figures)
    assert sorted(entry["figures"]) == sorted(str(f) for f in figures)
    # the report is written beside results.json and its path told on stderr (stdout stays JSON)
    page = tmp_path / "report.html"
    assert page.stat().st_size > 10_000 and f"report: {page}" in captured.err
    assert 'id="exp-tahboub-gains"' in page.read_text()
    # results.json also says how the numbers were made and which experiments exist
    saved = json.loads((tmp_path / "results.json").read_text())
    assert saved == out
    assert out["provenance"]["mode"] == "full"
    assert out["provenance"]["experiments_requested"] == ["tahboub-gains"]
    assert set(out["registry"]) == set(experiments.discover())
    assert out["registry"]["tahboub-gains"]["source"] == "T eq. 7–13, 20–22"


def test_reproduce_tables_report_path_and_no_report(tmp_path, capsys):
    assert cli.main(["reproduce", "tahboub-gains", "--quick", "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "tahboub-gains" in out and out.strip().endswith(str(tmp_path / "a" / "report.html"))
    assert (json.loads((tmp_path / "a" / "results.json").read_text())["provenance"]["mode"]
            == "quick")
    assert cli.main(["reproduce", "tahboub-gains", "--out", str(tmp_path / "b"),
                     "--no-report"]) == 0
    assert "report.html" not in capsys.readouterr().out
    assert ((tmp_path / "b" / "results.json").exists()
            and not (tmp_path / "b" / "report.html").exists())


def test_unknown_experiment_is_one_line_and_status_2(capsys):
    rc = cli.main(["reproduce", "no-such-experiment"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "no-such-experiment" in err and "tahboub-gains" in err


def test_list_names_every_experiment(capsys):
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    for name in ("model-checks", "ekf-impact", "newton-lissajous", "observability", "separation"):
        assert name in text


def test_reporting_helpers():
    data = {"a": {"b": np.float64(math.nan), "c": np.arange(3)}, "d": {"value": 1.0, "pass": True}}
    js = to_jsonable(data)
    assert js == {"a": {"b": None, "c": [0, 1, 2]}, "d": {"value": 1.0, "pass": True}}
    flat = flatten(js)
    assert set(flat) == {"a.b", "a.c", "d"}  # a check dict is a leaf
    assert format_value({"value": 0.5, "tolerance": 1.0, "pass": False}).endswith("FAIL")
    assert format_value([{"x": 1}, {"x": 2}]) == "2 rows (see results.json)"
    assert len(format_value("x" * 500)) == 118


def test_compile_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    """The command keeps JAX's compilation cache where the environment says: our variable (a
    folder, or off), else XDG's cache folder; JAX's own variable takes precedence."""
    for var in ("JAX_COMPILATION_CACHE_DIR", "VERTICALITY_JAX_CACHE", "XDG_CACHE_HOME"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cli.compile_cache_dir() == tmp_path / "home" / ".cache" / "verticality" / "jax"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cli.compile_cache_dir() == tmp_path / "xdg" / "verticality" / "jax"
    monkeypatch.setenv("VERTICALITY_JAX_CACHE", str(tmp_path / "mine"))
    assert cli.compile_cache_dir() == tmp_path / "mine"
    monkeypatch.setenv("VERTICALITY_JAX_CACHE", "off")
    assert cli.compile_cache_dir() is None
    monkeypatch.setenv("VERTICALITY_JAX_CACHE", str(tmp_path / "mine"))
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "jax"))
    assert cli.compile_cache_dir() is None
