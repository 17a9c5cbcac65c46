"""Accuracy of the tilt filter after gaps in the time stamps, on the BROAD trials.

Eight stretches of ``--gap`` seconds are cut out of each trial's movement phase (evenly spaced,
from 5 s after its start to 5 s before its end); the remaining samples keep their time stamps, so
the filter sees gaps (flag DT_GAP) with the sensor's motion hidden inside them. Reported per
trial, against the optical reference (BROAD's inclination error, movement samples): the RMS error
without gaps on the same samples, then with gaps: over 0–3 s after each gap (includes the
``reacquire_s`` wait), over 1.5–5 s after each gap (after re-acquisition), and over the trial.

Run: ``python benchmarks/gaps_broad.py BROAD_DIR [--gap 0.5] [--reacquire-s 1.0]
[--gap-rate-corr-s 0.25]`` (the bridge's correlation time, ``TiltParams.gap_rate_corr_s``: 0 the
rate after the gap over the whole gap, ``inf`` the trapezoid).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from verticality import tilt
from verticality.io import broad


def _rms(e, sel):
    return float(np.sqrt(np.mean(e[sel] ** 2)))


def trial_errors(tr, gap_s: float, params, no_gap: bool = True) -> tuple:
    """RMS errors (deg) of one BROAD trial ``tr`` with eight gaps of ``gap_s`` cut into it:
    ``(no gap, 0–3 s after each gap, 1.5–5 s after, whole trial)`` (``no gap`` the run on the
    whole trial over the 0–3 s windows; NaN unless ``no_gap``)."""
    n, fs = tr.gyr_rad_s.shape[0], tr.sampling_rate_hz
    mv = np.flatnonzero(tr.movement)
    starts = np.linspace(mv[0] + 5 * fs, mv[-1] - 5 * fs, 8).astype(int)
    keep = np.ones(n, dtype=bool)
    for s in starts:
        keep[s:s + int(gap_s * fs)] = False
    t = tr.t_s[keep]
    out = tilt.estimate(tr.gyr_rad_s[keep], tr.acc_m_s2[keep], t, params=params)
    err = broad.inclination_error_deg(out.quat_E_S, tr.quat_E_S_opt[keep])
    ok = np.isfinite(err) & tr.movement[keep]
    t_end = tr.t_s[starts + int(gap_s * fs)]
    since = t[:, None] - t_end[None, :]
    early = ok & np.any((since >= 0) & (since < 3.0), axis=1)
    late = ok & np.any((since >= 1.5) & (since < 5.0), axis=1)
    full = math.nan
    if no_gap:
        out_full = tilt.estimate(tr.gyr_rad_s, tr.acc_m_s2, period_s=tr.dt_s, params=params)
        full = _rms(broad.inclination_error_deg(out_full.quat_E_S, tr.quat_E_S_opt)[keep], early)
    return (full, _rms(err, early), _rms(err, late), _rms(err, ok))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("broad_dir", type=Path, metavar="BROAD_DIR",
                    help="folder of the BROAD trials (.hdf5)")
    ap.add_argument("--gap", type=float, default=0.5, help="length of each gap (s)")
    ap.add_argument("--reacquire-s", type=float, default=tilt.DEFAULT_PARAMS.reacquire_s)
    ap.add_argument("--gap-rate-corr-s", type=float,
                    default=tilt.DEFAULT_PARAMS.gap_rate_corr_s,
                    help="the gap bridge's correlation time (s; 0: the rate after the gap over "
                         "the whole gap, inf: the trapezoid)")
    args = ap.parse_args()
    params = tilt.DEFAULT_PARAMS._replace(reacquire_s=args.reacquire_s,
                                          gap_rate_corr_s=args.gap_rate_corr_s)
    print(f"gaps of {args.gap:g} s, reacquire_s = {args.reacquire_s:g} s, gap_rate_corr_s = "
          f"{args.gap_rate_corr_s:g} s; RMS error (deg)")
    print(f"{'trial':40s} {'no gap':>7s} {'0-3 s':>7s} {'1.5-5 s':>8s} {'trial':>7s}")
    rows = []
    for path in broad.list_trials(args.broad_dir):
        tr = broad.load_trial(path)
        row = trial_errors(tr, args.gap, params)
        rows.append(row)
        print(f"{tr.name[:40]:40s} {row[0]:7.2f} {row[1]:7.2f} {row[2]:8.2f} {row[3]:7.2f}",
              flush=True)
    m = np.mean(rows, axis=0)
    print(f"{'mean':40s} {m[0]:7.2f} {m[1]:7.2f} {m[2]:8.2f} {m[3]:7.2f}")


if __name__ == "__main__":
    main()
