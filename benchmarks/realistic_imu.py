"""Our tilt filter beside VQF on synthetic handheld recordings with realistic sensor errors
(:mod:`verticality.tilt.evaluation.realistic`: six motion classes, consumer-MEMS offsets,
scale and cross-axis errors, noise, clipping, 100–400 Hz; no parameter of either filter was
chosen on them). Inclination RMSE (deg) per class (mean over the seeds), causal and offline, and
the ratio to VQF's of the same mode, in the same run.

    python benchmarks/realistic_imu.py [--seeds 5]

Needs the peers extra (vqf).
"""

import argparse
import sys

import numpy as np

from verticality.tilt.evaluation import realistic as rr

FILTERS = ("verticality", "vqf", "verticality-offline", "vqf-offline")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args(argv)
    res = rr.compare(seeds=range(args.seeds), filters=FILTERS,
                     progress=lambda i, n: print(f"\r{i}/{n} recordings", end="", file=sys.stderr))
    print(file=sys.stderr)
    print(f"{'motion':24s} {'ours':>6s} {'VQF':>6s} {'ratio':>6s} {'ours off':>8s} "
          f"{'VQF off':>8s} {'ratio':>6s}")
    rows = []
    for kind in rr.MOTIONS:
        m = np.array([[res[(kind, s)][f] for f in FILTERS] for s in range(args.seeds)])
        rows.append(m)
        c = m.mean(axis=0)
        print(f"{kind:24s} {c[0]:6.3f} {c[1]:6.3f} {c[0] / c[1]:6.3f} {c[2]:8.3f} {c[3]:8.3f} "
              f"{c[2] / c[3]:6.3f}")
    m = np.concatenate(rows)
    c = m.mean(axis=0)
    print(f"{'all ' + str(len(m)) + ' recordings':24s} {c[0]:6.3f} {c[1]:6.3f} {c[0] / c[1]:6.3f} "
          f"{c[2]:8.3f} {c[3]:8.3f} {c[2] / c[3]:6.3f}")
    for name, a, b in (("causal", 0, 1), ("offline", 2, 3)):
        r = m[:, a] / m[:, b]
        print(f"{name}: ours better on {np.sum(r < 1)} of {len(r)} recordings; "
              f"worst ratio {r.max():.2f}, best {r.min():.2f}")


if __name__ == "__main__":
    main()
