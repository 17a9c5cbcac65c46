"""Accuracy of the tilt filter on robotics logs (docs/logs.md): ours, VQF and the log's own
estimate (PX4's EKF2 ``vehicle_attitude``, or the Imu messages' orientation) against the ground
truth where the log has one (a PX4 simulation's ``vehicle_attitude_groundtruth``), and how closely
they agree with each other on the others.

For each log: the angle between the up vectors (deg; RMS, median, 95th percentile) over the
samples after our filter settled (after its initialization, outside re-acquisitions), apart while
the IMU moves and while it is still; at rest also the angle between each estimate and the
accelerometer's direction. Filters: ours (causal and offline), VQF (``vqf``, 6D, defaults, causal
and offline), all on the same samples (:func:`verticality.tilt.estimate_log`).

Run: ``python benchmarks/logs_accuracy.py LOG [LOG ...] [--plot OUT.png]`` (the logs extra and
the peers extra); ``--plot`` draws ours beside the log's estimate for the first log.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from verticality import tilt
from verticality.io.logs import LOG, TRUTH, frames
from verticality.tilt.logs import angle_stats, judged_samples, rest_samples, up_at

FILTERS = (("verticality", {}), ("verticality offline", {"offline": True}),
           ("vqf", {"filter_name": "vqf"}), ("vqf offline", {"filter_name": "vqf-offline"}))


def _row(name, angle, judged, rest, dt):
    cells = [angle_stats(angle, judged & m, dt) for m in (np.ones_like(rest), ~rest, rest)]
    text = [f"{c['rms_deg']:.3f}" if c["n"] else "–" for c in cells]
    p95 = f"{cells[0]['p95_deg']:.3f}" if cells[0]["n"] else "–"
    return f"| {name} | {text[0]} | {p95} | {text[1]} | {text[2]} |"


def report(path: Path) -> tuple:
    rec = tilt.read_log(path)
    print(f"\n## {path.name}: {rec.format}, {rec.topic}, {rec.t_s.size} samples, "
          f"{rec.t_s[-1]:.1f} s, {1 / np.median(rec.dt_s):.0f} Hz")
    for note in rec.notes:
        print(f"note: {note}")
    ups, seconds = {}, {}
    for name, kw in FILTERS:
        start = time.perf_counter()
        est = tilt.estimate_log(rec, **kw)
        seconds[name] = time.perf_counter() - start
        ups[name] = np.asarray(est.up_S)
        if name == "verticality":
            ours = est
    judged = judged_samples(ours.flags, rec.t_s)
    rest = rest_samples(rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s)
    refs = {r.role: (r.name, up_at(r.t_s, r.quat_E_S, rec.t_s)) for r in rec.references}
    dt = rec.dt_s
    print(f"judged: {np.count_nonzero(judged)} samples, still {np.sum(dt[judged & rest]):.1f} s,"
          f" moving {np.sum(dt[judged & ~rest]):.1f} s; run time (s): "
          + ", ".join(f"{k} {v:.2f}" for k, v in seconds.items()))
    head = "| {} | RMS | 95 % | RMS moving | RMS still |\n|---|---|---|---|---|"
    if TRUTH in refs:
        truth_name, truth = refs[TRUTH]
        print(f"\nagainst the ground truth ({truth_name}), angle between the up vectors (deg):\n")
        print(head.format("estimate"))
        for name in ups:
            print(_row(name, frames.angle_between(ups[name], truth), judged, rest, dt))
        if LOG in refs:
            print(_row(f"{refs[LOG][0]} (the log's)", frames.angle_between(refs[LOG][1], truth),
                       judged, rest, dt))
    print("\nagreement, angle between the up vectors (deg):\n")
    print(head.format("pair"))
    pairs = [("verticality", "vqf"), ("verticality offline", "vqf offline")]
    for a, b in pairs:
        print(_row(f"{a} vs {b}", frames.angle_between(ups[a], ups[b]), judged, rest, dt))
    if LOG in refs:
        for name in ("verticality", "vqf"):
            print(_row(f"{name} vs {refs[LOG][0]}", frames.angle_between(ups[name], refs[LOG][1]),
                       judged, rest, dt))
    with np.errstate(invalid="ignore", divide="ignore"):
        acc_dir = rec.acc_m_s2 / np.linalg.norm(rec.acc_m_s2, axis=1, keepdims=True)
    still = {name: angle_stats(frames.angle_between(u, acc_dir), judged & rest, dt)
             for name, u in list(ups.items()) + [(n, u) for n, u in refs.values()]}
    if next(iter(still.values()))["n"]:
        print("\nat rest, angle to the accelerometer's direction (deg), RMS: "
              + ", ".join(f"{k} {v['rms_deg']:.3f}" for k, v in still.items()))
    return rec, ours


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logs", type=Path, nargs="+", metavar="LOG",
                    help="PX4 ULog, ROS 1 bag, ROS 2 bag folder or MCAP file")
    ap.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                    help="ours beside the log's estimate for the first log")
    args = ap.parse_args()
    first = None
    for path in args.logs:
        done = report(path)
        first = first or done
    if args.plot is not None:
        from verticality.tilt.plots import plot_log_comparison

        rec, est = first
        print(f"\nwrote {plot_log_comparison(args.plot, tilt.compare_log(rec, est), est, 'ours')}")


if __name__ == "__main__":
    main()
