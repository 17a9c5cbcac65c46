"""The `ekf-impact` / `ekf-jump` sweep kernels: the experiment's closed loop, knob by knob."""

from __future__ import annotations

import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pyarrow.parquet as pq
import pytest

from verticality.core.errors import InputError
from verticality.experiments import ekf as ekf_experiment
from verticality.simulation import ekf_runs, trajectories
from verticality.sweep import distribute
from verticality.sweep import spec as S
from verticality.sweep.ekf_kernels import EKF_IMPACT, EKF_JUMP

# the ekf-impact quick run, fixed and stabilized, seed 0 (the experiment's quick seed), in the
# experiment's settings: every knob at its default
TINY = """
kernel = "ekf-impact"
batch = 1
runs_per_task = 2
[options]
quick = true
[knobs]
head = ["fixed", "stabilized"]
[seeds]
values = [0]
"""


def test_a_tiny_sweep_in_process_is_the_experiment(tmp_path):
    """The tiny sweep through distribute's in-process path (a task computed and written here,
    no cluster) gives `ekf-impact --quick`'s numbers: the same max to the bit, the RMS to 1e-12."""
    spec = S.parse(TINY)
    design = S.design(spec)
    assert design.n_runs == 2 and list(design.columns["head"]) == ["fixed", "stabilized"]
    assert design.columns["head_rate_sigma"][0] == ekf_runs.SIGMA_PROCESS[3]
    assert design.columns["noise_std"][0] == ekf_runs.SIGMA_MEASUREMENT
    parts = tmp_path / "parts"
    parts.mkdir()
    distribute.run_task(spec.kernel, spec.options, design, 0, 0, spec.batch, str(parts))
    table = pq.read_table(distribute.part_path(parts, 0)).to_pydict()
    result = ekf_experiment.run_impact(quick=True).metrics
    assert table["seed"] == [0, 0] and table["diverged"] == [False, False]
    for i, head in enumerate(("fixed", "stabilized")):
        assert table["head"][i] == head
        assert table["max_error_deg"][i] == result["max_tilt_error_deg_per_seed"][head][0]
        np.testing.assert_allclose(table["rms_error_deg"][i], result["rms_tilt_error_deg"][head],
                                   rtol=1e-12)
    # the benefit P13 reports, as the experiment scores it
    assert table["rms_error_deg"][1] < table["rms_error_deg"][0] / 3.0


def test_scaled_trajectories_go_through_the_trajectory_parameters():
    """Amplitude × a and frequency × f are the trajectory functions' own parameters scaled (the
    jump's durations ÷ f); scale 1 is the experiment's trajectory."""
    t = np.array([0.7, 2.3, 4.9, 5.3])
    a, f = 2.0, 0.5
    for scenario, fn in (("impact", trajectories.impact), ("jump", trajectories.jump)):
        d = {k: v.default for k, v in inspect.signature(fn).parameters.items()}
        base = ekf_runs.scenario_trajectory(scenario)
        if scenario == "impact":
            ref = fn(ramp_in_s=ekf_runs.IMPACT_RAMP_IN_S,
                     translation_amplitude_m=tuple(a * x for x in d["translation_amplitude_m"]),
                     rotation_amplitude_rad=tuple(a * x for x in d["rotation_amplitude_rad"]),
                     translation_frequency_hz=tuple(f * x for x in d["translation_frequency_hz"]),
                     rotation_frequency_hz=tuple(f * x for x in d["rotation_frequency_hz"]))
        else:
            ref = fn(duration_s=ekf_runs.JUMP_DURATION_S, t_push_s=ekf_runs.JUMP_T_PUSH_S,
                     jump_length_m=a * d["jump_length_m"], pitch_rad=a * d["pitch_rad"],
                     roll_rad=a * d["roll_rad"], push_sigma_s=d["push_sigma_s"] / f,
                     flight_s=d["flight_s"] / f, edge_sigma_s=d["edge_sigma_s"] / f)
        got = ekf_runs.scenario_trajectory(scenario, amplitude_scale=a, frequency_scale=f)
        one = ekf_runs.scenario_trajectory(scenario, amplitude_scale=1.0, frequency_scale=1.0)
        assert got.duration_s == base.duration_s == ref.duration_s
        for fn_name in ("position_I_m", "rpy_rad"):  # the functions the motion is derived from
            x, y, z, w = (np.asarray(jax.vmap(getattr(tr, fn_name))(jnp.asarray(t)))
                          for tr in (got, ref, base, one))
            np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(w, z)  # scale 1: the experiment's trajectory
            assert not np.allclose(x, z)  # the scales did something


@pytest.mark.parametrize("change, words", [
    (("head = [\"fixed\", \"stabilized\"]", "head = [\"floating\"]"),
     "not one of fixed, stabilized"),
    (("head = [\"fixed\", \"stabilized\"]", "amplitude_scale = [0.1]"),
     "knob amplitude_scale: 0.1 is outside [0.25, 3.0]"),
    (("head = [\"fixed\", \"stabilized\"]", "frequency_scale = [4.0]"), "frequency_scale: 4.0"),
    (("head = [\"fixed\", \"stabilized\"]", "head_rate_sigma = [0.0]"), "outside (0.0, 1.0]"),
    (("head = [\"fixed\", \"stabilized\"]", "noise_std = [-0.02]"), "noise_std: -0.02"),
    (("quick = true", "quick = 1"), "quick = 1 must be true or false"),
    (("quick = true", "duration_s = 3.0"), "has no option(s) duration_s"),
])
def test_bad_knob_is_one_clear_error(change, words):
    for kernel in ("ekf-impact", "ekf-jump"):
        with pytest.raises(InputError) as exc:
            S.parse(TINY.replace("ekf-impact", kernel).replace(*change))
        assert words in str(exc.value) and "\n" not in str(exc.value)


def test_the_kernels_mark_the_published_condition():
    for k in (EKF_IMPACT, EKF_JUMP):
        assert k.published == {"amplitude_scale": 1.0, "frequency_scale": 1.0}
        assert k.knobs["amplitude_scale"].default == k.knobs["frequency_scale"].default == 1.0
