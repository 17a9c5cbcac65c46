import os
import shutil
import tempfile

os.environ.setdefault("MPLBACKEND", "Agg")
# One compilation cache for the whole session, shared by the worker processes (they inherit the
# variable from the first process, which made the folder) and removed at the end: the suite is
# compile-bound and many tests build the same kernels; nothing compiled outlives the session.
if not os.environ.get("VERTICALITY_TEST_JAX_CACHE"):
    os.environ["VERTICALITY_TEST_JAX_CACHE"] = tempfile.mkdtemp(prefix="verticality-test-jax-")
    _OWN_CACHE = True
else:
    _OWN_CACHE = False
os.environ["VERTICALITY_JAX_CACHE"] = os.environ["VERTICALITY_TEST_JAX_CACHE"]

import jax  # noqa: E402
import pytest  # noqa: E402

import verticality  # noqa: E402, F401  (switches JAX to float64, as every use of the package does)

jax.config.update("jax_compilation_cache_dir", os.environ["VERTICALITY_JAX_CACHE"])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)


def pytest_xdist_make_scheduler(config, log):
    """Files sharing compiled kernels in one worker, the most expensive dealt first
    (tests/worker_schedule.py); the other ``--dist`` modes are xdist's own."""
    if config.getvalue("dist") != "loadfile":
        return None
    from worker_schedule import make_scheduler

    return make_scheduler(config, log)


def pytest_unconfigure(config):
    if _OWN_CACHE and not hasattr(config, "workerinput"):
        shutil.rmtree(os.environ["VERTICALITY_TEST_JAX_CACHE"], ignore_errors=True)


@pytest.fixture(scope="session")
def quick_sweeps():
    """`ekf-sensitivity --quick` (the quick ekf-jump, seed 0, two fixed-head σ_ωH): shared by its
    tests and by `stabilize`'s, which replays the same jump from a recorded MOTION.csv."""
    from verticality.simulation import ekf_ratio_sweeps as sens

    labels = []
    out, simulated_s = sens.run_sweeps(quick=True, progress=labels.append)
    return out, simulated_s, labels


def _swinging_imu(n=1500, dt_s=0.01, seed=0):
    """A tilted sensor swinging about its x axis (±40°, 0.5 Hz), SI units, t from 0."""
    import numpy as np

    from verticality.core import so3
    from verticality.io import imu

    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt_s
    angle = np.radians(40.0) * np.sin(np.pi * t)
    rate = np.radians(40.0) * np.pi * np.cos(np.pi * t)
    R0 = np.asarray(so3.rot_y(np.radians(15.0)))
    R = np.einsum("ij,njk->nik", R0, np.asarray(so3.exp(angle[:, None] * np.array([1.0, 0, 0]))))
    acc = 9.81 * R[:, 2, :] + rng.normal(0, 0.02, (n, 3))
    gyr = np.column_stack([rate, np.zeros(n), np.zeros(n)]) + rng.normal(0, 1e-3, (n, 3))
    return imu.ImuRecording(t, gyr, acc)


@pytest.fixture
def swinging_imu():
    """``swinging_imu(n, dt_s, seed)``: a synthetic IMU recording (:class:`ImuRecording`) of a
    tilted sensor swinging ±40° about its x axis at 0.5 Hz, for the IMU file tests."""
    return _swinging_imu
