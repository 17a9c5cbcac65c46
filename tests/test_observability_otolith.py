"""The otolith models of F ch. 2 under the observability test (F Tables 3.1 and 3.2)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.analysis import otolith_observability as oo
from verticality.core import so3
from verticality.core.errors import InputError
from verticality.models.head import HeadInput, HeadState


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
        sym = oo.symmetry_directions(case)
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


def test_symmetry_directions_are_the_analytic_tangents(table):
    """Through the model's retraction (right perturbations), global yaw moves every frame by
    ``δ_X = R_IXᵀ e3`` and head yaw moves the head by ``δ_H = e3``, ``ω_H`` by ``−e3 × ω_H``,
    ``a_H`` by ``−e3 × a_H`` and ``τ`` by ``−J_H (e3 × J_H⁻¹ τ)``."""
    case = table[("medial", "rot+trans", "unknown")]
    x, th = case.result.point
    sym = oo.symmetry_directions(case)
    labels = case.result.labels

    def part(v, name):
        keys = [f"{name}.δ{a}" for a in "xyz"] if f"{name}.δx" in labels else \
            [f"{name}[{i}]" for i in range(3)]
        return np.array([v[labels.index(k)] for k in keys])

    e3 = np.array([0.0, 0.0, 1.0])
    J = np.array([1.0, 1.2, 0.9])
    assert np.allclose(part(sym["global_yaw"], "R_I_S"), x.pendula[0].R_I_S.T @ e3, atol=1e-12)
    assert np.allclose(part(sym["global_yaw"], "R_I_H"), x.head.R_I_H.T @ e3, atol=1e-12)
    assert np.allclose(part(sym["global_yaw"], "a_H"), 0.0, atol=1e-12)
    assert np.allclose(part(sym["head_yaw"], "R_I_H"), e3, atol=1e-12)
    assert np.allclose(part(sym["head_yaw"], "omega_H"), -np.cross(e3, x.head.omega_H_rad_s),
                       atol=1e-12)
    assert np.allclose(part(sym["head_yaw"], "a_H"), -np.cross(e3, th["a_H"]), atol=1e-12)
    assert np.allclose(part(sym["head_yaw"], "tau_H"), -J * np.cross(e3, th["tau_H"] / J),
                       atol=1e-12)
    assert np.allclose(part(sym["head_yaw"], "R_I_S"), 0.0, atol=1e-12)


def test_head_yaw_changes_the_tilt_but_not_the_outputs(table):
    """The symmetry behind the medial 'No' rows, checked on the model itself (no rank involved)."""
    case = table[("medial", "rot", "zero")]
    prob = case.problem
    x, th = case.result.point
    u = {"tau_u": jnp.zeros(3)}
    Rz = so3.rot_z(0.7)
    x2 = x._replace(head=HeadState(x.head.R_I_H @ Rz, Rz.T @ x.head.omega_H_rad_s))
    assert np.allclose(prob.measurement(x, u, th), prob.measurement(x2, u, th), atol=1e-12)
    f1, f2 = prob.vector_field(x, u, th), prob.vector_field(x2, u, th)
    assert np.allclose(f1.pendula[0].omega_S_rad_s, f2.pendula[0].omega_S_rad_s, atol=1e-12)
    assert not np.allclose(oo.E3 @ x.head.R_I_H, oo.E3 @ x2.head.R_I_H, atol=1e-3)


def test_problem_consumes_the_otolith_head_value():
    """The problem's vector field is the model value's dynamics under the declared input, and
    the 'thesis' output is the model's own output."""
    from verticality.models import otolith_head
    from verticality.simulation.control import global_stabilizer

    prob = oo.problem_for("lateral")
    assert isinstance(prob.model, otolith_head.OtolithHead) and len(prob.model.pendula) == 2
    x, th = prob.sample(np.random.default_rng(5))
    th = dict(th, stab=1.0)
    u = {"tau_u": jnp.array([0.1, -0.2, 0.3])}
    tau = th["tau_H"] + u["tau_u"] + global_stabilizer(x.head.R_I_H, x.head.omega_H_rad_s, 2.0, 1.5)
    expected = prob.model.dynamics(x, HeadInput(tau, x.head.R_I_H @ th["a_H"]))
    got = prob.vector_field(x, u, th)
    for a, b in zip(jax.tree_util.tree_leaves(got), jax.tree_util.tree_leaves(expected),
                    strict=True):
        assert np.allclose(a, b, rtol=1e-14, atol=1e-14)
    assert np.array_equal(prob.measurement(x, u, th), prob.model.output(x))
    axis = oo.problem_for("lateral", output="axis").measurement(x, u, th)
    assert axis.shape == (4,) and not np.allclose(axis, prob.model.output(x))


def test_full_form_keeps_the_gyroscopic_and_euler_terms():
    simple, full = oo.otolith_model("lateral"), oo.otolith_model("lateral", form="full")
    assert simple.head.params.gyroscopic == 0.0 and full.head.params.gyroscopic == 1.0
    assert all(p.params.euler == 0.0 and p.params.centripetal == 1.0 for p in simple.pendula)
    assert all(p.params.euler == 1.0 and p.params.gyroscopic == 1.0 for p in full.pendula)
    assert [float(p.params.pivot_H_m[1]) for p in simple.pendula] == [0.05, -0.05]


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
    assert r.in_null_space(oo.symmetry_directions(case)["yaw_conjugation"])
    assert not case.orientation_observable


def test_bad_case_names():
    with pytest.raises(InputError):
        oo.analyze_case("central", "rot", "zero")
    with pytest.raises(InputError):
        oo.case_settings("rot", "feedback")
    with pytest.raises(InputError):
        oo.otolith_model("medial", form="reduced")
    with pytest.raises(InputError):
        oo.build_problem("medial", output="canal")


def test_cli_prints_the_selected_rows(capsys):
    import json

    from verticality import cli

    argv = ["observability", "--model", "medial", "--motion", "rot", "--control", "known"]
    assert cli.main(argv + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cases"] == 1 and out["agreement"] == 0
    row = out["rows"][0]
    assert (row["model"], row["motion"], row["control"]) == ("medial", "rot", "known")
    assert row["orientation_observable"] and row["why"].endswith("[1]")
    assert cli.main(argv) == 0
    text = capsys.readouterr().out
    assert "known τ breaks head yaw" in text and "agreement with F Tables 3.1/3.2: 0/1" in text
    assert cli.main(["observability", "--points", "0"]) == 2
    assert "points must be >= 1" in capsys.readouterr().err
