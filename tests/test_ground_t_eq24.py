"""T eq. 24's printed observer gain beside ours (`ground-edo`)."""

import numpy as np

from verticality.estimators.disturbance import extended_system
from verticality.experiments import ground as G
from verticality.models.body import TwoSegmentBody
from verticality.simulation import ground_loop


def test_printed_gain_read_as_two_halves_matches_ts_description():
    L = G.T_EQ24_GAIN
    assert L.shape == (7, 6)
    col = np.max(np.abs(L), axis=0)
    # T: the three angular-rate columns (3, 4, 5) carry the high gains; a_x (6) is small
    assert min(col[2:5]) > 10 * max(col[0], col[1]) and col[5] < 0.01 * min(col[2:5])


def test_printed_gain_on_our_body_leaves_one_unstable_pole():
    A, _, C, _ = (np.asarray(m) for m in extended_system(ground_loop.linear_body(TwoSegmentBody())))
    poles = np.linalg.eigvals(A - G.T_EQ24_GAIN @ C)
    assert np.sum(np.real(poles) > 0) == 1 and np.sum(np.real(poles) < -5) == 6
