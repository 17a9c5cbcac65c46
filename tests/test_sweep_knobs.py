"""The `newton-lissajous` kernel's knobs of the trunk motion (``amplitude_scale``,
``frequency_scale``) and of the stabilized head's PD (``kp_Nm_rad``, ``kd_Nms_rad``): the defaults
are the published loop, the scales are the one Lissajous motion scaled, the gains act on the
stabilized head only, a batch equals its runs alone, and bad values are one clear spec error."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.models import lissajous_plant as lp
from verticality.models.lissajous import lissajous_trunk
from verticality.simulation import newton_loop
from verticality.sweep import kernels as K
from verticality.sweep import spec as S

KERNEL = K.NEWTON_LISSAJOUS
DURATION_S = 1.5  # 60 observer samples, the shortest run the kernel allows


def _columns(rows: list[dict]) -> dict[str, np.ndarray]:
    """The kernel's columns for ``rows`` (knob → value; knobs left out at their defaults), with
    P11's perturbed observer (m, J, b, K 10 % high) unless a row says otherwise."""
    perturbed = {k: 0.1 for k in ("m_rel_error", "J_rel_error", "beta_rel_error", "K_rel_error")}
    rows = [perturbed | r for r in rows]
    return {k: np.array([r.get(k, v.default) for r in rows],
                        dtype=object if v.choices else np.float64) for k, v in KERNEL.knobs.items()}


ROWS = [  # one batch: the scales and the gains off their defaults, both heads
    {"head": "fixed", "amplitude_scale": 0.5, "frequency_scale": 2.0},
    {"head": "stabilized", "amplitude_scale": 2.0, "frequency_scale": 0.5},
    {"head": "fixed", "kp_Nm_rad": 460.0, "kd_Nms_rad": 30.0},
    {"head": "fixed"},
    {"head": "stabilized", "kp_Nm_rad": 460.0, "kd_Nms_rad": 30.0},
    {"head": "stabilized"},
]
SEEDS = np.array([4, 4, 4, 4, 4, 4])


@pytest.fixture(scope="module")
def batch():
    return KERNEL.run_batch(_columns(ROWS), SEEDS, duration_s=DURATION_S)


def test_defaults_are_the_published_loop_to_the_bit():
    """The knobs at their defaults add nothing: the kernel's runs at the defaults are, metrics to
    the bit, a vmap of ``simulate`` called without the four knobs — the kernel as it was before
    them, whose runs equal the experiment's (``test_sweep``'s
    ``test_kernel_reproduces_the_experiment_run``); ``simulate``'s defaults are P11's."""
    defaults = {"amplitude_scale": 1.0, "frequency_scale": 1.0, "kp_Nm_rad": newton_loop.KP,
                "kd_Nms_rad": newton_loop.KD}
    assert {k: KERNEL.knobs[k].default for k in K.MOTION_KNOBS} == defaults
    assert (newton_loop.KP, newton_loop.KD) == (230.0, 15.0)  # P11's PD
    columns = _columns([{"head": "fixed"}, {"head": "stabilized"}])
    seeds = np.array([11, 12])
    got = KERNEL.run_batch(columns, seeds, duration_s=DURATION_S)
    (rel, fixed, noise, seeds_j, motion, n_blocks), _ = K.newton_lissajous_args(
        columns, seeds, DURATION_S)
    assert set(motion) == {"kp_Nm_rad", "kd_Nms_rad"}  # the published motion: scales left out
    before = K.newton_lissajous_batch(rel, fixed, noise, seeds_j, n_blocks=n_blocks)
    for name in KERNEL.metrics:
        np.testing.assert_array_equal(got[name], np.asarray(before[name]), err_msg=name)
    assert not got["diverged"].any()


def test_amplitude_zero_is_a_trunk_at_rest():
    """``amplitude_scale = 0``: no trunk motion at all, so the fixed head (rigid on the trunk) stays
    upright and its neck exerts no torque."""
    t = jnp.linspace(0.0, 3.0, 301)
    tr = lp.trunk(t, 0.0, 1.7)
    for a in tr:
        np.testing.assert_array_equal(np.asarray(a), 0.0)
    s = newton_loop.simulate(lp.p11_head(1.0), lp.p11_head(1.1), True, 0.0, jax.random.PRNGKey(0),
                             40, amplitude_scale=0.0)
    np.testing.assert_array_equal(s.theta_H_rad, 0.0)
    np.testing.assert_array_equal(s.tau_Nm, 0.0)
    assert np.max(np.abs(np.asarray(s.reading_rad))) == 0.0  # the pendulum hangs still


