"""P13 eq. 3's inclinometer outputs against F 2.8–2.9 (the package's otolith output)."""

import numpy as np
import pytest

from verticality.core import so3
from verticality.models.pendulum import otolith_angles, p13_inclinometer_angles


@pytest.mark.parametrize("eps", [0.1, 0.01, 0.001])
def test_equal_to_abs_f28_to_third_order_without_a_turn_about_the_arm(eps):
    R = np.asarray(so3.rot_x(eps) @ so3.rot_y(-0.7 * eps))
    f = np.abs(np.asarray(otolith_angles(R)))
    p = np.asarray(p13_inclinometer_angles(R))
    assert np.max(np.abs(p - f)) <= 0.5 * eps**3
    assert np.max(np.abs(p - f)) > 0 or eps < 0.01  # not identical: third order, not exact


def test_a_turn_about_the_arm_enters_at_first_order_and_the_sign_is_lost():
    eps = 1e-3
    R = np.asarray(so3.rot_x(eps) @ so3.rot_z(0.5 * eps))
    p = np.asarray(p13_inclinometer_angles(R))
    f = np.asarray(otolith_angles(R))
    np.testing.assert_allclose(p[0], np.hypot(eps, 0.5 * eps), rtol=1e-3)
    assert abs(f[0] - eps) < 1e-6  # F 2.8 sees the turn only at second order
    neg = np.asarray(p13_inclinometer_angles(np.asarray(so3.rot_x(-eps))))
    np.testing.assert_allclose(neg, np.asarray(p13_inclinometer_angles(np.asarray(so3.rot_x(eps)))))


def test_differs_under_p13s_impact_motion():
    from verticality.analysis import model_checks as mc

    diff, phi_max = mc.p13_outputs_minus_abs_f_max_rad()
    assert 0.1 < diff < phi_max
