"""The `model-checks` experiment: registry entry, helpers, the still-head batch, figures."""

import functools

import numpy as np

from verticality import experiments
from verticality.experiments import Result
from verticality.experiments import model_checks as mc


def test_registered_with_figures():
    exp = experiments.get("model-checks")
    assert exp.figures is not None and exp.run is mc.run


def test_zero_crossing_frequency_and_simpson_are_exact_on_known_signals():
    dt = 1e-3
    t = np.arange(10001) * dt
    w = 7.3
    assert abs(mc._zero_crossing_frequency(np.cos(w * t + 0.2), dt) / w - 1) < 1e-6
    y = 3 * t**3 - t + 2
    exact = 3 * 10**4 / 4 - 10**2 / 2 + 20
    assert abs(mc._simpson(y, dt) - exact) < 1e-9


@functools.lru_cache(maxsize=1)
def _still():
    return mc._check_still()


def _leaves(d):
    for v in d.values():
        if isinstance(v, dict) and "pass" in v:
            yield v
        elif isinstance(v, dict):
            yield from _leaves(v)


def test_still_head_checks_pass():
    m, _ = _still()
    checks = list(_leaves(m))
    assert len(checks) >= 13
    assert all(c["pass"] for c in checks), m
    assert set(m["still_tilt_error_rad"]) == {"x", "y"}
    assert m["energy_drift_rel"]["tolerance"] == 1e-6


def test_figures_are_written(tmp_path):
    m, s = _still()
    n = 50
    s = dict(s)
    s.update({
        "so3_t": np.arange(n) * 0.1, "so3_err": np.full(n, 1e-16), "so3_err_unprojected": np.full(n, 1e-9),
        "planar_medial": np.zeros((n, 2)), "planar3d_medial": np.zeros((n, 2)),
        "planar_lateral": np.zeros((n, 3)), "planar3d_lateral": np.zeros((n, 3)),
        "lm_t": np.arange(n) * 0.01, "lm_medial": np.zeros((n, 2)), "lm_lateral": np.zeros((n, 4)),
    })
    m = dict(m)
    m["planar_vs_3d_max_error_rad"] = {k: {"value": 0.0, "tolerance": 1e-7, "pass": True}
                                       for k in ("medial", "lateral")}
    paths = mc.figures(Result(metrics=m, series=s), tmp_path)
    assert len(paths) == 6
    assert all(p.exists() and p.stat().st_size > 10_000 for p in paths)
