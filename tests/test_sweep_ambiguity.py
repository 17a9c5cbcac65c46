"""The `ambiguity-walking` sweep kernel: the ambiguity-* experiments' closed loop, knob by knob."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from verticality.analysis import ambiguity_outcome
from verticality.core.errors import InputError
from verticality.experiments import ambiguity as E
from verticality.models.params import F452_HEAD_INERTIA_KG_M2
from verticality.simulation import ambiguity_loop
from verticality.sweep import distribute
from verticality.sweep import spec as S
from verticality.sweep.ambiguity_kernel import AMBIGUITY_WALKING, METRICS
from verticality.sweep.registry import KERNELS

# `ambiguity-known-acc --quick`: the known acceleration, held at −20, 0, 20° from 5°, 3 s, in one
# batch of three runs as the experiment computes them
TINY = """
kernel = "ambiguity-walking"
batch = 3
runs_per_task = 3
[options]
duration_s = 3.0
[knobs]
feed = ["known"]
desired_tilt_deg = [-20.0, 0.0, 20.0]
[seeds]
values = [0]
"""


def _columns(n: int, **given) -> dict[str, np.ndarray]:
    """Knob columns of ``n`` runs: the defaults, with ``given`` (a value or a list per knob)."""
    out = {}
    for k, knob in AMBIGUITY_WALKING.knobs.items():
        v = given.get(k, knob.default)
        out[k] = np.asarray(v if isinstance(v, list) else [v] * n,
                            dtype=object if knob.choices else np.float64)
    return out


def test_a_tiny_sweep_in_process_is_the_experiment(tmp_path):
    """The tiny sweep through distribute's in-process path writes a table with the knobs, the
    seed, the metrics and diverged, and its runs are `ambiguity-known-acc --quick`'s to the bit."""
    spec = S.parse(TINY)
    design = S.design(spec)
    assert KERNELS["ambiguity-walking"] is AMBIGUITY_WALKING
    assert design.columns["initial_tilt_deg"][0] == ambiguity_loop.THETA0_DEG
    assert design.columns["noise_rad"][0] == 0.0
    parts = tmp_path / "parts"
    parts.mkdir()
    distribute.run_task(spec.kernel, spec.options, design, 0, 0, spec.batch, str(parts))
    table = pq.read_table(distribute.part_path(parts, 0)).to_pydict()
    assert list(table) == ["run", *AMBIGUITY_WALKING.knobs, "seed", *METRICS, "diverged"]
    assert table["feed"] == ["known"] * 3 and table["seed"] == [0, 0, 0]
    assert table["desired_tilt_deg"] == [-20.0, 0.0, 20.0]
    rows = E.run_known(quick=True).metrics["luenberger"]
    for i, r in enumerate(rows):
        assert table["final_tilt_error_deg"][i] == r["final_tilt_error_deg"]
        assert table["final_head_error_deg"][i] == r["final_head_error_deg"]
        assert table["diverged"][i] == (not r["converged"])
        assert np.isnan(table["rms_acc_error_m_s2"][i])  # known: the experiment reports none


@pytest.mark.parametrize("feed", ["luenberger", "ekf_gauss_markov"])
def test_reconstructed_feeds_are_the_experiments_runs(feed):
    """A reconstructed feed at the experiment's settings (σ = 0, whatever the seed) is the
    experiment's own sweep of that feed, every metric to the bit, walking scaled or not."""
    init, ref = [5.0, 12.0], [0.0, 6.0]
    for scale in (0.0, 1.0):
        cols = _columns(2, feed=feed, initial_tilt_deg=init, desired_tilt_deg=ref,
                        walking_scale=scale)
        got = AMBIGUITY_WALKING.run_batch(cols, np.array([3, 9]), duration_s=2.0)
        want = ambiguity_outcome.summarize(ambiguity_loop.sweep(feed, init, ref, 2.0, scale), ref,
                                           known=False)
        for i, r in enumerate(want):
            for m in METRICS:
                assert got[m][i] == r[m] or (r[m] is None and np.isnan(got[m][i]))
            assert got["diverged"][i] == (not r["converged"])


