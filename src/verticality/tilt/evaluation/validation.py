"""The tilt filter's validation set: every recording the project can score with one parameter set,
at several sampling rates, beside VQF and offlineVQF in the same run (docs/tilt.md, "Validation
across datasets and rates").

* **BROAD** (the trials a user has; CC BY 4.0): at the native 285.7 Hz and resampled to lower
  rates (:func:`resample_trial`: anti-aliased, as an IMU sampled at that rate would read).
* **Synthetic** handheld recordings with data-sheet sensor errors
  (:mod:`verticality.tilt.evaluation.realistic`), each motion class at several rates, the
  vigorous hand-held class with brief clipping included.

A case is scored by the inclination error (BROAD's metric) on its scored samples, for the causal
filters (ours, VQF) and the offline ones (our smoother, offlineVQF), with the share of our scored
samples whose error is within 2σ (the σ's honesty). :func:`summarize` reduces the cases to one row
per dataset and rate: the mean errors, their ratios and the smallest σ coverage.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import NamedTuple

import numpy as np
from scipy import signal

from verticality.core import so3
from verticality.io import broad
from verticality.tilt.evaluation.broad import OFFLINE, OURS

CAUSAL = (OURS, "vqf")
FILTERS = CAUSAL + OFFLINE
BROAD_RATES_HZ = (None, 1000.0, 100.0, 50.0)  # None: the native rate
SYNTHETIC_RATES_HZ = (50.0, 100.0, 286.0, 1000.0)


class Case(NamedTuple):
    """One recording to score: readings, the true orientation ``quat_E_S`` (N, 4) wxyz (NaN rows
    where unknown), and the samples ``scored`` (N,) bool."""

    dataset: str
    name: str
    rate_hz: float
    gyr_rad_s: np.ndarray
    acc_m_s2: np.ndarray
    quat_E_S: np.ndarray
    scored: np.ndarray
    t_s: np.ndarray | None = None  # the time stamps a file holds (None: regular at rate_hz)
    windows: dict | None = None  # extra scored windows {name: (N,) bool}, each within scored
    clipped: np.ndarray | None = None  # (N,) bool: truly clipped samples (saturation classes)


def resample(x: np.ndarray, rate_in_hz: float, rate_out_hz: float, n_out: int) -> np.ndarray:
    """``x`` (N, k) sampled at ``rate_in_hz`` read at ``rate_out_hz`` (``n_out`` samples from the
    same start): low-passed below the lower Nyquist frequency (a zero-phase FIR at 0.4 × the new
    rate, as an IMU's anti-alias filter would pass the band) and interpolated linearly at the new
    instants (both sensors alike: no assumption on how an IMU times its gyro samples, to which
    BROAD's scores are sensitive, docs/tilt.md)."""
    cutoff_hz = min(0.4 * rate_out_hz, 0.45 * rate_in_hz)  # (reading at a higher rate: none)
    taps = signal.firwin(int(8 * rate_in_hz / cutoff_hz) | 1, cutoff_hz, fs=rate_in_hz)
    y = signal.filtfilt(taps, [1.0], x, axis=0, padtype="even")
    t_in = np.arange(x.shape[0]) / rate_in_hz
    t_out = np.arange(n_out) / rate_out_hz
    return np.stack([np.interp(t_out, t_in, y[:, i]) for i in range(x.shape[1])], axis=1)


def slerp_at(quat: np.ndarray, rate_in_hz: float, t_out: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4) sampled at ``rate_in_hz`` read at times ``t_out`` by spherical
    interpolation between the two neighbours; NaN where either neighbour is NaN."""
    u = t_out * rate_in_hz
    i = np.clip(np.floor(u).astype(int), 0, quat.shape[0] - 2)
    s = (u - i)[:, None]
    q0, q1 = quat[i], quat[i + 1]
    q1 = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -q1, q1)
    rel = np.asarray(so3.quat_multiply(so3.quat_conjugate(q0), q1))
    rot = np.asarray(so3.quat_log(rel))
    return np.asarray(so3.quat_multiply(q0, so3.quat_exp(s * rot)))


def resample_trial(trial: broad.BroadTrial, rate_hz: float) -> Case:
    """A BROAD trial as an IMU sampled at ``rate_hz`` would have read it (:func:`resample`); the
    optical reference interpolated (:func:`slerp_at`), the movement mask by the nearest sample."""
    rate_in = trial.sampling_rate_hz
    n = int(np.floor((trial.gyr_rad_s.shape[0] - 1) * rate_hz / rate_in)) + 1
    t_out = np.arange(n) / rate_hz
    nearest = np.clip(np.round(t_out * rate_in).astype(int), 0, trial.movement.size - 1)
    return Case("BROAD", trial.name, rate_hz,
                resample(trial.gyr_rad_s, rate_in, rate_hz, n),
                resample(trial.acc_m_s2, rate_in, rate_hz, n),
                slerp_at(trial.quat_E_S_opt, rate_in, t_out), trial.movement[nearest])


def broad_cases(paths: Iterable, rates_hz=BROAD_RATES_HZ) -> Iterable[Case]:
    """The BROAD trials at ``paths``, each at every rate of ``rates_hz`` (None: native)."""
    for path in paths:
        trial = broad.load_trial(path)
        for rate in rates_hz:
            if rate is None:
                yield Case("BROAD", trial.name, trial.sampling_rate_hz, trial.gyr_rad_s,
                           trial.acc_m_s2, trial.quat_E_S_opt, trial.movement)
            else:
                yield resample_trial(trial, rate)


def synthetic_cases(kinds, seeds, rates_hz=SYNTHETIC_RATES_HZ,
                    duration_s: float = 60.0) -> Iterable[Case]:
    """The synthetic recordings of each motion class in ``kinds`` and seed, each at every rate
    (the motion and the sensor's errors the same at every rate; its noise drawn per rate). The
    vigorous hand-held class is a dataset of its own (``synthetic/vigorous``): the motion where a
    filter that mistakes motion for disturbance loses."""
    from verticality.tilt.evaluation import realistic as rr

    for kind in kinds:
        for seed in seeds:
            for rate in rates_hz:
                rec = rr.recording(kind, seed, duration_s, rate_hz=rate)
                n = rec.gyr_rad_s.shape[0]
                scored = np.arange(n) * rec.dt_s >= rr.SCORE_FROM_S
                dataset = "synthetic/vigorous" if kind == rr.VIGOROUS else "synthetic"
                yield Case(dataset, f"{kind}/{seed}", rate, rec.gyr_rad_s, rec.acc_m_s2,
                           rec.quat_E_S, scored)


def case_steps(case: Case):
    """The time steps a filter integrates for ``case``: ``1 / rate_hz``, or from its time stamps
    as :func:`verticality.tilt.estimate` takes them (:func:`~verticality.tilt.output.time_axis`)."""
    if case.t_s is None:
        return 1.0 / case.rate_hz
    from verticality.tilt.output import time_axis

    return time_axis(case.t_s.shape[0], t_s=case.t_s)[1]


def score_case(case: Case, filters=FILTERS, run: Callable | None = None) -> dict:
    """``{"rmse": {FILTER: deg}, "within_2sigma": {FILTER: share}, "windows": {WINDOW: {FILTER:
    deg}}}`` of one case (the σ share for our filter and smoother only; ``windows`` the RMSE over
    each of the case's extra windows). ``run(name, gyr, acc, dt)`` → ``(quat, bias, σ or None)``
    (default: :mod:`verticality.tilt.evaluation.broad`'s runners). Our filters get the case's
    time steps (:func:`case_steps`); the peers the nominal period, as a user would give it."""
    if run is None:
        from verticality.tilt.evaluation.broad import run_filter_sigma as run
    res = {"rmse": {}, "within_2sigma": {}, "windows": {w: {} for w in case.windows or {}}}
    steps = case_steps(case)
    for name in filters:
        dt = steps if name.startswith(OURS) else 1.0 / case.rate_hz
        quat, _, sigma = run(name, case.gyr_rad_s, case.acc_m_s2, dt)
        err = broad.inclination_error_deg(np.asarray(quat), case.quat_E_S)
        sel = case.scored & np.isfinite(err)
        res["rmse"][name] = float(np.sqrt(np.mean(err[sel] ** 2)))
        for w, mask in (case.windows or {}).items():
            res["windows"][w][name] = float(np.sqrt(np.mean(err[sel & mask] ** 2)))
        if sigma is not None:
            res["within_2sigma"][name] = float(
                np.mean(err[sel] <= 2.0 * np.degrees(np.asarray(sigma)[sel])))
    return res


def failure_cases(classes, seeds, rates_hz=SYNTHETIC_RATES_HZ,
                  shares=None) -> Iterable[Case]:
    """The failure classes' recordings (:mod:`verticality.tilt.evaluation.failures`), each seed
    at every rate; the saturation classes at every clipped share of ``shares`` (default
    :data:`~verticality.tilt.evaluation.failures.CLIP_SHARES`), a dataset per share
    (``sat-gyro 5%``). Scored from :data:`~verticality.tilt.evaluation.realistic.SCORE_FROM_S`
    of the true time on."""
    from verticality.tilt.evaluation import failures as fl
    from verticality.tilt.evaluation import realistic as rr

    shares = fl.CLIP_SHARES if shares is None else shares
    for cls in classes:
        for seed in seeds:
            for rate in rates_hz:
                for share in (shares if cls in fl.SATURATION else (None,)):
                    rec = fl.recording(cls, seed, rate, share)
                    n = rec.gyr_rad_s.shape[0]
                    # the true time of each kept row: the clock classes' stamps lie
                    t_true = (rec.t_s if cls in ("jitter", "dropout") or cls not in fl.TIMING
                              else np.arange(n) * rec.period_s)
                    scored = t_true >= rr.SCORE_FROM_S
                    dataset = cls if share is None else f"{cls} {100 * share:g}%"
                    regular = cls not in fl.TIMING
                    yield Case(dataset, f"{cls}/{seed}", rate, rec.gyr_rad_s, rec.acc_m_s2,
                               rec.quat_E_S, scored, None if regular else rec.t_s,
                               rec.windows or None, rec.clipped)


def summarize(scored: dict) -> dict:
    """``{(dataset, rate_hz): row}`` from ``{(dataset, name, rate_hz): score_case result}``: the
    number of cases, each filter's mean RMSE, the ratios causal ours/VQF and offline
    ours/offlineVQF (of the means), and the smallest share within 2σ of our filter and smoother."""
    groups: dict = {}
    for (dataset, _, rate), res in scored.items():
        groups.setdefault((dataset, rate), []).append(res)
    rows = {}
    for key in sorted(groups, key=lambda k: (k[0], -k[1])):
        cases = groups[key]
        mean = {f: float(np.mean([c["rmse"][f] for c in cases])) for f in cases[0]["rmse"]}
        row = {"cases": len(cases), "mean_rmse_deg": mean}
        if "verticality" in mean and "vqf" in mean:
            row["causal_ratio"] = mean["verticality"] / mean["vqf"]
        if "verticality-offline" in mean and "vqf-offline" in mean:
            row["offline_ratio"] = mean["verticality-offline"] / mean["vqf-offline"]
        for f in ("verticality", "verticality-offline"):
            if f in cases[0]["within_2sigma"]:
                row[f"min_within_2sigma/{f}"] = min(c["within_2sigma"][f] for c in cases)
        for w in cases[0].get("windows", {}):
            row.setdefault("windows", {})[w] = {
                f: float(np.mean([c["windows"][w][f] for c in cases])) for f in mean}
        rows[key] = row
    return rows


def variant_runner(options: dict) -> Callable:
    """A ``run`` for :func:`score_case` whose our filter and smoother take the keyword arguments
    ``options`` (of :func:`verticality.tilt.estimator.estimate_steps`: ``params``,
    ``detect_clipping``, the ranges, ...); the peers as always."""
    from verticality.tilt import estimator
    from verticality.tilt.evaluation.broad import OURS_OFFLINE, run_filter_sigma
    from verticality.tilt.output import tilt_sigma_rad
    from verticality.tilt.params import DEFAULT_PARAMS

    params = options.get("params", DEFAULT_PARAMS)

    def run(name, gyr, acc, dt):
        if name == OURS:
            out = estimator.estimate_steps(gyr, acc, dt, **options)
        elif name == OURS_OFFLINE:
            out = estimator.smooth_steps(gyr, acc, dt, **options)
        else:
            return run_filter_sigma(name, gyr, acc, dt)
        return out.quat_E_S, out.bias_S_rad_s, tilt_sigma_rad(out.var, params)

    return run


def leave_one_class_out(cases: Iterable[Case], variants: dict, offline: bool = False,
                        progress: Callable[[str], None] | None = None,
                        runner: Callable = variant_runner) -> dict:
    """Which estimator variant the other classes would choose, and what it gives on each class.

    ``variants`` ``{NAME: options}`` (:func:`variant_runner`'s keyword arguments, e.g.
    ``{"now": {}, "no-detection": {"detect_clipping": False}}``). Every case is scored under every
    variant (the peer, VQF or with ``offline`` offlineVQF, once per case) and reduced per class
    (a case's ``dataset``) and rate to the ratio of mean RMSEs to the peer. A variant's score on
    a set of classes is the geometric mean of its ratios over their rows; for each class the
    variant with the best score on the *other* classes is chosen. Returns ``{"ratios": {VARIANT:
    {(class, rate): ratio}}, "within_2sigma": {VARIANT: {(class, rate): smallest share}},
    "chosen": {CLASS: {"variant": NAME, "ratios": {rate: ratio}, "best_here": NAME}}}``
    (``best_here``: the variant best on that class itself; a chosen variant that is not the best
    here is one the class would lose to the others' choice). ``runner(options)`` makes a variant's
    ``run`` (default :func:`variant_runner`; ``runner({})`` runs the peer)."""
    from verticality.tilt.evaluation.broad import OURS_OFFLINE, VQF_OFFLINE

    ours, peer = (OURS_OFFLINE, VQF_OFFLINE) if offline else (OURS, "vqf")
    cases = list(cases)
    sums: dict = {}
    for case in cases:
        key = (case.dataset, case.rate_hz)
        peer_rmse = score_case(case, (peer,), runner({}))["rmse"][peer]
        sums.setdefault(key, {"peer": [], **{v: [] for v in variants}, "2s": {}})
        sums[key]["peer"].append(peer_rmse)
        for v, options in variants.items():
            if progress is not None:
                progress(f"{case.dataset} {case.name} {case.rate_hz:.0f} Hz: {v}")
            r = score_case(case, (ours,), runner(options))
            sums[key][v].append(r["rmse"][ours])
            s2 = sums[key]["2s"].setdefault(v, 1.0)
            sums[key]["2s"][v] = min(s2, r["within_2sigma"][ours])
    ratios = {v: {k: float(np.mean(g[v]) / np.mean(g["peer"])) for k, g in sums.items()}
              for v in variants}
    within = {v: {k: g["2s"][v] for k, g in sums.items()} for v in variants}
    classes = sorted({k[0] for k in sums})

    def score(v, cls, held_out):
        r = [np.log(x) for k, x in ratios[v].items() if (k[0] != cls) == held_out]
        return float(np.mean(r)) if r else 0.0

    chosen = {}
    for c in classes:
        pick = min(variants, key=lambda v, c=c: score(v, c, True))
        here = min(variants, key=lambda v, c=c: score(v, c, False))
        chosen[c] = {"variant": pick, "best_here": here,
                     "ratios": {k[1]: x for k, x in ratios[pick].items() if k[0] == c}}
    return {"ratios": ratios, "within_2sigma": within, "chosen": chosen}
