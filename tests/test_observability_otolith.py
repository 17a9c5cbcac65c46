"""The otolith models of F ch. 2 under the observability test (F Tables 3.1 and 3.2)."""

import numpy as np
import pytest

from verticality.analysis import otolith_observability as oo
from verticality.errors import InputError


@pytest.fixture(scope="module")
def table():
    return {(c.model, c.motion, c.control): c for c in oo.run_table()}


def test_published_table_has_16_rows():
    assert len(oo.PUBLISHED) == 16


def test_every_case_saturated(table):
    for case in table.values():
        r = case.result
        assert r.stalled, case
        assert min(r.ranks_at_points) == r.rank  # both random points agree
        assert r.gap > 1e6 or r.rank == r.n_coords


def test_null_space_is_exactly_the_yaw_symmetries(table):
    """Zero or unknown torque (medial): global yaw and the head's yaw about its own z axis."""
    for (model, _, control), case in table.items():
        r = case.result
        sym = oo.symmetry_directions(r, oo.plant_params().J_H)
        if control == "stabilized":
            assert r.rank == r.n_coords  # the feedback breaks every symmetry
            continue
        assert r.in_null_space(sym["global_yaw"]), case
        assert not r.quantities["heading"].observable
        if model == "medial" and control in ("zero", "unknown"):
            assert r.n_coords - r.rank == 2 and r.in_null_space(sym["head_yaw"])
            assert not case.orientation_observable
        else:  # a known torque or the lateral pivots break the head-yaw symmetry
            assert r.n_coords - r.rank == 1 and not r.in_null_space(sym["head_yaw"])
            assert case.orientation_observable


def test_head_yaw_changes_the_tilt_but_not_the_outputs(table):
    """The symmetry behind the medial 'No' rows, checked on the model itself (no rank involved)."""
    import jax.numpy as jnp

    from verticality import so3

    prob = oo.problem_for("medial")
    x, th = table[("medial", "rot", "zero")].result.point
    th = {k: jnp.asarray(v) for k, v in th.items()}
    u = {"tau_u": jnp.zeros(3)}
    Rz = so3.rot_z(0.7)
    x2 = dict(x, R_I_H=x["R_I_H"] @ Rz, omega_H=Rz.T @ x["omega_H"])
    assert np.allclose(prob.h(x, u, th), prob.h(x2, u, th), atol=1e-12)
    f1, f2 = prob.f(x, u, th), prob.f(x2, u, th)
    assert np.allclose(f1["omega_S"], f2["omega_S"], atol=1e-12)
    assert not np.allclose(oo.E3 @ x["R_I_H"], oo.E3 @ x2["R_I_H"], atol=1e-3)


def test_acceleration_rows(table):
    for (model, motion, control), case in table.items():
        if motion == "rot":
            assert case.acceleration_identifiable is None
        else:
            expected = not (model == "medial" and control in ("zero", "unknown"))
            assert case.acceleration_identifiable == expected


def test_lateral_agrees_with_table_3_2(table):
    assert all(c.agrees for (m, _, _), c in table.items() if m == "lateral")


def test_free_entry_formulation_gives_the_published_known_row():
    """R entries as free variables: R_IH → L R_IH, R_IS → L⁻ᵀ R_IS (L e3 = e3) hides the tilt."""
    case = oo.analyze_case("medial", "rot", "known", chart="ambient", order=9)
    assert case.result.stalled
    assert case.orientation_observable is False and case.published_orientation is False
    assert case.result.n_coords - case.result.rank == 6  # the six-dimensional group of L


def test_isotropic_head_hides_tilt_under_feedback():
    """P13 head (J_H = 0.125 I, scalar gains): R_IH → Rz R_IH Rzᵀ with the pendulum turned by Rz is
    a symmetry of the stabilized medial model, so the tilt's direction is not observable."""
    case = oo.analyze_case("medial", "rot", "stabilized", params="p13")
    r = case.result
    assert r.stalled and r.n_coords - r.rank == 1
    assert r.in_null_space(oo.symmetry_directions(r, oo.plant_params("p13").J_H)["yaw_conjugation"])
    assert not case.orientation_observable


def test_bad_case_names():
    with pytest.raises(InputError):
        oo.analyze_case("central", "rot", "zero")
    with pytest.raises(InputError):
        oo.case_settings("rot", "feedback")
