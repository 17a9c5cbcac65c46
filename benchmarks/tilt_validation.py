"""The tilt filter's validation set in one table (docs/tilt.md, "Validation across datasets and
rates"): per dataset and sampling rate, our filter beside VQF and our smoother beside offlineVQF
(mean inclination RMSE of the cases, their ratio), with the smallest share of scored samples
within 2σ; then the fault recordings' σ and the clipped rotation. Every filter runs with its
defaults, one parameter set for every case, in this run.

    python benchmarks/tilt_validation.py [--broad BROAD_DIR] [--seeds 2] [--json FILE]
        [--per-case]

BROAD_DIR: the folder of BROAD's HDF5 files (CC BY 4.0; docs/references.md); without it the
BROAD rows are left out. Needs the peers extra (vqf).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from verticality.tilt.evaluation import realistic as rr
from verticality.tilt.evaluation import validation as tv
from verticality.tilt.evaluation.faults import FAULTS, fast_roll, sigma_honesty_over_seeds


def clipped_rotation_deg() -> tuple[float, float]:
    """The mean tilt error (deg) while a 12 rad/s roll pulse clips a ±7 rad/s gyro and in the 2 s
    after: clipping detected (the default) and not detected."""
    from verticality import tilt

    gyr, acc, up = fast_roll(n=2000, peak=12.0, centers_s=(5.0,), seed=1)
    clipped = np.clip(gyr, -7.0, 7.0)
    at = np.flatnonzero(np.any(np.abs(clipped) >= 7.0, axis=1))
    window = slice(at[0], at[-1] + 201)
    errs = []
    for detect in (True, False):
        out = tilt.estimate(clipped, acc, period_s=0.01, detect_clipping=detect)
        cos = np.clip(np.sum(np.asarray(out.up_S) * up, axis=1), -1.0, 1.0)
        errs.append(float(np.degrees(np.mean(np.arccos(cos)[window]))))
    return errs[0], errs[1]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--broad", help="folder of BROAD .hdf5 files")
    ap.add_argument("--seeds", type=int, default=2, help="synthetic recordings per class and rate")
    ap.add_argument("--json", help="write every case's scores and the summary to this file")
    ap.add_argument("--per-case", action="store_true", help="print every case's RMSEs too")
    ap.add_argument("--no-faults", action="store_true", help="leave out the fault recordings")
    args = ap.parse_args(argv)

    cases = list(tv.synthetic_cases(rr.ALL_MOTIONS, range(args.seeds)))
    if args.broad:
        from verticality.io import broad

        cases = list(tv.broad_cases(broad.list_trials(args.broad))) + cases
    scored = {}
    for i, case in enumerate(cases):
        print(f"\r{i + 1}/{len(cases)} {case.dataset} {case.name} {case.rate_hz:.0f} Hz   ",
              end="", file=sys.stderr)
        scored[(case.dataset, case.name, case.rate_hz)] = tv.score_case(case)
    print(file=sys.stderr)
    rows = tv.summarize(scored)
    print(f"{'dataset':18s} {'Hz':>6s} {'cases':>5s} {'ours':>6s} {'VQF':>6s} {'ratio':>6s} "
          f"{'ours off':>8s} {'oVQF':>6s} {'ratio':>6s} {'2σ min':>7s} {'2σ off':>7s}")
    for (dataset, rate), r in rows.items():
        m = r["mean_rmse_deg"]
        print(f"{dataset:18s} {rate:6.0f} {r['cases']:5d} {m['verticality']:6.3f} {m['vqf']:6.3f} "
              f"{r['causal_ratio']:6.3f} {m['verticality-offline']:8.3f} {m['vqf-offline']:6.3f} "
              f"{r['offline_ratio']:6.3f} {100 * r['min_within_2sigma/verticality']:6.1f}% "
              f"{100 * r['min_within_2sigma/verticality-offline']:6.1f}%")
    if args.per_case:
        for (dataset, name, rate), r in scored.items():
            e = r["rmse"]
            print(f"  {dataset:10s} {name:34s} {rate:6.0f} " + " ".join(
                f"{f}={e[f]:.3f}" for f in tv.FILTERS))
    faults = {}
    if not args.no_faults:
        print(f"\n{'fault':12s} {'unflagged':>9s} {'within 2σ':>9s} {'worst 2σ':>9s}")
        for fault in FAULTS:
            h = sigma_honesty_over_seeds(fault, range(5))
            faults[fault] = h
            print(f"{fault:12s} {100 * h['unflagged']:8.1f}% {100 * h['within_2sigma']:8.1f}% "
                  f"{100 * h['worst_within_2sigma']:8.1f}%")
        detected, undetected = clipped_rotation_deg()
        faults["clipped_rotation_deg"] = {"detected": detected, "undetected": undetected}
        print(f"clipped rotation: {detected:.1f}° while clipped and 2 s after "
              f"({undetected:.1f}° without clipping detection)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"cases": [{"dataset": k[0], "name": k[1], "rate_hz": k[2], **v}
                                 for k, v in scored.items()],
                       "summary": [{"dataset": k[0], "rate_hz": k[1], **v}
                                   for k, v in rows.items()],
                       "faults": faults}, fh, indent=1)


if __name__ == "__main__":
    main()
