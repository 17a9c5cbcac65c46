"""The correlation time of the gap bridge (``TiltParams.gap_rate_corr_s``, docs/tilt.md "Gaps.")
on the two sets with gaps, and the choice of each set judged on the other.

The sets: the validation's drop-out class (synthetic hand-held motion, eight runs of missing rows
of 0.05–1 s; our filter and smoother against VQF and offlineVQF, as
``benchmarks/tilt_validation.py --classes dropout``) and the BROAD trials with eight gaps cut into
each (``benchmarks/gaps_broad.py``, at each ``--gaps`` length). Every ``--taus`` value is run on
both (0: the rate after the gap over the whole gap, the rule before the bridge; ``inf`` the
trapezoid). The τ best on one set (drop-out: the geometric mean over the rates of the causal
ratio to VQF; BROAD: the mean over the gap lengths of the trials' mean RMSE 0–3 s after each gap,
where the bridge acts) is then reported on the other, beside the rule before the bridge.

Run: ``python benchmarks/gap_bridge.py BROAD_DIR [--taus 0,0.1,0.25,0.5,1,inf] [--seeds 2]
[--gaps 0.2,0.5,1] [--json FILE]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from verticality import tilt
from verticality.io import broad
from verticality.tilt.evaluation import validation as tv
from verticality.tilt.evaluation.broad import OURS, OURS_OFFLINE, VQF_OFFLINE

sys.path.insert(0, str(Path(__file__).resolve().parent))
import gaps_broad  # noqa: E402 (a benchmark beside this one)


def _params(tau: float):
    return tilt.DEFAULT_PARAMS._replace(gap_rate_corr_s=tau)


def dropout(taus, seeds: int, rates) -> dict:
    """Per τ and rate: the mean RMSEs of our filter and smoother and of the peers over the seeds,
    the ratios and the smallest shares within 2σ."""
    cases = list(tv.failure_cases(["dropout"], range(seeds), rates))
    peers, ours = {}, {tau: {} for tau in taus}
    for i, case in enumerate(cases):
        print(f"drop-out {i + 1}/{len(cases)}", file=sys.stderr, flush=True)
        key = (case.name, case.rate_hz)
        peers[key] = tv.score_case(case, ("vqf", VQF_OFFLINE))["rmse"]
        for tau in taus:
            ours[tau][key] = tv.score_case(case, (OURS, OURS_OFFLINE),
                                           tv.variant_runner({"params": _params(tau)}))
    out = {}
    for tau in taus:
        for rate in rates:
            keys = [k for k in peers if k[1] == rate]
            m = {f: float(np.mean([ours[tau][k]["rmse"][f] for k in keys]))
                 for f in (OURS, OURS_OFFLINE)}
            p = {f: float(np.mean([peers[k][f] for k in keys])) for f in ("vqf", VQF_OFFLINE)}
            out[(tau, rate)] = {
                "ours": m[OURS], "vqf": p["vqf"], "ratio": m[OURS] / p["vqf"],
                "offline": m[OURS_OFFLINE], "ovqf": p[VQF_OFFLINE],
                "offline_ratio": m[OURS_OFFLINE] / p[VQF_OFFLINE],
                "within_2sigma": min(ours[tau][k]["within_2sigma"][OURS] for k in keys),
                "within_2sigma_offline": min(ours[tau][k]["within_2sigma"][OURS_OFFLINE]
                                             for k in keys),
                "per_case": {k[0]: ours[tau][k]["rmse"][OURS] for k in keys}}
    return out


def broad_gaps(taus, gaps, broad_dir) -> dict:
    """Per τ and gap length: each trial's RMSEs 0–3 s and 1.5–5 s after each gap and over the
    trial (:func:`gaps_broad.trial_errors`) and their means."""
    trials = [broad.load_trial(p) for p in broad.list_trials(broad_dir)]
    out = {}
    for gap in gaps:
        for tau in taus:
            print(f"BROAD gap {gap:g} s, tau {tau:g} s", file=sys.stderr, flush=True)
            rows = {tr.name: gaps_broad.trial_errors(tr, gap, _params(tau), no_gap=False)[1:]
                    for tr in trials}
            out[(tau, gap)] = {"trials": rows,
                               "mean": [float(v) for v in np.mean(list(rows.values()), axis=0)]}
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("broad_dir", type=Path, metavar="BROAD_DIR")
    ap.add_argument("--taus", default="0,0.1,0.25,0.5,1,inf")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--rates", default="1000,286,100,50")
    ap.add_argument("--gaps", default="0.2,0.5,1")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--dropout-only", action="store_true",
                    help="the drop-out class alone (no BROAD, no choice)")
    args = ap.parse_args(argv)
    taus = [float(v) for v in args.taus.split(",")]
    rates = [float(v) for v in args.rates.split(",")]
    gaps = [float(v) for v in args.gaps.split(",")]
    d = dropout(taus, args.seeds, rates)
    b = {} if args.dropout_only else broad_gaps(taus, gaps, args.broad_dir)

    print("drop-out class (seeds 0.." f"{args.seeds - 1}): ours / VQF, offline / offlineVQF, 2σ")
    print(f"{'tau s':>6s} {'Hz':>5s} {'ours':>7s} {'VQF':>7s} {'ratio':>6s} {'off':>7s} "
          f"{'oVQF':>7s} {'ratio':>6s} {'2σ':>6s} {'2σ off':>6s}")
    for (tau, rate), r in d.items():
        print(f"{tau:6g} {rate:5g} {r['ours']:7.3f} {r['vqf']:7.3f} {r['ratio']:6.3f} "
              f"{r['offline']:7.3f} {r['ovqf']:7.3f} {r['offline_ratio']:6.3f} "
              f"{100 * r['within_2sigma']:5.1f}% {100 * r['within_2sigma_offline']:5.1f}%")
    if args.dropout_only:
        for tau in taus:
            print(f"{tau:6g}", " ".join(f"{k}={v:.2f}" for k, v in d[(tau, rates[0])]
                                         ["per_case"].items()))
        return
    print("\nBROAD, eight gaps per trial: mean RMSE (deg) 0-3 s / 1.5-5 s after each gap / trial")
    for (tau, gap), r in b.items():
        m = r["mean"]
        print(f"tau {tau:6g} gap {gap:4g} s: {m[0]:7.2f} {m[1]:7.2f} {m[2]:7.2f}")
    print("\nper trial, 0-3 s after each gap (deg), tau:", " ".join(f"{t:g}" for t in taus))
    for gap in gaps:
        for name in b[(taus[0], gap)]["trials"]:
            vals = " ".join(f"{b[(tau, gap)]['trials'][name][0]:7.2f}" for tau in taus)
            print(f"gap {gap:g} {name[:34]:34s} {vals}")

    def d_score(tau):  # geometric mean over the rates of the causal ratio to VQF
        return float(np.exp(np.mean([np.log(d[(tau, r)]["ratio"]) for r in rates])))

    def b_score(tau):  # mean over the gap lengths of the mean 0–3 s RMSE
        return float(np.mean([b[(tau, g)]["mean"][0] for g in gaps]))

    print("\nscores: tau, drop-out (geo-mean causal ratio), BROAD (mean 0-3 s RMSE, deg)")
    for tau in taus:
        print(f"{tau:6g} {d_score(tau):7.3f} {b_score(tau):7.2f}")
    cands = [t for t in taus if t > 0]
    on_broad = min(cands, key=b_score)
    on_dropout = min(cands, key=d_score)
    print(f"\nchosen on BROAD: tau = {on_broad:g} s -> drop-out {d_score(on_broad):.3f} "
          f"(rule before the bridge {d_score(0.0):.3f})" if 0.0 in taus else "")
    print(f"chosen on drop-out: tau = {on_dropout:g} s -> BROAD {b_score(on_dropout):.2f} deg "
          f"(rule before the bridge {b_score(0.0):.2f})" if 0.0 in taus else "")
    if args.json:
        args.json.write_text(json.dumps({
            "dropout": {f"{t:g}@{r:g}": v for (t, r), v in d.items()},
            "broad": {f"{t:g}@{g:g}": v for (t, g), v in b.items()},
            "chosen_on_broad": on_broad, "chosen_on_dropout": on_dropout}, indent=1,
            default=str))


if __name__ == "__main__":
    main()
