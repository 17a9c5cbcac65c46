"""`newton-lissajous`'s ``error_level`` knob (random errors on every parameter, drawn from the
run's seed) and the divergence curve along a knob (``sweep-plot --curve``)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from verticality.cli import main
from verticality.core.errors import InputError
from verticality.sweep import curves, distribute, maps
from verticality.sweep import kernels as K
from verticality.sweep import spec as S
from verticality.sweep.kernels import NEWTON_LISSAJOUS

SEEDS = np.array([3, 5])


def _columns(n: int, **knobs) -> dict[str, np.ndarray]:
    cols = {k: np.full(n, v.default, dtype=object if v.choices else np.float64)
            for k, v in NEWTON_LISSAJOUS.knobs.items()}
    cols["head"] = np.array(["fixed", "stabilized"] * (n // 2))
    return cols | {k: np.full(n, v, dtype=np.float64) for k, v in knobs.items()}


def test_drawn_errors_are_reproducible_uniform_and_scale_with_the_level():
    seeds = np.arange(4000)
    u = np.asarray(K.drawn_errors(np.ones(seeds.size), seeds))
    assert u.shape == (seeds.size, len(K.PARAMETERS))
    np.testing.assert_array_equal(u, np.asarray(K.drawn_errors(np.ones(seeds.size), seeds)))
    assert np.all(np.abs(u) <= 1.0) and np.unique(u).size == u.size  # every draw differs
    # uniform on [−1, 1]: mean 0, a quarter in each quarter of the interval (±4σ of 20 000 draws)
    assert abs(u.mean()) < 4 * math.sqrt(1 / 3 / u.size)
    counts, _ = np.histogram(u, bins=4, range=(-1, 1))
    assert np.all(np.abs(counts / u.size - 0.25) < 4 * math.sqrt(0.25 * 0.75 / u.size))
    # the parameters' draws are not correlated with each other
    assert np.max(np.abs(np.corrcoef(u.T) - np.eye(len(K.PARAMETERS)))) < 0.05
    # a level scales the same draw; level 0 draws +0 (not −0)
    levels = np.linspace(0.0, 0.5, seeds.size)
    scaled = np.asarray(K.drawn_errors(levels, seeds))
    np.testing.assert_allclose(scaled, levels[:, None] * u, rtol=0, atol=1e-16)
    zero = np.asarray(K.drawn_errors(np.zeros(3), seeds[:3]))
    assert np.all(zero == 0.0) and not np.any(np.signbit(zero))


def test_level_zero_is_the_run_without_the_knob_to_the_bit():
    """At level 0 the kernel's metrics are those of the batch function given the knobs' errors
    alone (the computation before the knob existed), bit for bit."""
    cols = _columns(2, K_rel_error=0.2, m_rel_error=-0.1)
    got = NEWTON_LISSAJOUS.run_batch(cols, SEEDS, duration_s=1.5)
    rel = K.PlanarHead(**{leaf: np.asarray(cols[leaf.split("_")[0] + "_rel_error"])
                          for leaf in K.PARAMETERS}, g_m_s2=np.zeros(2))
    ref = K.newton_lissajous_batch(rel, np.asarray(cols["head"] == "fixed"), cols["noise_rad"],
                                   SEEDS, n_blocks=60)
    for m in (*NEWTON_LISSAJOUS.metrics, "diverged"):
        assert got[m].tobytes() == np.asarray(ref[m]).tobytes(), m
    for d in NEWTON_LISSAJOUS.drawn:
        assert np.all(got[d] == 0.0)


def test_a_level_adds_its_drawn_errors_to_the_knobs():
    """A run at level 0.3 is the run at level 0 with the knobs set to the errors it drew; the
    same seed draws the same errors, another seed others."""
    a = NEWTON_LISSAJOUS.run_batch(_columns(2, error_level=0.3), SEEDS, duration_s=1.5)
    again = NEWTON_LISSAJOUS.run_batch(_columns(2, error_level=0.3), SEEDS, duration_s=1.5)
    for m in (*NEWTON_LISSAJOUS.drawn, *NEWTON_LISSAJOUS.metrics):
        assert a[m].tobytes() == again[m].tobytes(), m
    drawn = np.stack([a[d] for d in NEWTON_LISSAJOUS.drawn], axis=1)
    assert np.all(np.abs(drawn) <= 0.3) and np.all(drawn != 0.0)
    assert not np.any(drawn[0] == drawn[1])  # seeds 3 and 5 draw different errors
    as_knobs = _columns(2, **{d.replace("drawn", "rel"): a[d] for d in NEWTON_LISSAJOUS.drawn})
    b = NEWTON_LISSAJOUS.run_batch(as_knobs, SEEDS, duration_s=1.5)
    for m in NEWTON_LISSAJOUS.metrics:
        assert a[m].tobytes() == b[m].tobytes(), m
    base = NEWTON_LISSAJOUS.run_batch(_columns(2), SEEDS, duration_s=1.5)
    assert not np.any(a["max_error_deg"] == base["max_error_deg"])  # the errors changed the runs


def test_the_level_knob_in_a_spec_and_the_table(tmp_path):
    text = """
