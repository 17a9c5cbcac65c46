"""`verticality sweep`: the spec's errors, the design's order, a real local Dask cluster of two
worker processes, worker-count independence and resume (its tasks computed in this process)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pyarrow.parquet as pq  # the extra 'sweep' is part of the test extra: missing, this fails
import pytest

from verticality.analysis import newton_errors
from verticality.cli import main
from verticality.core.errors import InputError
from verticality.simulation import newton_loop
from verticality.sweep import distribute, grid, maps
from verticality.sweep import spec as S
from verticality.sweep.kernels import NEWTON_LISSAJOUS

# 8 runs of 1.5 s (fixed/stabilized × K̂ −20 / +30 % × 2 seeds) in tasks of 2 runs, batches of 2
TINY = """
kernel = "newton-lissajous"
batch = 2
runs_per_task = 2
[options]
duration_s = 1.5
[knobs]
head = ["fixed", "stabilized"]
K_rel_error = [-0.2, 0.3]
[seeds]
values = [3, 5]
"""


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory):
    """The tiny sweep on a real local cluster of two worker processes; they load the kernel from
    the session's compilation cache (``run`` compiles it there first)."""
    out = tmp_path_factory.mktemp("sweep2")
    spec = S.parse(TINY)
    summary = distribute.run(spec, out, workers=2, progress=False)
    return spec, out, summary


def test_design_order_and_columns():
    spec = S.parse(TINY)
    d = S.design(spec)
    assert d.n_runs == 8 and S.n_tasks(spec, d.n_runs) == 4
    assert list(d.seeds) == [3, 5] * 4
    assert list(d.columns["head"]) == ["fixed"] * 4 + ["stabilized"] * 4
    assert list(d.columns["K_rel_error"]) == [-0.2, -0.2, 0.3, 0.3] * 2
    assert set(d.columns) == set(NEWTON_LISSAJOUS.knobs)  # knobs left out are columns too
    assert np.all(d.columns["noise_rad"] == NEWTON_LISSAJOUS.knobs["noise_rad"].default)


def test_random_design_is_reproducible_and_in_range():
    text = TINY.replace("[knobs]", '[design]\nkind = "random"\nn = 5\nseed = 7\n[knobs]').replace(
        "K_rel_error = [-0.2, 0.3]", "K_rel_error = {min = -0.5, max = 0.5}")
    a, b = S.design(S.parse(text)), S.design(S.parse(text))
    assert a.n_runs == 10
    np.testing.assert_array_equal(a.columns["K_rel_error"], b.columns["K_rel_error"])
    k = a.columns["K_rel_error"]
    assert np.all((k >= -0.5) & (k <= 0.5)) and len(set(k)) == 5


@pytest.mark.parametrize("change, words", [
    (("kernel = \"newton-lissajous\"", "kernel = \"nope\""), "kernel must be one of"),
    (("K_rel_error = [-0.2, 0.3]", "K_rel_error = [-1.0]"), "outside (-1.0"),
    (("K_rel_error = [-0.2, 0.3]", "Q_rel_error = [0.1]"), "has no knob 'Q_rel_error'"),
    (("head = [\"fixed\", \"stabilized\"]", "head = [\"floating\"]"),
     "not one of fixed, stabilized"),
    (("values = [3, 5]", "values = [3, 3]"), "seeds repeat"),
    (("duration_s = 1.5", "duration_s = 1.51"), "multiple of the observer's 25 ms"),
    (("runs_per_task = 2", "runs_per_task = 3"),
     "runs_per_task must be a positive multiple of batch"),
    (("[seeds]", "[seed]"), "unknown key(s) seed"),
    (("K_rel_error = [-0.2, 0.3]", "K_rel_error = {min = 0, max = 1}"), "random design"),
    (("[knobs]", "[knobs"), "not valid TOML"),
])
def test_bad_spec_is_one_clear_error(change, words, tmp_path, capsys):
    text = TINY.replace(*change)
    with pytest.raises(InputError, match=None) as exc:
        S.parse(text)
    assert words in str(exc.value)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0]


