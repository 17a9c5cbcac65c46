"""models/vestibular.py: the former function API, adapters onto the model values (for
experiments/model_checks.py). The physics is tested on the values (tests/test_otolith_head.py);
here the adapters give exactly the values' numbers and keep their refusals."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality import so3
from verticality.models import otolith_head as oh
from verticality.models import planar
from verticality.models import vestibular as V
from verticality.models.head import FreeHead
from verticality.models.kinematics import RigidMotion, still
from verticality.models.pendulum import Pendulum, PendulumState
from verticality.params import P13_HEAD, P13_PENDULUM, lateral_pendulums

RNG = np.random.default_rng(3)


def _pend():
    return PendulumState(so3.exp(jnp.asarray(RNG.normal(size=3))), jnp.asarray(RNG.normal(size=3)))


def _same(a, b):
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_array_equal(x, y)


def test_adapters_give_the_values_numbers():
    xl, xr = _pend(), _pend()
    h = V.HeadState(so3.exp(jnp.asarray(RNG.normal(size=3))), jnp.asarray(RNG.normal(size=3)))
    u = V.HeadInput(jnp.array([0.01, -0.02, 0.03]), jnp.array([1.0, -2.0, 0.5]))
    motion = RigidMotion(h.R_I_H, h.omega_H_rad_s, jnp.array([0.3, 0.1, -0.2]), u.a_I_m_s2)
    med = oh.medial(P13_PENDULUM, P13_HEAD)
    d = V.medial_dynamics(V.MedialState(xl, h), u, P13_PENDULUM, P13_HEAD)
    _same(d, med.dynamics(oh.OtolithHeadState((xl,), h), u))
    lat = oh.lateral(P13_PENDULUM, P13_HEAD)
    d = V.lateral_dynamics(V.LateralState(xl, xr, h), u, P13_PENDULUM, hp=P13_HEAD)
    _same(d, lat.dynamics(oh.OtolithHeadState((xl, xr), h), u))
    kin = oh.Otoliths(tuple(Pendulum(p) for p in lateral_pendulums(P13_PENDULUM)))
    _same(V.lateral_dynamics(V.LateralState(xl, xr), motion, P13_PENDULUM).left,
          kin.dynamics((xl, xr), motion)[0])
    _same(V.head_dynamics(h, u.tau_H_Nm, P13_HEAD), FreeHead(P13_HEAD).dynamics(h, u))
    _same(V.medial_outputs(V.MedialState(xl), h.R_I_H), med.otoliths.angles((xl,), h.R_I_H)[0])
    _same(V.lateral_rest_state(motion, P13_PENDULUM, free_head=True),
          (*kin.rest_state(motion), h))
    x = V.PlanarLateralState(*(jnp.asarray(v) for v in RNG.normal(size=6)))
    pu = planar.PlanarInput(*(jnp.asarray(v) for v in RNG.normal(size=3)))
    _same(V.planar_lateral_dynamics(x, pu, planar.PlanarParams(), euler=0.0),
          oh.PlanarLateral(planar.PlanarParams(), euler=0.0).dynamics(x, pu))


def test_still_tilted_head_outputs():
    p = P13_PENDULUM
    R = so3.rot_x(0.3)
    x = V.lateral_rest_state(still(R), p)
    np.testing.assert_allclose(np.asarray(V.lateral_outputs(x, R)), [-0.3, 0.0, -0.3, 0.0],
                               atol=1e-12)
    xm = V.medial_rest_state(still(so3.rot_y(0.3)), p)
    np.testing.assert_allclose(V.medial_outputs(xm, so3.rot_y(0.3)), [0.0, 0.3], atol=1e-12)


def test_mismatched_drive_is_refused():
    p = P13_PENDULUM
    xs = PendulumState(jnp.eye(3), jnp.zeros(3))
    with pytest.raises(ValueError, match="free head"):
        V.medial_dynamics(V.MedialState(xs), V.HeadInput(jnp.zeros(3), jnp.zeros(3)), p, P13_HEAD)
    with pytest.raises(ValueError, match="head=None"):
        V.medial_dynamics(V.MedialState(xs, V.HeadState(jnp.eye(3), jnp.zeros(3))), still(), p)
    with pytest.raises(ValueError, match="multiple"):
        V.simulate(lambda t, x: x, jnp.zeros(1), 1e-3, 10, every=3)
