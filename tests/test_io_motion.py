"""MOTION.csv / OUT.csv: exact round trips and one-line refusals naming row and column."""

import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.io import motion as io

HEADER = "t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az\n"
GOOD = "0,1,0,0,0,0,0,0,0,0,0\n"


def _write(tmp_path, text):
    p = tmp_path / "m.csv"
    p.write_text(text)
    return p


def test_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    n = 7
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rec = io.MotionRecord(np.cumsum(rng.uniform(0.001, 0.01, n)), q, rng.normal(size=(n, 3)),
                          rng.normal(size=(n, 3)))
    back = io.read_motion_csv(io.write_motion_csv(tmp_path / "m.csv", rec))
    np.testing.assert_array_equal(back.t_s, rec.t_s)
    np.testing.assert_array_equal(back.omega_H_rad_s, rec.omega_H_rad_s)
    np.testing.assert_array_equal(back.a_I_m_s2, rec.a_I_m_s2)
    np.testing.assert_allclose(back.q_I_H_wxyz, rec.q_I_H_wxyz, atol=1e-15)  # renormalized
    s = rng.normal(size=(n, 2, 3))
    phi = rng.normal(size=(n, 2, 2))
    out = io.read_otolith_csv(io.write_otolith_csv(tmp_path / "o.csv", rec.t_s, s, phi,
                                                   ("_left", "_right")))
    assert list(out) == io.otolith_columns(("_left", "_right"))
    np.testing.assert_array_equal(out["phi_y_right"], phi[:, 1, 1])
    np.testing.assert_array_equal(out["sx_left"], s[:, 0, 0])


def test_columns_in_any_order_and_extra_columns(tmp_path):
    p = _write(tmp_path, "az,extra,t,qw,qx,qy,qz,wx,wy,wz,ax,ay\n9,x,0,1,0,0,0,0,0,0,0,0\n")
    rec = io.read_motion_csv(p)
    assert rec.a_I_m_s2[0, 2] == 9.0 and rec.t_s[0] == 0.0


@pytest.mark.parametrize(
    "text, expected",
    [
        ("t,qw,qx,qy,qz,wx,wy,wz,ax,ay\n0,1,0,0,0,0,0,0,0,0\n", "missing column(s) az"),
        (HEADER + GOOD + "0.1,1,0,0,0,0,nan,0,0,0,0\n", "row 2 (line 3), column wy"),
        (HEADER + GOOD + "0.1,1,0,0,0,0,0,0,0,abc,0\n", "row 2 (line 3), column ay: not a number"),
        (HEADER + GOOD + "0.1,1,0,0,0,0,0,0,0,0\n", "row 2 (line 3), column az: missing value"),
        (HEADER + GOOD + "0.1,1,0,0,0,0,0,0,0,0,0\n0.1,1,0,0,0,0,0,0,0,0,0\n",
         "row 3 (line 4), column t"),
        (HEADER + GOOD + "0.1,0.9,0,0,0,0,0,0,0,0,0\n", "row 2 (line 3), columns qw,qx,qy,qz"),
        (HEADER, "no data rows"),
        ("", "empty file"),
    ],
)
def test_bad_files_are_refused_in_one_line(tmp_path, text, expected):
    with pytest.raises(InputError) as err:
        io.read_motion_csv(_write(tmp_path, text))
    msg = str(err.value)
    assert expected in msg and "\n" not in msg
