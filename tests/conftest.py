import os

os.environ.setdefault("MPLBACKEND", "Agg")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def quick_sweeps():
    """`ekf-sensitivity --quick` (the quick ekf-jump, seed 0, two fixed-head σ_ωH): shared by its
    tests and by `stabilize`'s, which replays the same jump from a recorded MOTION.csv."""
    from verticality.experiments import ekf_sensitivity as sens

    labels = []
    out, simulated_s = sens.run_sweeps(quick=True, progress=labels.append)
    return out, simulated_s, labels
