"""The model checks (analysis/model_checks.py): each invariant asserted at its tolerance on the same
function the `model-checks` experiment reports; the experiment's registry entry and figures."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality import experiments
from verticality.analysis import model_checks as mc
from verticality.core import so3
from verticality.experiments import Result
from verticality.experiments import model_checks as exp
from verticality.models.head import FreeHead, HeadInput, HeadState

TOL = mc.TOL


def test_zero_crossing_frequency_and_simpson_are_exact_on_known_signals():
    dt = 1e-3
    t = np.arange(10001) * dt
    w = 7.3
    assert abs(mc.zero_crossing_frequency(np.cos(w * t + 0.2), dt) / w - 1) < 1e-6
    y = 3 * t**3 - t + 2
    exact = 3 * 10**4 / 4 - 10**2 / 2 + 20
    assert abs(mc.simpson(y, dt) - exact) < 1e-9


def test_run_model_takes_the_input_at_the_rk4_stages_and_projects():
    """A free head spun by a torque τ(t) = (cos t, 0, 0): ω_x = sin t / J exactly (RK4 is exact for
    the quadrature of a smooth τ to 4th order, so to ~1e-13 over 1 s at 1 ms), R stays on SO(3)."""
    head = FreeHead(mc.P13_HEAD)
    J = float(mc.P13_HEAD.J_H[0])

    def u(t, x):
        return HeadInput(jnp.stack([jnp.cos(t), 0.0, 0.0]), jnp.zeros(3))

    xf, ws = jax.jit(lambda x0: mc.run_model(head, x0, u, 1e-3, 1000, every=100,
                                             output=lambda t, x: x.omega_H_rad_s[0]))(
        HeadState(jnp.eye(3), jnp.zeros(3)))
    assert ws.shape == (10,) and float(ws[0]) == 0.0
    assert np.allclose(np.asarray(ws), np.sin(np.arange(10) * 0.1) / J, atol=1e-12)
    assert abs(float(xf.omega_H_rad_s[0]) - np.sin(1.0) / J) < 1e-12
    assert float(so3.orthonormality_error(xf.R_I_H)) < 1e-14
    with pytest.raises(ValueError):
        mc.run_model(head, HeadState(jnp.eye(3), jnp.zeros(3)), u, 1e-3, 10, every=3)


def test_small_oscillation_frequency():
    w0 = mc.analytic_frequency_rad_s()
    assert abs(w0 - np.sqrt(9.81 / 0.06)) < 1e-9  # J_xx = m l²: √(g/l)
    for axis in "xy":
        assert abs(mc.oscillation_frequency_rad_s(axis) / w0 - 1) <= TOL["oscillation"]


def test_energy_is_conserved_undamped_and_dissipated_damped():
    assert mc.energy_drift_rel().max() <= TOL["energy"]
    assert mc.energy_rate_identity_rel() <= TOL["energy_rate"]
    assert mc.energy_balance_rel() <= TOL["energy_balance"]


def test_steady_deflection_under_constant_acceleration():
    for axis in "xy":
        err, direction = mc.steady_deflection_errors_rad(axis)
        assert err <= TOL["steady"] and direction <= TOL["steady"]
        assert mc.deflection_rad(axis)[0] == 0.0  # released hanging straight down


def test_still_tilted_head():
    for axis in ("x", "y", "xy"):
        e = mc.still_tilt_errors_rad(axis)
        assert e.axis_error <= TOL["still_tilt"] and e.magnitude_error <= TOL["still_tilt"]
        if axis != "xy":
            assert e.phi_error <= TOL["still_tilt"]
    # two-axis tilt: row 3 of R_HS depends on the pendulum's turn about its arm (information)
    assert 1e-3 < mc.still_tilt_errors_rad("xy").phi_error < 0.1


def test_rotations_stay_on_so3_with_the_projection_only():
    projected, unprojected = mc.so3_drift_medial()
    assert projected.max() <= TOL["so3"]
    assert unprojected.max() > 5 * TOL["so3"]  # what the projection is for


def test_lateral_free_head_stays_on_so3():
    assert mc.so3_drift_lateral_free_head().max() <= TOL["so3"]


@pytest.mark.parametrize("which", ["medial", "lateral"])
def test_planar_models_are_the_3d_models_in_the_plane(which):
    yp, y3 = mc.planar_vs_3d(which)
    assert yp.shape == y3.shape == (10000, 2 if which == "medial" else 3)
    assert np.ptp(yp[:, 0]) > 0.1  # the run moves
    assert mc.planar_vs_3d_max_error_rad(which) <= TOL["planar"]


def test_lateral_with_r0_is_the_medial_model():
    assert mc.lateral_r0_vs_medial_max_error() <= TOL["lateral_r0"]
    assert mc.lateral_minus_medial_max_rad() > 1e-3  # the ±r pivots do matter


def test_stabilizers():
    assert mc.global_stabilizer_final_angle_rad() <= TOL["global"]
    assert mc.global_stabilizer_angle_rad()[0][0] == pytest.approx(2.5)
    assert mc.pd_poles_error() <= TOL["poles"]
    poles = mc.closed_loop_poles()
    assert np.allclose(sorted(poles.real), [-32, -32, -8, -8, -8, 0])


def test_registered_with_figures():
    entry = experiments.get("model-checks")
    assert entry.figures is not None and entry.run is exp.run


def test_experiment_reports_the_library_values():
    m, _ = exp.still_metrics()
    assert m["energy_rate_identity_rel"]["value"] == mc.energy_rate_identity_rel()
    assert m["energy_drift_rel"]["tolerance"] == TOL["energy"] == 1e-6
    checks = [v for group in m.values() if isinstance(group, dict)
              for v in ([group] if "pass" in group else group.values())]
    assert len(checks) >= 13 and all(c["pass"] for c in checks)


def test_figures_are_written(tmp_path):
    m, s = exp.still_metrics()
    n = 50
    s = dict(s)
    s.update({
        "so3_t": np.arange(n) * 0.1, "so3_err": np.full(n, 1e-16),
        "so3_err_unprojected": np.full(n, 1e-9),
        "planar_medial": np.zeros((n, 2)), "planar3d_medial": np.zeros((n, 2)),
        "planar_lateral": np.zeros((n, 3)), "planar3d_lateral": np.zeros((n, 3)),
        "lm_t": np.arange(n) * 0.01, "lm_medial": np.zeros((n, 2)), "lm_lateral": np.zeros((n, 4)),
    })
    m = dict(m)
    m["planar_vs_3d_max_error_rad"] = {k: {"value": 0.0, "tolerance": 1e-7, "pass": True}
                                       for k in ("medial", "lateral")}
    paths = exp.figures(Result(metrics=m, series=s), tmp_path)
    assert len(paths) == 6
    assert all(p.exists() and p.stat().st_size > 10_000 for p in paths)
