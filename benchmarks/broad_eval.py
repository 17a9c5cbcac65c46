"""Our tilt filter on whole BROAD trials, read from the folder where you keep the dataset.

Per trial: the official inclination RMSE of our filter and of VQF (when installed) in the same
run, their ratio, the share of scored samples within our σ and 2σ, and what the sensor-limit
inference makes of the trial (clipped axes, which BROAD's IMU never reaches, and rows held bit for
bit). The tests check the same on the short slices shipped in tests/data/broad/.

Run: ``python benchmarks/broad_eval.py BROAD_DIR``. Exit status 1 when a check fails: an axis
inferred clipped, or a σ that covers fewer than 99 % of the errors at 2σ.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from verticality.io import broad
from verticality.tilt import limits as tilt_limits
from verticality.tilt.evaluation.broad import evaluate_trials, peer_status


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("broad_dir", type=Path, metavar="BROAD_DIR",
                    help="folder of the BROAD trials (.hdf5)")
    args = ap.parse_args(argv)
    paths = broad.list_trials(args.broad_dir)
    filters = ["verticality"] + (["vqf"] if peer_status().get("vqf") is None else [])
    res = evaluate_trials(paths, filters)
    print(f"{'trial':46s} {'ours':>7s} {'vqf':>7s} {'ratio':>6s} {'σ / 2σ (%)':>12s} "
          f"{'clipped':>8s} {'held':>5s}")
    failed = []
    for path in paths:
        trial = broad.load_trial(path)
        lim = tilt_limits.find_limits(trial.gyr_rad_s, trial.acc_m_s2, trial.dt_s)
        clipped = int(lim.gyr_clipped.any()) + int(lim.acc_clipped.any())
        rmse = res["trials"][trial.name]
        cal = res["sigma"][trial.name]
        vqf = rmse.get("vqf", np.nan)
        print(f"{trial.name:46s} {rmse['verticality']:7.3f} {vqf:7.3f} "
              f"{rmse['verticality'] / vqf:6.2f} "
              f"{100 * cal['within_1sigma']:5.1f} / {100 * cal['within_2sigma']:5.1f} "
              f"{clipped:8d} {int(lim.held.sum()):5d}", flush=True)
        if clipped:
            failed.append(f"{trial.name}: an axis inferred clipped")
        if cal["within_2sigma"] < 0.99:
            failed.append(f"{trial.name}: {100 * cal['within_2sigma']:.2f} % within 2σ")
    mean = res["mean"]
    print(f"{'mean':46s} {mean['verticality']:7.3f} {mean.get('vqf', np.nan):7.3f} "
          f"{mean['verticality'] / mean.get('vqf', np.nan):6.2f}")
    for line in failed:
        print(f"FAILED {line}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
