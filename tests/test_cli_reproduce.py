"""The `reproduce` and `list` commands: the JSON contract of docs/reproduction.md, figures, exit codes."""

import json
import math

import numpy as np

from verticality import cli
from verticality.reporting import flatten, format_value, to_jsonable


def test_reproduce_json_contract_and_figures(tmp_path, capsys):
    rc = cli.main(["reproduce", "tahboub-gains", "--json", "--out", str(tmp_path)])
    out = json.loads(capsys.readouterr().out)
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
