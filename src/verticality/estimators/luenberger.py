"""Luenberger observer on a linear(ized) model (F eq. 4.10), gain by pole placement.

    dx̂/dt = A x̂ + B u + L (y − C x̂ − D u)                                  (F 4.10)

``A, B, C, D`` typically come from :func:`verticality.models.linearize.linearize` of a model value
at upright; ``L`` from :func:`design` (``control.place`` on the dual pair, so that ``eig(A − L C)``
are the requested poles). The observer is the fixed-gain
:class:`~verticality.estimators.kalman.ContinuousObserver`: between samples ``u`` and ``y`` are held
(zero-order hold) and the observer ODE is integrated exactly by one matrix exponential per step, so
the discrete observer has its poles at ``exp(p·dt)`` for any ``dt``; a NaN component of ``y`` is
not measured (its gain column is zero for that step, ``out.measured`` says so).

    obs = design(model, poles)                       # a ContinuousObserver
    state = obs.init(x0)
    state, out = obs.step(state, u, y, dt)           # out.x: x̂ at the end of the sample
    state, outs = obs.run(state, us, ys, dts)
"""

from __future__ import annotations

import numpy as np

from verticality.core.errors import InputError
from verticality.estimators.kalman import ContinuousObserver, continuous_observer
from verticality.models.linearize import LinearModel


def design(model: LinearModel, poles) -> ContinuousObserver:
    """Place the poles of ``A − L C`` at ``poles`` (python-control ``place`` on the dual system)."""
    import control

    A, C = np.asarray(model.A, float), np.asarray(model.C, float)
    poles = np.atleast_1d(np.asarray(poles))
    if poles.shape != (A.shape[0],):
        raise InputError(f"Luenberger design: need {A.shape[0]} poles, got {poles.size}")
    if np.any(np.real(poles) >= 0):
        raise InputError("Luenberger design: observer poles must have negative real parts")
    if np.linalg.matrix_rank(control.obsv(A, C)) < A.shape[0]:
        raise InputError("Luenberger design: (A, C) is not observable")
    L = np.asarray(control.place(A.T, C.T, poles)).T
    return continuous_observer(model.A, model.B, model.C, model.D, L)
