"""The tilt filter's validation set in one table (docs/tilt.md, "Validation across datasets and
rates"): per dataset and sampling rate, our filter beside VQF and our smoother beside offlineVQF
(mean inclination RMSE of the cases, their ratio), with the smallest share of scored samples
within 2σ; then the fault recordings' σ and the clipped rotation. Every filter runs with its
defaults, one parameter set for every case, in this run.

    python benchmarks/tilt_validation.py [--broad BROAD_DIR] [--classes broad,sat-gyro,...]
        [--rates 50,100] [--shares 0.01,0.2] [--seeds 2] [--json FILE] [--per-case]
        [--no-faults] [--detection] [--loco] [--loco-limits [--offline]]

BROAD_DIR: the folder of BROAD's HDF5 files (CC BY 4.0; docs/references.md); without it the BROAD
rows are left out. The failure classes (:mod:`verticality.tilt.evaluation.failures`: saturated-
then-calibrated gyro and accelerometer at each clipped share, shocks, a crash, drop-outs, clock
jumps, jittered rates) are datasets of their own; ``--detection`` prints the clip detector's hit
and false-alarm rates on the saturation classes instead, ``--loco`` the leave-one-class-out of clip
detection on and off, ``--loco-limits`` of what a clipped sample means (:data:`LIMITS_VARIANTS`;
``--offline`` the smoother against offlineVQF). Needs the peers extra (vqf).
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


def detection_rates(cases) -> dict:
    """The clip detector on the saturation classes: ``{(dataset, rate): {"hit": share of the truly
    clipped samples flagged CLIPPED, "false": share of the unclipped samples flagged}}``, pooled
    over the cases (no filter runs)."""
    from verticality.tilt.limits import find_limits

    pooled: dict = {}
    for case in cases:
        if case.clipped is None:
            continue
        lim = find_limits(case.gyr_rad_s, case.acc_m_s2, tv.case_steps(case))
        flagged = np.any(lim.gyr_clipped, axis=1) | lim.acc_clipped
        p = pooled.setdefault((case.dataset, case.rate_hz), np.zeros(4))
        p += [np.count_nonzero(flagged & case.clipped), np.count_nonzero(case.clipped),
              np.count_nonzero(flagged & ~case.clipped), np.count_nonzero(~case.clipped)]
    return {k: {"hit": p[0] / max(p[1], 1), "false": p[2] / max(p[3], 1), "clipped": int(p[1])}
            for k, p in pooled.items()}


LIMITS_VARIANTS = {"fitted": {}, "fraction": {"fit_peaks": False}, "off": {"infer": False}}


def limits_runner(options: dict):
    """:func:`~verticality.tilt.evaluation.validation.leave_one_class_out`'s runner for variants
    of what a clipped sample means (:data:`LIMITS_VARIANTS`: keyword arguments of
    :func:`verticality.tilt.limits.find_limits`; "fitted" the default, each clipped run's peak
    fitted and added; "fraction" the earlier model, σ = 0.5 × the clip level and nothing added;
    "off" no clipping inferred): our filter and smoother run on the limits so found as
    ``estimate_steps`` and ``smooth_steps`` run them (a recording of one piece); the peers as
    always."""
    from verticality.tilt import batch, estimator, smoother
    from verticality.tilt.evaluation.broad import OURS, OURS_OFFLINE, run_filter_sigma
    from verticality.tilt.limits import find_limits
    from verticality.tilt.output import tilt_sigma_rad
    from verticality.tilt.params import DEFAULT_PARAMS, block_samples

    def run(name, gyr, acc, dt):
        if name not in (OURS, OURS_OFFLINE):
            return run_filter_sigma(name, gyr, acc, dt)
        lim = find_limits(gyr, acc, dt, **options)
        g, a = lim.readings(gyr, acc)
        block = block_samples(DEFAULT_PARAMS, dt)
        init = estimator.TiltFilter(DEFAULT_PARAMS, block).init()
        if name == OURS:
            out = batch.run(DEFAULT_PARAMS, block, init, g, a, dt, **lim.run_args())[1]
        else:
            final, out, trans = batch.run(DEFAULT_PARAMS, block, init, g, a, dt,
                                          transitions=True, **lim.run_args())
            dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), g.shape[:1])
            out = smoother.smoothed_output(out, trans, final.P, dts, block)
        return out.quat_E_S, out.bias_S_rad_s, tilt_sigma_rad(out.var, DEFAULT_PARAMS)

    return run


def _floats(text):
    return None if text is None else [float(x) for x in text.split(",")]


def select_cases(classes, rates, seeds, shares, broad_dir=None):
    """The validation cases of ``classes`` (``broad``, ``synthetic`` (the realistic motion
    classes), ``vigorous``, the failure classes) at ``rates`` (None: each dataset's own)."""
    from verticality.tilt.evaluation import failures as fl

    cases = []
    if "broad" in classes and broad_dir:
        from verticality.io import broad

        b_rates = tv.BROAD_RATES_HZ if rates is None else [None if r in (285.7, 286.0) else r
                                                            for r in rates]
        cases += list(tv.broad_cases(broad.list_trials(broad_dir), b_rates))
    kinds = ((rr.MOTIONS if "synthetic" in classes else ())
             + ((rr.VIGOROUS,) if "vigorous" in classes else ()))
    s_rates = tv.SYNTHETIC_RATES_HZ if rates is None else rates
    cases += list(tv.synthetic_cases(kinds, range(seeds), s_rates))
    failure = [c for c in fl.CLASSES if c in classes]
    cases += list(tv.failure_cases(failure, range(seeds), s_rates, shares))
    return cases


ALL_CLASSES = ("broad", "synthetic", "vigorous", "sat-gyro", "sat-acc", "shock", "crash",
               "dropout", "clock-jump", "jitter")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--broad", help="folder of BROAD .hdf5 files")
    ap.add_argument("--classes", default=",".join(ALL_CLASSES),
                    help=f"comma-separated, of {','.join(ALL_CLASSES)} (default all)")
    ap.add_argument("--rates", help="comma-separated sampling rates, Hz (default each dataset's: "
                    "BROAD native, 1000, 100, 50; synthetic 50, 100, 286, 1000)")
    ap.add_argument("--shares", help="clipped shares of the saturation classes, e.g. 0.01,0.2")
    ap.add_argument("--seeds", type=int, default=2, help="synthetic recordings per class and rate")
    ap.add_argument("--json", help="write every case's scores and the summary to this file")
    ap.add_argument("--per-case", action="store_true", help="print every case's RMSEs too")
    ap.add_argument("--no-faults", action="store_true", help="leave out the fault recordings")
    ap.add_argument("--detection", action="store_true",
                    help="only the clip detector's hit and false-alarm rates (no filters)")
    ap.add_argument("--loco", action="store_true",
                    help="leave-one-class-out of clip detection on/off instead of the table")
    ap.add_argument("--loco-limits", action="store_true",
                    help="leave-one-class-out of the clipped-sample models (LIMITS_VARIANTS)")
    ap.add_argument("--offline", action="store_true",
                    help="with --loco-limits: our smoother against offlineVQF")
    args = ap.parse_args(argv)

    classes = set(args.classes.split(","))
    unknown = classes - set(ALL_CLASSES)
    if unknown:
        ap.error(f"unknown classes {', '.join(sorted(unknown))}")
    cases = select_cases(classes, _floats(args.rates), args.seeds, _floats(args.shares),
                         args.broad)
    if args.detection:
        print(f"{'class':16s} {'Hz':>6s} {'clipped':>8s} {'hit':>7s} {'false':>8s}")
        for (dataset, rate), d in detection_rates(cases).items():
            print(f"{dataset:16s} {rate:6.0f} {d['clipped']:8d} {100 * d['hit']:6.1f}% "
                  f"{100 * d['false']:7.3f}%")
        return
    if args.loco:
        import time

        t0 = time.perf_counter()
        res = tv.leave_one_class_out(cases, {"detect": {}, "off": {"detect_clipping": False}})
        print(f"leave-one-class-out over {len(cases)} cases, 2 variants: "
              f"{time.perf_counter() - t0:.0f} s")
        for c, r in res["chosen"].items():
            print(f"{c:16s} chosen {r['variant']:7s} (best here {r['best_here']:7s}) "
                  + " ".join(f"{rate:.0f} Hz {x:.3f}" for rate, x in r["ratios"].items()))
        return
    if args.loco_limits:
        res = tv.leave_one_class_out(cases, LIMITS_VARIANTS, offline=args.offline,
                                     runner=limits_runner,
                                     progress=lambda m: print(f"\r{m:60s}", end="",
                                                              file=sys.stderr))
        print(file=sys.stderr)
        print(f"{'class':16s} {'Hz':>6s} " + " ".join(f"{v:>9s} {'2σ':>6s}"
                                                      for v in LIMITS_VARIANTS))
        for key in sorted(res["ratios"]["off"], key=lambda k: (k[0], -k[1])):
            print(f"{key[0]:16s} {key[1]:6.0f} " + " ".join(
                f"{res['ratios'][v][key]:9.3f} {100 * res['within_2sigma'][v][key]:5.1f}%"
                for v in LIMITS_VARIANTS))
        for c, r in res["chosen"].items():
            print(f"{c:16s} chosen {r['variant']:8s} (best here {r['best_here']:8s})")
        return
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
        for w, wm in r.get("windows", {}).items():
            print(f"  {w:16s} {'':>12s} {wm['verticality']:6.3f} {wm['vqf']:6.3f} "
                  f"{wm['verticality'] / wm['vqf']:6.3f} {wm['verticality-offline']:8.3f} "
                  f"{wm['vqf-offline']:6.3f} "
                  f"{wm['verticality-offline'] / wm['vqf-offline']:6.3f}")
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
