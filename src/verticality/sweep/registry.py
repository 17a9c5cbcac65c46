"""The sweep kernels by name (:data:`KERNELS`): every kernel module's kernels, in one table."""

from __future__ import annotations

from verticality.sweep.ambiguity_kernel import AMBIGUITY_WALKING
from verticality.sweep.ekf_kernels import EKF_IMPACT, EKF_JUMP
from verticality.sweep.kernels import NEWTON_LISSAJOUS, Kernel

KERNELS: dict[str, Kernel] = {k.name: k for k in (NEWTON_LISSAJOUS, EKF_IMPACT, EKF_JUMP,
                                                  AMBIGUITY_WALKING)}