def test_frequency_scale_is_the_motion_at_scaled_time():
    """``frequency_scale = 2``: the trunk at t is :func:`lissajous_trunk` at 2t, its rate twice and
    its accelerations four times the published motion's there; and the simulated fixed head, which
    starts with the scaled motion's rate ω_H(0) = Θ̇(0), follows that faster Θ."""
    t = jnp.linspace(0.0, 2.0, 201)
    fast, slow = lp.trunk(t, 0.25, 2.0), lp.trunk(2.0 * t)
    x, z, theta = np.asarray(lissajous_trunk(2.0 * t))
    np.testing.assert_allclose(fast.Theta_rad, theta, rtol=0, atol=1e-15)
    np.testing.assert_allclose(fast.Theta_dot_rad_s, 2.0 * np.asarray(slow.Theta_dot_rad_s),
                               rtol=1e-14, atol=1e-13)
    for a, b in ((fast.a_h_I_m_s2, slow.a_h_I_m_s2), (fast.a_z_I_m_s2, slow.a_z_I_m_s2),
                 (fast.Theta_ddot_rad_s2, slow.Theta_ddot_rad_s2)):
        np.testing.assert_allclose(a, 4.0 * np.asarray(b), rtol=1e-14, atol=1e-12)
    # independently of the autodiff: x'' of A sin(0.5π·2t) is −A π² sin(πt)
    np.testing.assert_allclose(fast.a_h_I_m_s2, -0.25 * np.pi**2 * np.sin(np.pi * t), atol=1e-12)
    s = newton_loop.simulate(lp.p11_head(1.0), lp.p11_head(1.0), True, 0.0, jax.random.PRNGKey(0),
                             80, frequency_scale=2.0)
    want = np.asarray(lissajous_trunk(2.0 * s.t_s))[2]
    # 1.3e-4 rad here (1.6e-5 at the published rate: the 1 ms steps hold Θ̈); a head started at
    # the published rate Θ̇(0) = 4.9 rad/s, half the scaled one, would be off by radians
    np.testing.assert_allclose(s.theta_H_rad, want, rtol=0, atol=1e-3)
    assert np.max(np.abs(want)) > 0.7  # the head did turn (±45°)


def test_a_gain_changes_the_stabilized_run_not_the_fixed_one(batch):
    """Doubled PD gains: the same seed's stabilized run changes, the fixed head (no controller)
    gives the same numbers to the bit."""
    for name in KERNEL.metrics:
        assert batch[name][2] == batch[name][3], name  # fixed: gains × 2 vs the defaults
    assert abs(batch["max_error_deg"][4] - batch["max_error_deg"][5]) > 1e-3  # stabilized


def test_scaled_motion_changes_the_runs(batch):
    """The scales act: the fixed head's error on a half-amplitude, twice-as-fast motion is not
    the published motion's."""
    assert abs(batch["max_error_deg"][0] - batch["max_error_deg"][3]) > 1e-2


def test_batched_equals_alone(batch):
    """Every run of the mixed batch (scales and gains traced, per run) equals the run computed
    alone, to 1e-12 relative; the runs at the published motion computed alone take the constant
    path (scales left out) and still agree to that tolerance."""
    columns = _columns(ROWS)
    for i in range(len(ROWS)):
        alone = KERNEL.run_batch({k: v[i:i + 1] for k, v in columns.items()}, SEEDS[i:i + 1],
                                 duration_s=DURATION_S)
        for name in KERNEL.metrics:
            np.testing.assert_allclose(alone[name][0], batch[name][i], rtol=1e-12, atol=0,
                                       err_msg=f"{name} of run {i}")
        assert alone["diverged"][0] == batch["diverged"][i]


SPEC = """
kernel = "newton-lissajous"
[options]
duration_s = 1.5
[knobs]
head = ["fixed", "stabilized"]
{knob} = [{value}]
[seeds]
count = 2
"""


@pytest.mark.parametrize("knob, value", [
    ("amplitude_scale", -0.5), ("amplitude_scale", 5.0), ("frequency_scale", 0.0),
    ("frequency_scale", 4.5), ("kp_Nm_rad", 0.0), ("kp_Nm_rad", 5000.0), ("kd_Nms_rad", -1.0),
    ("kd_Nms_rad", 80.0), ("frequency_scale", '"fast"'),
])
def test_out_of_range_knobs_are_one_clear_spec_error(knob, value):
    with pytest.raises(InputError) as e:
        S.parse(SPEC.format(knob=knob, value=value))
    assert knob in str(e.value) and ("outside" in str(e.value) or "not a finite" in str(e.value))


def test_in_range_knobs_are_accepted():
    spec = S.parse(SPEC.format(knob="frequency_scale", value="0.25, 4.0").replace(
        "[knobs]", "[knobs]\namplitude_scale = [0.0, 4.0]\nkp_Nm_rad = [2000.0]\n"
                   "kd_Nms_rad = [50.0]"))
    d = S.design(spec)
    assert d.n_runs == 16 and set(d.columns["frequency_scale"]) == {0.25, 4.0}


def test_precompile_covers_the_forms_the_design_batches_need():
    # a batch wholly at P11's motion compiles without the scales, any other with them traced:
    # the parent compiles both when the design has both, so that no worker compiles on its own
    n = 6
    cols = {"amplitude_scale": np.ones(n), "frequency_scale": np.ones(n)}
    assert K.published_batches(cols, 3) == {True}
    cols["frequency_scale"] = np.array([1.0, 1.0, 1.0, 1.0, 0.5, 1.0])
    assert K.published_batches(cols, 3) == {True, False}
    assert K.published_batches(cols, 6) == {False}
    cols["amplitude_scale"] = np.full(n, 2.0)
    assert K.published_batches(cols, 3) == {False}
