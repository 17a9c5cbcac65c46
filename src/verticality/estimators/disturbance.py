"""Extended disturbance observer for the ground motion (T §II.B, eq. 16–19, 23).

The linearized body ``ẋ = A x + B u + N F_d`` (T eq. 16:
:func:`verticality.models.linearize.linearize` of :class:`verticality.models.body.TwoSegmentBody` at
upright, whose input is ``(u, F_d)``, so that the last three columns of its B and D are T's N and E)
is extended with the disturbance ``F_d = (θ1, θ̇1, θ̈1)`` modelled as a chain of integrators with a
piecewise-constant θ̈1 (T eq. 17, Friedland's disturbance model):

    A_e = [[A, N], [0, A_d]],  A_d = [[0, 1, 0], [0, 0, 1], [0, 0, 0]],  B_e = [[B], [0]] (T eq. 18)
    y_e = (θ2, θ3, θ̇2, θ̇3, ω, a_x) = C_e x_e + D u,  C_e = [C, E]                       (T eq. 23)

and estimated by ``x̂_e' = A_e x̂_e + B_e u + L_e (y_e − C_e x̂_e − D u)`` (T eq. 19). The
feed-through ``D u`` (the accelerometer sees the torque-driven accelerations) is not written in
T eq. 19 but follows from the same linearization; without it the a_x innovation would be biased by
every motor command. ``L_e`` is found by pole placement (``control.place``, i.e. the
Kautsky–Nichols–Van Dooren algorithm on the dual pair), as T suggests.

Which measurements the gain uses is an option (``outputs``). Pole placement has no notion of
measurement noise: with all six outputs the algorithm spends gain on a_x, whose sensitivity to θ1
(given the motor command) is only ≈ 0.5 m/s² per rad for a human-sized body — most of ``g φ`` is
cancelled by the gravity-driven accelerations — so its noise dominates the θ1 estimate (see
``docs/linear-tahboub.md`` for the numbers). The ``ground-edo`` experiment places with the five
kinematic outputs (a_x column of L_e zero).
"""

from __future__ import annotations

import numpy as np

from verticality.core.errors import InputError
from verticality.estimators.kalman import ContinuousObserver, continuous_observer
from verticality.models.linearize import LinearModel

A_D = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])  # T eq. 17

STATE_NAMES = ("theta2_rad", "theta3_rad", "theta2_dot_rad_s", "theta3_dot_rad_s",
               "theta1_rad", "theta1_dot_rad_s", "theta1_ddot_rad_s2")


def extended_system(lin: LinearModel):
    """``(A_e, B_e, C_e, D)`` of T eq. 18 and 23 from the body linearized with the input
    ``(u, F_d)``: the last three input columns (of B: T's N; of D: T's E) are the disturbance."""
    k = A_D.shape[0]
    A, B_all, C, D_all = (np.asarray(m, dtype=float) for m in lin)
    n, m = A.shape[0], B_all.shape[1] - k
    if m < 1:
        raise InputError(f"the linear model has {B_all.shape[1]} inputs; it needs the known inputs "
                         f"followed by the {k} of F_d")
    B, N, D, E = B_all[:, :m], B_all[:, m:], D_all[:, :m], D_all[:, m:]
    A_e = np.block([[A, N], [np.zeros((k, n)), A_D]])
    B_e = np.vstack([B, np.zeros((k, m))])
    C_e = np.hstack([C, E])
    return A_e, B_e, C_e, D


def observability_rank(A_e, C_e) -> int:
    """Rank of the observability matrix of ``(A_e, C_e)`` (T: the observer exists iff it is
    full)."""
    n = A_e.shape[0]
    O = np.vstack([C_e @ np.linalg.matrix_power(A_e, i) for i in range(n)])
    return int(np.linalg.matrix_rank(O))


def place_gain(A_e, C_e, poles, outputs=None) -> np.ndarray:
    """Observer gain with ``eig(A_e − L C_e) = poles`` (``control.place`` on the dual pair).

    ``outputs`` (indices into the rows of C_e) restricts the gain to those measurements; the other
    columns of L are zero. ``None`` uses all of them.
    """
    import control

    poles = np.asarray(poles, dtype=complex)
    n = A_e.shape[0]
    p_all = C_e.shape[0]
    idx = np.arange(p_all) if outputs is None else np.asarray(outputs, dtype=int)
    if idx.size == 0 or idx.min() < 0 or idx.max() >= p_all:
        raise InputError(f"outputs must be indices in 0..{p_all - 1}, got {list(idx)}")
    C_e = C_e[idx]
    if poles.shape != (n,):
        raise InputError(f"need {n} observer poles, got {poles.size}")
    if np.any(poles.real >= 0):
        raise InputError("observer poles must have negative real parts")
    if observability_rank(A_e, C_e) < n:
        raise InputError("(A_e, C_e) is not observable; no observer gain can place the poles")
    p = poles.real if np.all(poles.imag == 0) else poles
    L = np.zeros((n, p_all))
    L[:, idx] = np.asarray(control.place(A_e.T, C_e.T, p)).T
    return L


def extended_disturbance_observer(lin: LinearModel, poles, outputs=None) -> ContinuousObserver:
    """T eq. 19 with the pole-placement gain; states ordered as :data:`STATE_NAMES`.

    ``outputs`` selects the measurements the gain uses (see :func:`place_gain`); the observer always
    takes the full y_e of T eq. 23.
    """
    A_e, B_e, C_e, D = extended_system(lin)
    return continuous_observer(A_e, B_e, C_e, D, place_gain(A_e, C_e, poles, outputs))
