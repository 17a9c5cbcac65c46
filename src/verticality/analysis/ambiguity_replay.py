"""How far the tilt–translation ambiguity bites on a recorded head motion (F §3.2).

For a head motion (MOTION.csv, :mod:`verticality.io.motion`) the otolith pendulum is replayed
(:func:`verticality.simulation.closed_loop.otolith_replay`, the project's pendulum model value) and
its angles are read as an accelerometer under the **upright assumption** (F 3.14–3.15, the head's
tilt taken as zero, the vertical head-frame acceleration ``a_z`` known from the saccule):
:func:`verticality.analysis.ambiguity.head_acceleration`. The indicated horizontal acceleration is
compared with the true one (the recording's acceleration in head-frame components). Its error has
two sources: the head's real tilt (``g tan Θ`` for a still tilted head, the ambiguity itself) and
the otolith's own dynamics (the pendulum lags; zero in steady state).

The default otolith is F §4.5.2's (critically damped, 300 Hz natural frequency); ``otolith="p13"``
takes the P13 pendulum of the `otolith` command (slow and lightly damped, so its dynamics dominate
the error).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from verticality.analysis import ambiguity as am
from verticality.core import so3
from verticality.core.errors import InputError
from verticality.io.motion import MotionRecord
from verticality.models.otolith_presets import otolith_pendula
from verticality.models.params import (
    F452_OTOLITH_DAMPING_RATIO,
    F452_OTOLITH_NATURAL_HZ,
    G_M_S2,
)

OTOLITHS = ("f452", "p13")
F452_MASS_KG = 0.01  # only g/l and β/(m l²) matter


class UprightReading(NamedTuple):
    t_s: np.ndarray  # (N,)
    a_true_H_m_s2: np.ndarray  # (N, 3) head-frame acceleration of the recording (gravity excluded)
    a_indicated_H_m_s2: np.ndarray  # (N, 3) what the otolith indicates under the upright assumption
    error_H_m_s2: np.ndarray  # (N, 2) indicated − true, x and y
    tilt_deg: np.ndarray  # (N, 2) the head's true tilt angles Θx, Θy (F 3.8–3.9)
    phi_rad: np.ndarray  # (N, 2) the otolith angles φx, φy (F 2.8–2.9)
    summary: dict


def otolith_values(otolith: str) -> dict[str, float]:
    """The parameter values of :func:`verticality.models.otolith_presets.otolith_pendula` for
    ``otolith`` (by name; none for P13's own)."""
    if otolith not in OTOLITHS:
        raise InputError(f"otolith must be one of {', '.join(OTOLITHS)}, not {otolith!r}")
    if otolith == "p13":
        return {}
    w_n = 2.0 * math.pi * F452_OTOLITH_NATURAL_HZ
    l_m = G_M_S2 / w_n**2
    J = F452_MASS_KG * l_m**2
    beta = 2.0 * F452_OTOLITH_DAMPING_RATIO * w_n * J
    # isotropic inertia: the turn about the arm does not move the arm, and with P13's J_zz = J/20
    # its damping rate β/J_zz = 40 ω_n would need sub-steps below 40 µs
    return {"m": F452_MASS_KG, "l": l_m, "beta": beta, "Jxx": J, "Jyy": J, "Jzz": J}


def upright_reading(record: MotionRecord, otolith: str = "f452", progress=None) -> UprightReading:
    """The acceleration the otolith indicates under the upright assumption, against the truth."""
    from verticality.simulation import closed_loop as simulation

    pendula, _ = otolith_pendula("medial", otolith_values(otolith))
    max_substep = 1e-4 if otolith == "f452" else 1e-3
    _, phi = simulation.otolith_replay(record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s,
                                       record.a_I_m_s2, pendula, max_substep_s=max_substep,
                                       progress=progress)
    phi = np.asarray(phi)[:, 0, :]
    R_I_H = np.asarray(so3.matrix_from_quat(jnp.asarray(record.q_I_H_wxyz)))
    a_H = np.einsum("nji,nj->ni", R_I_H, np.asarray(record.a_I_m_s2, float))
    a_ind = np.asarray(am.head_acceleration(phi[:, 0], phi[:, 1], a_H[:, 2]))
    err = a_ind[:, :2] - a_H[:, :2]
    tilt = np.degrees(np.asarray(so3.tilt_angles(R_I_H)))
    summary = {
        "otolith": otolith,
        "samples": int(record.t_s.size),
        "duration_s": float(record.t_s[-1] - record.t_s[0]),
        "rms_true_acceleration_m_s2": {k: float(np.sqrt(np.mean(a_H[:, i] ** 2)))
                                       for i, k in enumerate("xy")},
        "rms_error_m_s2": {k: float(np.sqrt(np.mean(err[:, i] ** 2))) for i, k in enumerate("xy")},
        "max_abs_error_m_s2": {k: float(np.max(np.abs(err[:, i]))) for i, k in enumerate("xy")},
        # Θx, Θy: the tilt about the head's x and y axes
        "max_abs_tilt_deg": {k: float(np.max(np.abs(tilt[:, i]))) for i, k in enumerate("xy")},
        # a_x is biased by the tilt about y (Θy), a_y by the tilt about x: g tan Θ for a still head
        "still_head_error_at_max_tilt_m_s2": {
            k: float(G_M_S2 * math.tan(math.radians(np.max(np.abs(tilt[:, 1 - i])))))
            for i, k in enumerate("xy")},
    }
    return UprightReading(np.asarray(record.t_s, float), a_H, a_ind, err, tilt, phi, summary)


def columns(r: UprightReading) -> dict:
    """The OUT.csv columns: t, true and indicated head-frame accelerations, their difference, the
    true tilt (deg) and the otolith angles (rad)."""
    return {"t": r.t_s,
            "ax_true": r.a_true_H_m_s2[:, 0], "ay_true": r.a_true_H_m_s2[:, 1],
            "az_true": r.a_true_H_m_s2[:, 2],
            "ax_upright": r.a_indicated_H_m_s2[:, 0], "ay_upright": r.a_indicated_H_m_s2[:, 1],
            "ax_error": r.error_H_m_s2[:, 0], "ay_error": r.error_H_m_s2[:, 1],
            "tilt_x_deg": r.tilt_deg[:, 0], "tilt_y_deg": r.tilt_deg[:, 1],
            "phi_x": r.phi_rad[:, 0], "phi_y": r.phi_rad[:, 1]}


def plot(r: UprightReading, path) -> None:
    """True and indicated accelerations, their error and the head's tilt against time."""
    from verticality.core.plots import new_figure, save

    fig, axes = new_figure(3, 1, width=10)
    for i, k in enumerate("xy"):
        axes[i, 0].plot(r.t_s, r.a_true_H_m_s2[:, i], label=f"a_{k} true (head frame)")
        axes[i, 0].plot(r.t_s, r.a_indicated_H_m_s2[:, i], lw=0.8,
                        label=f"a_{k} indicated, upright assumption")
        axes[i, 0].plot(r.t_s, r.error_H_m_s2[:, i], lw=0.8, color="C3", label="error")
        axes[i, 0].set_ylabel("m/s²")
        axes[i, 0].legend(fontsize=7)
    axes[2, 0].plot(r.t_s, r.tilt_deg[:, 0], label="Θx")
    axes[2, 0].plot(r.t_s, r.tilt_deg[:, 1], label="Θy")
    axes[2, 0].set_ylabel("head tilt [deg]")
    axes[2, 0].set_xlabel("t [s]")
    axes[2, 0].legend(fontsize=7)
    save(fig, path)


def write(r: UprightReading, out=None, plot_path=None) -> None:
    """Write OUT.csv (:func:`columns`) and/or the figure."""
    from verticality.io.motion import write_columns_csv

    if out is not None:
        write_columns_csv(out, columns(r))
    if plot_path is not None:
        plot(r, plot_path)


def report(motion_path, out=None, plot_path=None, otolith: str = "f452", progress=None) -> dict:
    """The `ambiguity` command's one call: read MOTION.csv, :func:`upright_reading`, write OUT.csv
    and the figure if asked; returns the summary."""
    from verticality.io.motion import read_motion_csv

    r = upright_reading(read_motion_csv(motion_path), otolith, progress)
    write(r, out, plot_path)
    return r.summary
