"""The F §4.5.2 experiments (experiments/ambiguity.py) and the model value they add."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from verticality.analysis import ambiguity as am
from verticality.analysis import ambiguity_outcome
from verticality.experiments import ambiguity as ex
from verticality.models.linearize import linearize
from verticality.models.params import G_M_S2
from verticality.models.planar import (
    AccelerationState,
    HeadInput,
    PlanarState,
    TorqueAndVertical,
    WithAccelerationState,
)
from verticality.simulation import ambiguity_loop


def test_known_acceleration_observer_converges_from_every_sweep_value():
    result = ex.run_known(quick=True)
    rows = result.metrics["luenberger"]
    assert len(rows) == len(result.metrics["desired_tilt_deg"]) == 3
    assert all(r["converged"] for r in rows)
    assert all(r["final_tilt_error_deg"] < ambiguity_outcome.CONVERGED_DEG for r in rows)
    assert result.metrics["checks"]["all_converge"]["pass"]


def test_the_otolith_and_head_parameters_are_f452s():
    head = ambiguity_loop.plant().head
    assert head.K_kg_m2 == 0.0174
    w_n = math.sqrt(head.g_m_s2 / head.l_m)
    zeta = head.beta_Nms / head.J_kg_m2 / (2.0 * w_n)
    assert abs(w_n / (2 * math.pi) - 300.0) < 1e-9 and abs(zeta - 1.0) < 1e-12
    lin = ambiguity_loop.linear_model()
    assert np.asarray(lin.B).shape == (4, 2)  # τ and ᴴa_h: ᴴa_z drops out at upright
    poles = np.sort(np.linalg.eigvals(np.asarray(lin.A)).real)
    np.testing.assert_allclose(poles[:2], -w_n, rtol=1e-6)  # the critically damped double pole


def test_acceleration_state_model_is_the_plant_with_the_input_moved_into_the_state():
    plant = ambiguity_loop.plant()
    z = jnp.asarray(0.0)
    lin = linearize(plant, PlanarState(z, z, z, z), HeadInput(z, z, z))
    aug = WithAccelerationState(plant, 5.0)
    lin_aug = linearize(aug, AccelerationState(PlanarState(z, z, z, z), z), TorqueAndVertical(z, z))
    A, A_aug = np.asarray(lin.A), np.asarray(lin_aug.A)
    np.testing.assert_array_equal(A_aug[:4, :4], A)
    np.testing.assert_array_equal(A_aug[:4, 4], np.asarray(lin.B)[:, 1])
    assert A_aug[4, 4] == -5.0 and not np.any(A_aug[4, :4])
    np.testing.assert_array_equal(np.asarray(lin_aug.C)[:, :4], np.asarray(lin.C))


def test_the_reconstruction_corrects_the_tilt_only_at_third_order():
    """A still head at θ, an estimate at 0: the acceleration reconstructed from the reading
    explains the reading to the linear internal model (ŷ = −â/g − θ̂) up to a third-order
    innovation, restoring with F 3.17 (−e³/6 … the estimate is pushed towards θ) and repelling
    with the exact form (+e³/3)."""
    for deg in (2.0, 12.0, 25.0):
        th = math.radians(deg)
        y = float(am.planar_reading(0.0, 0.0, th))
        assert y == -th or abs(y + th) < 1e-15
        for small, coeff in ((True, -1.0 / 6.0), (False, 1.0 / 3.0)):
            a_hat = float(am.planar_head_acceleration(y, 0.0, 0.0, small_angle=small))
            innovation = y - (-a_hat / G_M_S2 - 0.0)
            assert math.copysign(1.0, innovation) == math.copysign(1.0, coeff)
            assert abs(innovation - coeff * th**3) <= 0.2 * abs(coeff) * th**3 + 1e-12


def test_walking_head_acceleration_is_a_steady_gait():
    (a_h, a_z), (a_h_st, a_z_st) = ambiguity_loop.walking_head_acceleration(20000)  # 2 s at 10 kHz
    assert a_h_st.shape == (20000, ambiguity_loop.SUBSTEPS, 3)
    np.testing.assert_allclose(a_h_st[:, 0, 0], a_h, atol=1e-12)
    # steady gait: periodic at the step frequency (2 Hz), zero-mean, vertical bounce ≈ 0.3 g
    period = int(round(0.5 / ambiguity_loop.DT_S))
    np.testing.assert_allclose(a_z[period:], a_z[:-period], atol=1e-9)
    np.testing.assert_allclose(a_h[period:], a_h[:-period], atol=1e-9)
    assert abs(a_h.mean()) < 0.05 and abs(a_z.mean()) < 0.05
    assert 2.5 < np.max(np.abs(a_z)) < 4.5 and 1.0 < np.max(np.abs(a_h)) < 3.5


def test_printed_relations_hold_only_under_fs_unstated_conventions():
    r = ex.printed_relations()
    assert r["f314_with_conventions_max_error_m_s2"] < 1e-9
    assert r["f316_with_conventions_max_error_m_s2"] < 1e-9
    assert r["f314_as_printed_a_z_up_max_error_m_s2"] > 1.0  # g − a_z with a_z up is wrong
