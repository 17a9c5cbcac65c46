"""`observability`: F §3.1, Tables 3.1 and 3.2 — is the head's tilt observable from the otoliths?

Readings and choices (the thesis leaves them open or they had to be fixed):

- Test: local generic-rank (Hermann–Krener / Sedoglavic) test of
  :mod:`verticality.analysis.observability` in float64 at two random points per case, rotations on
  the tangent space of SO(3); rank tolerance 1e-8 relative after row normalisation, quantity
  residual 1e-6. Derivative orders 8 (medial) and 6 (lateral); every case is checked to have stopped
  gaining rank before that order.
- "Orientation observable" = the tilt ``R_IHᵀ e3`` (which fixes Θx, Θy of F 3.8–3.9) lies in the
  observable span; yaw about gravity is never observable from otoliths and is not asked.
  "Acceleration identifiable" = all three components of the constant head-frame acceleration
  ``H a``.
- Models: the ``OtolithHead`` values of ``models/otolith_head.py`` in the simplified form of
  F 2.7 / 2.12 (no gyroscopic, no Euler term; centripetal term kept for the lateral pendula);
  lateral pivots at ±0.05 m on the head's y axis; head ``J_H ω̇ = τ``. Unknown torque and
  acceleration, known torque and the feedback enter through the model's input.
- Outputs: the otolith angles of F 2.8–2.9 as written (third row of ``R_HS``).
- Controls: ``unknown`` = constant unknown torque, ``known`` = known input with free derivatives,
  ``stabilized`` = F 2.20–2.21 with the restoring sign.
- Parameters: generic O(1) values (anisotropic head inertia J_H = (1, 1.2, 0.9)). Full mode also
  runs the P13 plant, whose isotropic head (J_H = 0.125 I, scalar gains) makes the stabilized
  medial model equivariant under yaw conjugation: there the tilt's direction is hidden too.
- Full mode also runs two other formulations: rotation-matrix entries as free variables (``chart =
  ambient``, the formulation of a rational-model tool) and otolith angles from the pendulum's axis
  in the head frame (third column of ``R_HS``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from verticality.experiments import Result, check, register


def _validation() -> dict:
    from verticality.analysis import observability as ob
    from verticality.analysis import observability_examples as ex

    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 4)) * 0.5
    A[:2, 2:] = 0.0
    C = np.array([[1.0, -0.5, 0.0, 0.0]])
    lin = ob.analyze(ex.linear(A, C), points=2)
    acc = ob.analyze(ex.accelerometer(), points=2)
    uni = ob.analyze(ex.unicycle("position"), points=2)
    pen = ob.analyze(ex.pendulum_from_rate(), points=2)
    prod = ob.analyze(ex.product_parameter(), points=2)
    return {
        "linear_rank_minus_kalman": check(lin.rank - ex.kalman_rank(A, C), 0,
                                          lin.rank == ex.kalman_rank(A, C)),
        "accelerometer_tilt_residual_yaw_hidden": check(acc.quantities["tilt"].residual, 1e-6,
                                                        acc.rank == 2
                                          and acc.quantities["tilt"].observable
                                          and not acc.quantities["heading"].observable),
        "unicycle_rank_deficit": check(uni.n_coords - uni.rank, 0, uni.observable),
        "pendulum_angle_from_rate": check(pen.quantities["angle"].residual, 1e-6,
                                          pen.quantities["angle"].observable),
        "product_ab_residual_a_b_hidden": check(prod.quantities["ab"].residual, 1e-6,
                                   not prod.quantities["theta:a"].observable
                                   and prod.quantities["ab"].observable),
    }


def _published_rows():
    from verticality.analysis.otolith_observability import PUBLISHED

    return [{"model": m, "motion": mo, "control": c, "orientation_observable": o,
             "acceleration_identifiable": a} for (m, mo, c), (o, a) in PUBLISHED.items()]


def _agreement(rows) -> int:
    return int(sum(r["agrees"] for r in rows))


def figures(result: Result, out_dir: Path) -> list[Path]:
    from verticality.core import plots

    rows = result.metrics["rows"]
    fig, axes = plots.new_figure(1, 2, width=13.0, height_per_row=6.0, sharex=False)
    ax = axes[0, 0]
    cols = ["published tilt", "ours tilt", "published acc.", "ours acc."]
    keys = [("published_orientation_observable", "orientation_observable"),
            ("published_acceleration_identifiable", "acceleration_identifiable")]
    grid = np.full((len(rows), 4), np.nan)
    for i, r in enumerate(rows):
        for j, (kp, ko) in enumerate(keys):
            for k, key in enumerate((kp, ko)):
                v = r[key]
                grid[i, 2 * j + k] = np.nan if v is None else float(v)
    ax.imshow(np.ma.masked_invalid(grid), cmap="RdYlGn", vmin=-0.3, vmax=1.3, aspect="auto")
    for i, r in enumerate(rows):
        for j in range(4):
            v = grid[i, j]
            ax.text(j, i, "–" if np.isnan(v) else ("yes" if v else "no"), ha="center",
                    va="center", fontsize=8)
        if not r["agrees"]:
            ax.text(3.6, i, "≠", ha="left", va="center", color="red", fontsize=11)
    ax.set_xticks(range(4), cols, fontsize=8)
    ax.set_yticks(range(len(rows)),
                  [f"{r['model']} {r['motion']} {r['control']}" for r in rows], fontsize=8)
    ax.set_title(f"F Tables 3.1/3.2 vs ours: {result.metrics['agreement']}/{len(rows)} agree")
    ax = axes[0, 1]
    for r in rows:
        rk = np.asarray(r["rank_by_order"]) / r["n_coords"]
        ax.plot(range(len(rk)), rk, marker="o", ms=3, alpha=0.7,
                label=f"{r['model'][:3]} {r['motion']} {r['control']}")
    plots.published_line(ax, 1.0, label="full rank")
    ax.set_xlabel("output derivative order k")
    ax.set_ylabel("rank of O_k / number of coordinates")
    ax.set_title("rank growth (plateau below 1 = unobservable directions)")
    ax.legend(fontsize=6, ncol=2)
    return [plots.save(fig, out_dir / "observability_table.png")]


@register("observability", "nonlinear observability of the head's tilt from the otoliths",
          source="F §3.1, Tables 3.1–3.2", figures=figures)
def run(quick: bool = False) -> Result:
    from verticality.analysis import otolith_observability as oo

    def rows_of(cases):
        out = []
        for c in cases:
            d = oo.row_dict(c)
            d["rank_by_order"] = c.result.rank_by_order
            out.append(d)
        return out

    rows = rows_of(oo.run_table())
    metrics = {"rows": rows, "agreement": _agreement(rows), "cases": len(rows),
               "disagreements": [f"{r['model']} {r['motion']} {r['control']}: {r['why']}"
                                 for r in rows if not r["agrees"]],
               "note": oo.FREE_ENTRY_NOTE,
               "validation": _validation()}
    if not quick:
        free = rows_of(oo.run_table(chart="ambient", orders=oo.AMBIENT_ORDERS, points=3))
        axis = rows_of(oo.run_table(output="axis"))
        metrics["rows_free_entries"] = free
        metrics["agreement_free_entries"] = _agreement(free)
        metrics["rows_axis_output"] = axis
        metrics["agreement_axis_output"] = _agreement(axis)
        p13 = rows_of(oo.run_table(params="p13"))
        metrics["rows_p13_params"] = p13
        metrics["agreement_p13_params"] = _agreement(p13)
    paper = {"rows": _published_rows(), "agreement": 16, "cases": 16}
    return Result(metrics=metrics, paper=paper, simulated_s=0.0)
