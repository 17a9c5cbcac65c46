"""F §4.4.2's Luenberger observer applied to the lateral model (F 2.18–2.19) in `separation`."""

import numpy as np
import pytest

from verticality.experiments import separation as S
from verticality.models.linearize import linearize, select_inputs
from verticality.simulation import separation_loop


def test_linearized_models_cannot_separate_tilt_from_a_steady_acceleration():
    assert S.unknown_acceleration_rank(separation_loop.lateral_linear_model()) == (6, 7)
    assert S.unknown_acceleration_rank(separation_loop.linear_model()) == (4, 5)


def test_lateral_model_linearization_is_observable_and_pivot_independent():
    a = separation_loop.lateral_linear_model()
    b = select_inputs(linearize(separation_loop.lateral_plant(0.0, 0.0), *_upright()), [0, 1])
    for m, n in zip(a, b, strict=True):
        np.testing.assert_allclose(np.asarray(m), np.asarray(n), atol=1e-12)


def _upright():
    import jax.numpy as jnp

    from verticality.models.otolith_head import PlanarLateralState
    from verticality.models.planar import PlanarInput

    z = jnp.asarray(0.0)
    return PlanarLateralState(*([z] * 6)), PlanarInput(z, z, z)


@pytest.fixture(scope="module")
def lateral():
    return S.lateral_metrics(quick=True)[0]


def test_lateral_observer_on_the_axis_is_the_medial_one_and_offsets_break_the_loop(lateral):
    err = lateral["max_error_rad_by_r_mm"]
    assert err["f219"]["0"]["ref0"] < 0.05 and 0.1 < err["f219"]["0"]["ref1"] < 0.5
    for plant in ("f219", "with_euler_term"):
        assert err[plant]["50"]["ref0"] is None and err[plant]["50"]["ref1"] is None
    assert lateral["largest_stable_r_mm"]["f219"] == 0.0
