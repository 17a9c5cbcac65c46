"""The runnable Python examples of the README and the docs run as written (a renamed function breaks
this test, not a reader's first try). Each example gets only the data a reader would have: an
IMU recording as arrays, or a ``recording.csv`` in the working folder."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _blocks(rel: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / rel).read_text(encoding="utf-8"), re.S)


def _imu(n=600, dt_s=0.01):
    """A sensor tilted 10° about x, turning slowly about z: the arrays a reader would load."""
    t = np.arange(n) * dt_s
    g = 9.81 * np.array([0.0, np.sin(np.radians(10.0)), np.cos(np.radians(10.0))])
    acc = np.tile(g, (n, 1)) + np.random.default_rng(0).normal(0, 0.02, (n, 3))
    gyr = np.tile([0.0, 0.0, 0.05], (n, 1))
    return t, gyr, acc, dt_s


# (file, index of the python block among the file's blocks). The chain of docs/architecture.md (one
# medial value into a StateSpace and an EKF) is the one tests/test_architecture.py runs with the
# same calls; run here as written it costs ~45 s of eager differentiation, so it is left to that
# test.
EXAMPLES = [("README.md", 0), ("docs/tutorials/tilt-from-imu.md", 0),
            ("docs/observability.md", 0), ("docs/tutorials/extend.md", 0)]


@pytest.mark.parametrize(("rel", "index"), EXAMPLES, ids=[f"{r}[{i}]" for r, i in EXAMPLES])
def test_example_runs_as_written(rel, index, tmp_path, monkeypatch):
    code = _blocks(rel)[index]
    t, gyr, acc, dt_s = _imu()
    header = "t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z"
    np.savetxt(tmp_path / "recording.csv", np.column_stack([t, gyr, acc]), delimiter=",",
               header=header, comments="")
    monkeypatch.chdir(tmp_path)
    namespace = {"gyr_rad_s": gyr, "acc_m_s2": acc, "dt_s": dt_s, "t_s": t,
                 "gyr": gyr[0], "acc": acc[0], "dt": dt_s}
    exec(compile(code, f"{rel}[{index}]", "exec"), namespace)  # noqa: S102
    if "out" in namespace and hasattr(namespace["out"], "roll_rad"):
        roll = np.degrees(np.asarray(namespace["out"].roll_rad))
        assert np.all(np.isfinite(roll))
        assert abs(roll[-1] - 10.0) < 1.0  # the example's tilt is the recording's