@pytest.mark.parametrize("module", ["distributed", "pyarrow.parquet"])
def test_without_the_extra_the_command_says_what_to_install(module, monkeypatch, tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` raise ImportError
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'verticality[sweep]'" in err[0]
    assert module.split(".")[0] in err[0]
    assert not (tmp_path / "o").exists()


def test_local_cluster_two_workers_writes_the_table(two_workers):
    spec, out, summary = two_workers
    assert summary.n_runs == 8 and summary.computed_tasks == (0, 1, 2, 3)
    t = pq.read_table(out / "results.parquet")
    assert t.column_names == (["run", *NEWTON_LISSAJOUS.knobs, "seed", *NEWTON_LISSAJOUS.drawn,
                               *NEWTON_LISSAJOUS.metrics, "diverged"])
    assert t.column("run").to_pylist() == list(range(8))
    err = np.asarray(t.column("max_error_deg"))
    head = np.asarray(t.column("head"))
    assert np.all(np.isfinite(err)) and not np.any(t.column("diverged").to_numpy())
    # the stabilized head's error is far below the fixed head's with the same wrong K̂
    assert np.max(err[head == "stabilized"]) < 0.2 * np.min(err[head == "fixed"])
    assert (out / "spec.toml").read_text() == TINY
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["runs"] == 8 and prov["tasks_computed"] == 4 and prov["libraries"]["dask"]


def test_one_worker_table_is_bit_identical(two_workers, tmp_path):
    """One worker and tasks of 6 runs (two full tasks' worth and a short one): the same table."""
    spec, out2, _ = two_workers
    other = S.parse(TINY.replace("runs_per_task = 2", "runs_per_task = 6"))
    assert distribute.run(other, tmp_path, workers=1, progress=False).n_tasks == 2
    assert pq.read_table(tmp_path / "results.parquet").equals(
        pq.read_table(out2 / "results.parquet"))


def test_task_size_does_not_change_a_run(two_workers):
    """One task of all 8 runs, computed in this process, gives the same numbers as the cluster's
    tasks of 2."""
    spec, out2, _ = two_workers
    d = S.design(spec)
    one = distribute.task_table(spec.kernel, spec.options, d, 0, spec.batch)
    assert one.equals(pq.read_table(out2 / "results.parquet"))


def test_resume_recomputes_only_the_missing_part(two_workers, tmp_path, monkeypatch):
    """Which parts a resume keeps is decided before any task is handed out; the tasks left are
    computed in this process (the engine's path without a cluster, the same ``run_task``), as
    tests/test_reliability_commands.py's resume cases do: the cluster itself is the two-worker and
    one-worker tests' (a cluster of one started here would cost a process importing JAX)."""
    from verticality.sweep import engine

    def in_process(fn, calls, *, scheduler=None, workers=None, **kwargs):
        assert scheduler is None and workers == 1
        return engine.map_tasks(fn, calls, **kwargs)

    monkeypatch.setattr(distribute, "map_tasks", in_process)
    spec, out2, _ = two_workers
    out = tmp_path / "r"
    out.mkdir()
    (out / "parts").mkdir()
    for p in sorted((out2 / "parts").iterdir()):
        (out / "parts" / p.name).write_bytes(p.read_bytes())
    (out / "spec.toml").write_text(TINY)
    before = {p.name: p.read_bytes() for p in (out / "parts").iterdir()}
    (out / "parts" / "part-000002.parquet").unlink()
    (out / "parts" / "part-000001.parquet").write_bytes(before["part-000001.parquet"][:100])  # torn
    summary = distribute.run(spec, out, workers=1, resume=True, progress=False)
    assert summary.computed_tasks == (1, 2)
    for name in ("part-000000.parquet", "part-000003.parquet"):
        assert (out / "parts" / name).read_bytes() == before[name]
    assert pq.read_table(out / "results.parquet").equals(pq.read_table(out2 / "results.parquet"))
    with pytest.raises(InputError, match="already holds a sweep"):
        distribute.run(spec, out, workers=1, progress=False)
    with pytest.raises(InputError, match="another spec"):
        distribute.run(S.parse(TINY.replace("[3, 5]", "[3, 6]")), out, resume=True, progress=False)
    # a finished part from a kernel with other knobs (an older version, which wrote no manifest):
    # refused, nothing computed
    old = pq.read_table(out / "parts" / "part-000000.parquet").drop_columns(["amplitude_scale"])
    pq.write_table(old.replace_schema_metadata(None), out / "parts" / "part-000000.parquet")
    (out / "parts" / "part-000003.parquet").unlink()
    with pytest.raises(InputError, match="part 0 has other columns.*without amplitude_scale"):
        distribute.run(spec, out, workers=1, resume=True, progress=False)
    assert not (out / "parts" / "part-000003.parquet").exists()


def test_kernel_reproduces_the_experiment_run():
    """A sweep run with the experiment's perturbed observer (every mass-like parameter 10 % high)
    and seed is the experiment's run: computed in a batch of two, the same maximum error to 1e-12
    as `newton-lissajous`'s computation of that run alone."""
    cols = {k: np.array([v.default]) for k, v in NEWTON_LISSAJOUS.knobs.items()}
    for k in ("m_rel_error", "J_rel_error", "beta_rel_error", "K_rel_error"):
        cols[k] = np.array([0.1])
    got = NEWTON_LISSAJOUS.run_batch({k: np.repeat(v, 2) for k, v in cols.items()},
                                     np.array([11, 11]), duration_s=1.5)  # the tests' batch shape
    ref = newton_errors.max_error_after(newton_loop.RunSeries(*(
        np.asarray(a[0]) for a in newton_loop.run_batch(
            [True], [0.1], [newton_loop.NOISE_RAD], seed=11, duration_s=1.5))))
    np.testing.assert_allclose(got["max_error_deg"][0], ref, rtol=1e-12)


def _groupby(columns, x, y):
    """The per-(head, x, y) divergence share and median max error (of the runs that did not
    diverge), by pyarrow's group_by: an independent computation of the maps' cells."""
    import pyarrow as pa

    t = pa.table({"head": columns["head"], "x": columns[x], "y": columns[y],
                  "div": np.asarray(columns["diverged"], dtype=float),
                  "err": columns["max_error_deg"]})
    p = {(r["head"], r["x"], r["y"]): r["div_mean"]
         for r in t.group_by(["head", "x", "y"]).aggregate([("div", "mean")]).to_pylist()}
    kept = t.filter(pa.compute.equal(t["div"], 0.0))
    med = {(r["head"], r["x"], r["y"]): float(np.median(r["err_list"]))
           for r in kept.group_by(["head", "x", "y"]).aggregate([("err", "list")]).to_pylist()}
    return p, med


def _assert_maps_match(m, columns):
    p, med = _groupby(columns, m.x, m.y)
    seen = 0
    for h in maps.HEADS:
        for j, yv in enumerate(m.y_values):
            for i, xv in enumerate(m.x_values):
                key = (h, xv, yv)
                if key in p:
                    seen += 1
                    assert m.p_diverged[h][j, i] == p[key]
                    if key in med:
                        assert m.median_max_error_deg[h][j, i] == med[key]
                    else:
                        assert np.isnan(m.median_max_error_deg[h][j, i])
                else:
                    assert m.runs[h][j, i] == 0 and np.isnan(m.p_diverged[h][j, i])
    assert seen == len(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.testing.assert_array_equal(
            m.ratio, m.median_max_error_deg["fixed"] / m.median_max_error_deg["stabilized"])


def test_sweep_plot_writes_the_maps_of_the_table(two_workers, tmp_path, capsys):
    _, out, _ = two_workers
    png = tmp_path / "maps.png"
    assert main(["sweep-plot", str(out), "--x", "K_rel_error", "--y", "noise_rad",
                 "--out", str(png)]) == 0
    assert capsys.readouterr().out.strip() == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    kernel, columns = maps.read(out)
    m = maps.compute(kernel, columns, "K_rel_error", "noise_rad")
    assert list(m.x_values) == [-0.2, 0.3] and m.runs["fixed"].sum() == 4
    _assert_maps_match(m, columns)
    assert np.all(m.ratio > 5.0)  # the stabilized head's error is far below the fixed head's
    assert m.published == (0.1, newton_loop.NOISE_RAD)  # P11's perturbed run, marked
    assert main(["sweep-plot", str(out), "--x", "head"]) == 2
    assert "cannot map over 'head'" in capsys.readouterr().err


def test_maps_of_diverged_runs_and_binned_knobs():
    """A made-up table: divergence shares and medians per cell equal the group-by; a knob with
    many values is cut into equal bins (counts = a histogram); P11's point is marked."""
    rng = np.random.default_rng(0)
    n = 400
    cols = {k: np.full(n, v.default) for k, v in NEWTON_LISSAJOUS.knobs.items()}
    cols["head"] = rng.choice(["fixed", "stabilized"], n)
    cols["K_rel_error"] = rng.choice([-0.2, 0.1, 0.3], n)
    cols["m_rel_error"] = rng.choice([0.0, 0.1], n)
    cols["diverged"] = rng.random(n) < 0.3
    cols["max_error_deg"] = np.where(cols["diverged"], np.nan, rng.gamma(2.0, 1.0, n))
    cols["diverged"][:3] = True  # diverged with a finite error: still left out of the median
    cols["max_error_deg"][:3] = 99.0
    m = maps.compute(NEWTON_LISSAJOUS, cols, "K_rel_error", "m_rel_error")
    _assert_maps_match(m, cols)
    assert 0.1 < np.nanmean(m.p_diverged["fixed"]) < 0.5
    assert m.published == (0.1, 0.1)
    cols["J_rel_error"] = rng.uniform(-0.5, 0.5, n)
    b = maps.compute(NEWTON_LISSAJOUS, cols, "J_rel_error", "K_rel_error")
    assert b.binned == (True, False) and b.x_values.size == grid.BINS
    counts, _ = np.histogram(cols["J_rel_error"], bins=grid.BINS)
    np.testing.assert_array_equal((b.runs["fixed"] + b.runs["stabilized"]).sum(axis=0), counts)
