"""The estimator contract (estimators/base.py), for every estimator of the project: the Kalman
filter (time-varying, steady-state, continuous), the Luenberger observer, the extended disturbance
observer, the Newton observer, the multiplicative EKF and the 3-D tilt filter. ``run`` equals
``step`` sample by sample, a measurement with no finite component gives exactly ``predict`` and is
flagged, a non-finite input never makes a finite estimate non-finite, and partial measurements are
flagged per component (or for the whole sample, where the estimator uses a sample all or
nothing)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core import so3
from verticality.estimators import base, disturbance, ekf, luenberger, newton, otolith_canal
from verticality.estimators.kalman import (
    continuous_observer,
    kalman_filter,
    steady_state_kalman_filter,
)
from verticality.models import head
from verticality.models import lissajous_plant as lp
from verticality.models.body import HUMAN_TWO_SEGMENT, upright
from verticality.models.linearize import linearize
from verticality.models.otolith_head import OtolithHeadState
from verticality.models.params import P13_EKF_HEAD, P13_EKF_PENDULUM
from verticality.models.pendulum import PendulumState
from verticality.models.planar import HeadInput, PlanarState
from verticality.perception.laurens import laurens_angelaki
from verticality.perception.merfeld import MerfeldZupan
from verticality.perception.params import LAURENS_PRESETS, MERFELD_PRESETS
from verticality.simulation.separation_loop import linear_model
from verticality.tilt import TiltFilter

DT = 0.01
N = 30


def _otolith(form):
    F, H = otolith_canal.matrices()
    Q, R = otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R
    return {"time-varying": lambda: kalman_filter(F, None, H, None, Q, R),
            "steady-state": lambda: steady_state_kalman_filter(F, None, H, None, Q, R, DT),
            "continuous": lambda: continuous_observer(F, None, H, None,
                                                      otolith_canal.steady_state_gain())}[form]()


@functools.cache
def _case(name):
    """(estimator, x0, P0, us (N, ...), ys (N, p), dt) for each estimator of this half: one value
    per estimator for the module, so that its compiled methods (:func:`_compiled`) are shared by
    the tests (the cases copy what they change)."""
    rng = np.random.default_rng(4)
    if name in ("time-varying", "steady-state", "continuous"):
        ys = rng.normal(size=(N, 2)) * np.array([0.01, 0.3])
        return _otolith(name), jnp.array([0.1, 0.2, 0.01]), jnp.eye(3) * 0.01, None, ys, DT
    if name == "luenberger":
        est = luenberger.design(linear_model(), (-100.0, -110.0, -120.0, -130.0))
        us = rng.normal(size=(N, 2)) * np.array([1e-4, 1.0])
        return est, jnp.array([0.0, 0.0, 0.3, 0.0]), None, us, rng.normal(size=(N, 1)) * 0.1, 1e-3
    if name == "disturbance":
        lin = linearize(HUMAN_TWO_SEGMENT, *upright())
        est = disturbance.extended_disturbance_observer(lin, (-6.0, -7.0, -8.0, -9.0, -10.0,
                                                              -11.0, -12.0))
        us = rng.normal(size=(N, 2))
        return est, jnp.zeros(7), None, us, rng.normal(size=(N, 6)) * 0.01, DT
    if name == "ekf":
        est = ekf.medial_filter(P13_EKF_PENDULUM, P13_EKF_HEAD, (1e-3, 0.3, 1e-3, 0.03))
        x0 = OtolithHeadState(
            (PendulumState(so3.exp(jnp.array([0.1, -0.2, 0.3])), jnp.array([0.3, 0.1, -0.2])),),
            head.HeadState(so3.exp(jnp.array([0.2, 0.1, 0.4])), jnp.array([0.5, -0.3, 1.0])))
        us = head.HeadInput(jnp.asarray(rng.normal(scale=0.01, size=(N, 4, 3))),
                            jnp.asarray(rng.normal(scale=1.0, size=(N, 4, 3))))
        return (est, x0, 0.01 * jnp.eye(ekf.N_ERR), us, rng.normal(scale=0.1, size=(N, ekf.N_Y)),
                0.02)
    if name in ("merfeld", "laurens"):
        est = (MerfeldZupan(MERFELD_PRESETS["observer"]) if name == "merfeld"
               else laurens_angelaki(LAURENS_PRESETS["default"]))
        x0 = est.init(None)._replace(g_H=jnp.array([0.1, -0.2, -0.97])
                                     / np.linalg.norm([0.1, -0.2, -0.97]))
        ys = np.concatenate([rng.normal(scale=0.3, size=(N, 3)),
                             np.array([0.05, 0.1, -1.0]) + rng.normal(scale=0.05, size=(N, 3))],
                            axis=1)
        return est, x0, None, None, ys, DT
    if name == "tilt":
        x0 = (np.array([0.99, 0.1, -0.05, 0.0]), np.array([0.01, -0.02, 0.0]))
        acc = np.array([0.5, -0.3, 9.8]) + rng.normal(scale=0.05, size=(N, 3))
        return TiltFilter(), x0, None, rng.normal(scale=0.1, size=(N, 3)), acc, DT
    # the Newton observer on the P11 plant, window 4 so that it solves within the sequence
    z = jnp.zeros(25)
    est = newton.NewtonObserver(lp.observer_model(lp.p11_head(), 5), HeadInput(z, z, z),
                                newton.NewtonConfig(window=4, iterations=3))
    t = (np.arange(N * 25) + 0.5) * 1e-3
    tr = lp.trunk(t)
    blk = lambda a: jnp.asarray(np.asarray(a).reshape(N, 25))  # noqa: E731
    us = HeadInput(blk(0.5 * np.asarray(tr.Theta_ddot_rad_s2) * lp.p11_head().K_kg_m2),
                   blk(tr.a_h_I_m_s2), blk(tr.a_z_I_m_s2))
    ys = 0.02 * np.sin(np.arange(N) * 0.3)[:, None]
    x0 = PlanarState(*(jnp.asarray(v) for v in (0.01, 0.0, 0.02, 0.1)))
    return est, x0, None, us, ys, 0.025


@functools.cache
def _compiled(name, method):
    """``_case(name)``'s estimator's ``method``, compiled once for the module (as ``run`` uses it;
    each ``jax.jit`` of a bound method would trace and compile it again); the tilt filter's own
    (NumPy at its edges) as it is."""
    fn = getattr(_case(name)[0], method)
    return fn if name == "tilt" else jax.jit(fn)


NAMES = ["time-varying", "steady-state", "continuous", "luenberger", "disturbance", "newton", "ekf",
         "tilt", "merfeld", "laurens"]
WHOLE_SAMPLE = {"tilt"}  # estimators that use a sample all or nothing (one flag per sample)


def _at(us, k):
    return None if us is None else jax.tree_util.tree_map(lambda a: jnp.asarray(a)[k], us)


def _u(us, k):
    return 0.0 if us is None else _at(us, k)


def _leaves(tree):
    return np.concatenate([np.ravel(np.asarray(a, dtype=float))
                           for a in jax.tree_util.tree_leaves(tree)])


def _estimate(state):
    """The estimate a state holds (the Newton observer's data buffers are not part of it; the
    perception models' state is their estimate)."""
    if hasattr(state, "x_hat"):
        return _leaves(state.x_hat)
    return _leaves(state.x if hasattr(state, "x") else state)


def test_every_estimator_is_an_estimator():
    for name in NAMES:
        assert isinstance(_case(name)[0], base.Estimator), name


@pytest.mark.parametrize("name", NAMES)
def test_run_is_repeated_step(name):
    est, x0, P0, us, ys, dt = _case(name)
    ys = np.array(ys)
    ys[5] = np.nan  # a sample with nothing measured
    ys[9, -1] = np.nan  # and one with a component missing
    s0 = est.init(x0, P0)
    final, outs = _compiled(name, "run")(s0, us, ys, dt)
    step = _compiled(name, "step")
    s = s0
    for k in range(N):
        s, o = step(s, _u(us, k), ys[k], dt)
    np.testing.assert_allclose(_leaves(s), _leaves(final), rtol=1e-10, atol=1e-12, equal_nan=True)
    assert not np.any(np.asarray(outs.measured)[5])
    if name in WHOLE_SAMPLE:
        assert (not bool(np.asarray(outs.measured)[9])
                and bool(np.all(np.asarray(outs.measured)[10:])))
    else:
        assert np.asarray(outs.measured)[9].tolist() == [True] * (ys.shape[1] - 1) + [False]
    assert np.all(np.isfinite(_estimate(final)))
    if name == "newton":
        assert bool(np.any(np.asarray(outs.solved)))


@pytest.mark.parametrize("name", NAMES)
def test_no_measurement_is_predict_and_finite_stays_finite(name):
    est, x0, P0, us, ys, dt = _case(name)
    s0 = est.init(x0, P0)
    step = _compiled(name, "step")
    # a float64 array like the measurements `run` gets (a weakly typed one would compile `step`
    # again rather than reuse test_run_is_repeated_step's)
    s_nan, out = step(s0, _u(us, 0), jnp.full(np.shape(ys)[1], jnp.nan, dtype=float), dt)
    s_pred = _compiled(name, "predict")(s0, _u(us, 0), dt)
    for a, b in zip(jax.tree_util.tree_leaves(s_nan), jax.tree_util.tree_leaves(s_pred),
                    strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert not np.any(np.asarray(out.measured))
    # a non-finite input: the estimate stays finite (the previous one is kept). Of the type of
    # the input `step` had above (the estimators without one take a weakly typed 0.0: a float64
    # array would compile `step` again)
    u_bad = jax.tree_util.tree_map(lambda a: jnp.full_like(jnp.asarray(a), jnp.nan), _u(us, 0))
    s_bad, _ = step(s0, u_bad, jnp.asarray(ys[0]), dt)
    assert np.all(np.isfinite(_estimate(s_bad)))