def test_batched_equals_alone_and_the_knobs_act():
    """Runs of two groups interleaved in one batch equal each run computed alone: the Luenberger
    loop to the bit, the EKF's to rounding (its batched matrix algebra rounds otherwise; measured
    2e-12 relative at most, on ``final_head_error_deg``, a mean of |θ_H| near 0.8°). A model
    error, the noise and its seed change the run; a zero σ ignores the seed."""
    cols = _columns(4, feed=["known", "ekf_gauss_markov", "known", "ekf_gauss_markov"],
                    noise_rad=[1e-4, 0.0, 0.0, 1e-4], initial_tilt_deg=[5.0, 5.0, 10.0, 10.0],
                    walking_scale=0.5)
    seeds = np.array([1, 2, 3, 4])
    batch = AMBIGUITY_WALKING.run_batch(cols, seeds, duration_s=2.0)

    def alone(i, **change):
        one = {k: v[i:i + 1] for k, v in cols.items()} | {
            k: np.asarray([v], dtype=cols[k].dtype) for k, v in change.items()}
        return AMBIGUITY_WALKING.run_batch(one, seeds[i:i + 1], duration_s=2.0)

    for i in range(4):
        one = alone(i)
        assert one["diverged"][0] == batch["diverged"][i]
        for m in METRICS:
            if cols["feed"][i] == "known":
                np.testing.assert_array_equal(one[m][0], batch[m][i])
            else:
                np.testing.assert_allclose(one[m][0], batch[m][i], rtol=1e-11)
    assert np.isnan(batch["rms_acc_error_m_s2"][0]) and batch["rms_acc_error_m_s2"][1] > 0
    base = alone(0)["final_tilt_error_deg"][0]
    assert alone(0, noise_rad=0.0)["final_tilt_error_deg"][0] != base
    assert alone(0, head_inertia_rel_error=0.3)["final_tilt_error_deg"][0] != base
    assert alone(0, otolith_frequency_rel_error=-0.1)["final_tilt_error_deg"][0] != base
    noiseless = alone(2)["final_tilt_error_deg"][0]
    assert AMBIGUITY_WALKING.run_batch({k: v[2:3] for k, v in cols.items()}, np.array([77]),
                                       duration_s=2.0)["final_tilt_error_deg"][0] == noiseless


def test_internal_model_errors_reach_the_observer_and_the_pd():
    """The assumed parameters build the plant's model value (its leaves scaled), the observer's
    poles follow the assumed natural frequency, the PD's gains the assumed inertia."""
    from verticality.sweep.ambiguity_kernel import internal_model

    true = ambiguity_loop.plant()
    model, omega_n, J = internal_model(0.1, -0.2, 0.3)
    np.testing.assert_allclose(model.head.K_kg_m2, 1.3 * true.head.K_kg_m2, rtol=1e-15)
    p, q = model.head, true.head
    np.testing.assert_allclose(p.m_kg * p.g_m_s2 * p.l_m / p.J_kg_m2,
                               1.1**2 * q.m_kg * q.g_m_s2 * q.l_m / q.J_kg_m2, rtol=1e-12)
    np.testing.assert_allclose(p.beta_Nms / p.J_kg_m2, 1.1 * 0.8 * q.beta_Nms / q.J_kg_m2,
                               rtol=1e-12)
    assert omega_n == ambiguity_loop.OMEGA_N_RAD_S * 1.1 and J == F452_HEAD_INERTIA_KG_M2 * 1.3
    assert internal_model(0.0, 0.0, 0.0)[0] == true
    assert ambiguity_loop.pd_gains() == (ambiguity_loop.KP_NM_RAD, ambiguity_loop.KD_NMS_RAD)
    omega_n = ambiguity_loop.OMEGA_N_RAD_S
    assert ambiguity_loop.luenberger_poles(omega_n) == ambiguity_loop.LUENBERGER_POLES
    with pytest.raises(InputError, match="both noise_rad and seeds"):
        ambiguity_loop.sweep("known", [5.0], [0.0], 2.0, noise_rad=[1e-4])