kernel = "newton-lissajous"
batch = 2
runs_per_task = 4
[options]
duration_s = 1.5
[knobs]
head = ["fixed", "stabilized"]
error_level = [0.0, 0.3]
[seeds]
values = [3, 5]
"""
    spec = S.parse(text)
    d = S.design(spec)
    assert list(d.columns["error_level"]) == [0.0, 0.0, 0.3, 0.3] * 2
    for bad in ("[1.0]", "[-0.1]"):
        with pytest.raises(InputError, match="error_level"):
            S.parse(text.replace("[0.0, 0.3]", bad))
    # a knob's error and a drawn one that together could reach −100 %: one clear line
    S.parse(text.replace("[knobs]", "[knobs]\nl_rel_error = [-0.6]"))  # −0.6 − 0.3 > −1
    with pytest.raises(InputError, match=r"l_rel_error down to -0.8 with error_level up to 0.3"):
        S.parse(text.replace("[knobs]", "[knobs]\nl_rel_error = [0.1, -0.8]"))
    with pytest.raises(InputError, match="K_rel_error down to -0.5 with error_level up to 0.6"):
        S.parse(text.replace("[knobs]", '[design]\nkind = "random"\nn = 3\n[knobs]').replace(
            "error_level = [0.0, 0.3]",
            "error_level = {min = 0.0, max = 0.6}\nK_rel_error = {min = -0.5, max = 0.0}"))
    t = distribute.task_table("newton-lissajous", spec.options, d.rows(0, 4), 0, 2)
    cols = {c: t.column(c).to_numpy(zero_copy_only=False) for c in t.column_names}
    assert all(np.all(cols[c][:2] == 0.0) for c in NEWTON_LISSAJOUS.drawn)
    single = NEWTON_LISSAJOUS.run_batch(_columns(2, error_level=0.3), SEEDS, duration_s=1.5)
    for c in NEWTON_LISSAJOUS.drawn:  # the table's drawn errors are the kernel's, run by run
        assert cols[c][2:4].tobytes() == single[c].tobytes()


def test_wilson_interval():
    lo, hi = curves.wilson(0, 200)
    assert lo == 0.0 and 0.015 < hi < 0.02  # 1.9 %: not the normal approximation's 0
    lo, hi = curves.wilson(100, 200)
    assert lo == pytest.approx(0.4314, abs=1e-4) and hi == pytest.approx(0.5686, abs=1e-4)
    lo, hi = curves.wilson(200, 200)
    assert 0.98 < lo < 0.985 and hi == 1.0
    assert all(math.isnan(v) for v in curves.wilson(0, 0))


def _made_up(n=600, seed=0):
    rng = np.random.default_rng(seed)
    cols = {k: np.full(n, v.default) for k, v in NEWTON_LISSAJOUS.knobs.items()}
    cols["head"] = rng.choice(["fixed", "stabilized"], n)
    cols["error_level"] = rng.choice([0.0, 0.1, 0.15, 0.3], n)
    cols["diverged"] = rng.random(n) < cols["error_level"] * np.where(cols["head"] == "fixed", 2, 1)
    cols["max_error_deg"] = np.where(cols["diverged"], np.nan, rng.gamma(2.0, 1.0, n))
    cols["diverged"][:3] = True  # diverged with a finite error: still left out of the median
    cols["max_error_deg"][:3] = 99.0
    cols["run"] = np.arange(n)
    cols["seed"] = np.arange(n)  # the kernel's other columns, so that the table is its table
    cols["rms_error_deg"] = cols["max_error_deg"] / 2.0
    cols["converged_fraction"] = np.where(cols["diverged"], 0.0, 1.0)
    return cols


def _assert_curve_is_the_groupby(c: curves.Curve, cols) -> None:
    """Counts, Wilson intervals and medians equal pyarrow's group-by of the table."""
    import pyarrow as pa

    t = pa.table({"head": cols["head"], "x": cols[c.knob],
                  "div": np.asarray(cols["diverged"], dtype=np.int64),
                  "err": cols["max_error_deg"]})
    g = {(r["head"], r["x"]): (r["div_sum"], r["div_count"])
         for r in t.group_by(["head", "x"]).aggregate([("div", "sum"),
                                                       ("div", "count")]).to_pylist()}
    kept = t.filter(pa.compute.equal(t["div"], 0))
    med = {(r["head"], r["x"]): float(np.median(r["err_list"]))
           for r in kept.group_by(["head", "x"]).aggregate([("err", "list")]).to_pylist()}
    seen = 0
    for h in maps.HEADS:
        for i, v in enumerate(c.values):
            k, n = g.get((h, v), (0, 0))
            seen += (h, v) in g
            assert (c.diverged[h][i], c.runs[h][i]) == (k, n)
            assert (c.p_low[h][i], c.p_high[h][i]) == pytest.approx(curves.wilson(k, n),
                                                                    nan_ok=True)
            if (h, v) in med:
                assert c.median[h][i] == med[(h, v)]
            else:
                assert np.isnan(c.median[h][i])
    assert seen == len(g)


def test_curve_equals_the_groupby_of_the_table():
    cols = _made_up()
    c = curves.compute(NEWTON_LISSAJOUS, cols, "error_level")
    assert list(c.values) == [0.0, 0.1, 0.15, 0.3]
    _assert_curve_is_the_groupby(c, cols)
    assert c.mark == (0.15, curves.MARKS[("newton-lissajous", "error_level")][1])
    p = c.p_diverged("fixed")
    assert p[0] == 0.0 and p[-1] > 0.4  # the made-up rates rise with the level
    assert all(lo <= q <= hi for lo, q, hi in zip(c.p_low["fixed"], p, c.p_high["fixed"],
                                                  strict=True))
    assert len(curves.table(c)) == 2 + c.values.size
    with pytest.raises(InputError, match="numeric knobs"):
        curves.compute(NEWTON_LISSAJOUS, cols, "head")
    cols["K_rel_error"] = np.random.default_rng(1).uniform(-0.5, 0.5, cols["run"].size)
    with pytest.raises(InputError, match="map it"):
        curves.compute(NEWTON_LISSAJOUS, cols, "K_rel_error")


def test_sweep_plot_curve_command(tmp_path, capsys, monkeypatch):
    """``sweep-plot DIR --curve KNOB`` draws the curve of the table in DIR and prints its table."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = _made_up(200, seed=2)
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "spec.toml").write_text('kernel = "newton-lissajous"\n[seeds]\ncount = 1\n')
    pq.write_table(pa.table({k: cols[k] for k in ("run", "seed", *NEWTON_LISSAJOUS.knobs,
                                                   "diverged", "max_error_deg", "rms_error_deg",
                                                   "converged_fraction")}),
                   out / "results.parquet")
    assert main(["sweep-plot", str(out), "--curve", "error_level"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    png = out / "curve-error_level.png"
    assert lines[-1] == str(png) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert lines[:-1] == curves.table(curves.compute(NEWTON_LISSAJOUS, cols, "error_level"))
    # the same numbers as JSON (whole, for a script), and the figure's path
    assert main(["sweep-plot", str(out), "--curve", "error_level", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    curve = curves.compute(NEWTON_LISSAJOUS, cols, "error_level")
    assert got["figure"] == str(png) and got["knob"] == "error_level"
    np.testing.assert_array_equal(got["values"], curve.values)
    for g in curve.groups:
        np.testing.assert_array_equal(got["groups"][g]["diverged"], curve.diverged[g])
        np.testing.assert_array_equal(got["groups"][g]["runs"], curve.runs[g])
        np.testing.assert_allclose(np.array(got["groups"][g]["median"], dtype=float),
                                   curve.median[g], rtol=0, atol=0, equal_nan=True)
    assert main(["sweep-plot", str(out), "--json"]) == 2
    assert "--json" in capsys.readouterr().err
    assert main(["sweep-plot", str(out), "--curve", "error_level", "--x", "K_rel_error"]) == 2
    assert "--curve draws one knob" in capsys.readouterr().err