@pytest.mark.parametrize("change, words", [
    (("feed = [\"known\"]", "feed = [\"kalman\"]"), "not one of known, luenberger"),
    (("feed = [\"known\"]", "initial_tilt_deg = [50.0]"), "initial_tilt_deg: 50.0 is outside"),
    (("feed = [\"known\"]", "head_inertia_rel_error = [-1.0]"), "head_inertia_rel_error: -1.0"),
    (("feed = [\"known\"]", "otolith_frequency_rel_error = [2.0]"), "outside [-0.9, 1.0]"),
    (("feed = [\"known\"]", "noise_rad = [-1e-4]"), "noise_rad: -0.0001"),
    (("feed = [\"known\"]", "head_loop_rad_s = [0.0]"), "outside (0.0, 100.0]"),
    (("feed = [\"known\"]", "walking_scale = [4.0]"), "walking_scale: 4.0"),
    (("duration_s = 3.0", "duration_s = 1.0"), "duration_s must be a number of seconds in [2, 60]"),
    (("duration_s = 3.0", "duration_s = 3.00005"), "multiple of the 0.1 ms sample"),
    (("duration_s = 3.0", "quick = true"), "has no option(s) quick"),
])
def test_bad_knob_is_one_clear_error(change, words):
    with pytest.raises(InputError) as exc:
        S.parse(TINY.replace(*change))
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_sweep_plot_maps_each_feed(tmp_path, capsys):
    """`sweep-plot` of an ambiguity-walking table (made up, written as a finished sweep): one
    column of maps per feed; each cell's divergence share and median final tilt error (over the
    runs that did not diverge) equal the group-by of the table."""
    import pyarrow as pa

    from verticality.cli import main
    from verticality.sweep import category_maps, maps

    rng = np.random.default_rng(1)
    n = 300
    cols = _columns(n, feed=list(rng.choice(["known", "luenberger", "ekf"], n)),
                    walking_scale=list(rng.choice([0.0, 0.5, 1.0], n)),
                    head_inertia_rel_error=list(rng.choice([-0.3, 0.0, 0.3], n)))
    cols["feed"] = cols["feed"].astype(str)
    table = {"run": np.arange(n), **cols, "seed": np.zeros(n, dtype=np.int64)}
    diverged = rng.random(n) < 0.3
    table |= {m: rng.gamma(2.0, 1.0, n) for m in METRICS} | {"diverged": diverged}
    pq.write_table(pa.table(table), tmp_path / "results.parquet")
    (tmp_path / "spec.toml").write_text(TINY, encoding="utf-8")
    png = tmp_path / "maps.png"
    assert main(["sweep-plot", str(tmp_path), "--x", "head_inertia_rel_error", "--y",
                 "walking_scale", "--out", str(png)]) == 0
    assert capsys.readouterr().out.strip() == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    m = category_maps.compute(*maps.read(tmp_path), "head_inertia_rel_error", "walking_scale")
    assert list(m.runs) == ["known", "luenberger", "ekf"] and m.metric == "final_tilt_error_deg"
    for feed in m.runs:
        for j, y in enumerate(m.y_values):
            for i, x in enumerate(m.x_values):
                sel = ((cols["feed"] == feed) & (cols["head_inertia_rel_error"] == x)
                       & (cols["walking_scale"] == y))
                assert m.runs[feed][j, i] == sel.sum()
                assert m.p_diverged[feed][j, i] == diverged[sel].mean()
                assert m.median[feed][j, i] == np.median(
                    table["final_tilt_error_deg"][sel & ~diverged])
    assert main(["sweep-plot", str(tmp_path), "--x", "feed"]) == 2
    assert "cannot map over 'feed'" in capsys.readouterr().err
    # the curve along a knob, one line per feed: the group-by of the table, printed as a table
    from verticality.sweep import curves

    c = curves.compute(*maps.read(tmp_path), "walking_scale")
    assert (c.group, c.groups, c.metric) == ("feed", ("known", "luenberger", "ekf"),
                                             "final_tilt_error_deg")
    for feed in c.groups:
        for i, v in enumerate(c.values):
            sel = (cols["feed"] == feed) & (cols["walking_scale"] == v)
            assert (c.runs[feed][i], c.diverged[feed][i]) == (sel.sum(), diverged[sel].sum())
            assert c.median[feed][i] == np.median(table["final_tilt_error_deg"][sel & ~diverged])
    assert main(["sweep-plot", str(tmp_path), "--curve", "walking_scale"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[:-1] == curves.table(c) and "luenberger: median final_tilt_error_deg" in out[0]
    assert (tmp_path / "curve-walking_scale.png").stat().st_size > 10_000
