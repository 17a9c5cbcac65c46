"""Filter variants prototyped in the plain-Python reference (``tilt.stream.Stream``), scored on the
validation set beside VQF (docs/tilt.md, "Validation across datasets and rates"), class by class
and rate by rate, with a leave-one-class-out choice among the variants.

    python benchmarks/tilt_stream_variants.py --cache DIR --broad BROAD_DIR [--seeds 2]
        [--variants current,no_shock_recovery,vel_m_s=1.0] [--engine stream|batch] [--only REGEX]
        [--jobs 2] [--json FILE]

A variant is a ``TiltParams``: a name of ``VARIANTS`` or ``field=value;field=value`` over the
defaults (a prototype's options are parameters whose defaults keep the filter as it is). Every
case is run through ``Stream`` sample by sample (~40 000 samples/s on a quiet core), so a full
table over BROAD at four rates and the synthetic classes costs minutes per variant; the cases
(resampled BROAD trials, synthetic recordings) and the scores are kept in ``--cache`` (scores
keyed by the parameters a variant changes and ``CODE_VERSION``, to be bumped when an edit changes
what a parameter set computes), and cases run in ``--jobs`` processes.

The classes: BROAD by kind (rotation 01–08, translation 10–18, disturbed 24–32) at 285.7, 1000,
100 and 50 Hz; the six synthetic motion classes, the vigorous hand-held class and the shock class
(:mod:`verticality.tilt.evaluation.shocks`) at 50, 100, 286 and 1000 Hz; the fault recordings
(their 2σ share).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from verticality.io import broad
from verticality.tilt import limits as tilt_limits
from verticality.tilt import stream as tilt_stream
from verticality.tilt.params import (
    DEFAULT_PARAMS,
    NO_SHOCK_RECOVERY,
    TiltParams,
    block_samples,
)

BROAD_KIND = {"01": "rotation", "03": "rotation", "05": "rotation", "06": "rotation",
              "08": "rotation", "10": "translation", "12": "translation", "15": "translation",
              "18": "translation", "24": "disturbed", "26": "disturbed", "32": "disturbed"}
RATES = (50.0, 100.0, 286.0, 1000.0)
CODE_VERSION = "s3"
SHOCK_AFTER_S = (1.0, 2.0, 5.0)  # the error this long after the impact is reported
SHOCK_WINDOW_S = 10.0  # a shock case is scored from the impact to this long after it

VARIANTS: dict[str, TiltParams] = {
    "current": DEFAULT_PARAMS,
    "no_shock_recovery": DEFAULT_PARAMS._replace(**NO_SHOCK_RECOVERY),
}


def variant(name: str) -> TiltParams:
    """A named variant, or ``field=value;field=value`` over the defaults."""
    if name in VARIANTS:
        return VARIANTS[name]
    fields = dict(kv.split("=") for kv in name.split(";"))
    return DEFAULT_PARAMS._replace(**{k: type(getattr(DEFAULT_PARAMS, k))(eval(v))
                                      for k, v in fields.items()})


def _tag(p: dict, engine: str) -> str:
    """The key of a variant's scores: the parameters it changes from the defaults and the
    engine (the scores are kept across edits that leave the defaults' filter as it is: bump
    ``CODE_VERSION`` when they do not, as when the defaults change)."""
    changed = {k: v for k, v in p.items() if v != getattr(DEFAULT_PARAMS, k)}
    return (hashlib.sha1(json.dumps(changed, sort_keys=True).encode()).hexdigest()[:12]
            + CODE_VERSION + ("" if engine == "stream" else "batch"))


class _Store:
    """Scores by ``tag|case``, one JSON file per tag (so that runs of different variants can go
    on at once)."""

    def __init__(self, folder: Path):
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.data, self.dirty = {}, set()
        for f in folder.glob("*.json"):
            self.data.update(json.loads(f.read_text()))

    def put(self, key, value):
        self.data[key] = value
        self.dirty.add(key.split("|")[0])

    def flush(self):
        for tag in self.dirty:
            f = self.folder / f"{tag}.json"
            mine = {k: v for k, v in self.data.items() if k.split("|")[0] == tag}
            tmp = f.with_suffix(".tmp")
            tmp.write_text(json.dumps(mine))
            tmp.replace(f)
        self.dirty = set()


# ---------------------------------------------------------------------------- cases


def _case_file(cache: Path, key: str) -> Path:
    return cache / "cases" / (key.replace("/", "_") + ".npz")


def _ranges(gyr, acc):
    """Per-axis full scales from the recording's flat tops (as ``tilt.estimate`` infers them),
    for a Stream, which takes given ranges only."""
    held = tilt_limits.held_rows(gyr, acc)
    out = []
    for x, floor in ((gyr, tilt_limits.GYR_FLOOR_RAD_S), (acc, tilt_limits.ACC_FLOOR_M_S2)):
        lo, hi = tilt_limits.inferred_levels(x, held, floor)
        r = np.minimum(-lo, hi)
        out.append(None if not np.any(np.isfinite(r)) else r)
    return out


def build_cases(broad_dir, seeds, cache: Path, shock_seeds=range(4)) -> list[str]:
    """Every case's key (``class/name/rate``), its arrays cached in ``cache``."""
    from verticality.tilt.evaluation import realistic as rr
    from verticality.tilt.evaluation import validation as tv
    from verticality.tilt.evaluation.shocks import shock_recording

    (cache / "cases").mkdir(parents=True, exist_ok=True)
    keys = []

    def save(key, gyr, acc, quat, scored, dt, extra=None):
        keys.append(key)
        f = _case_file(cache, key)
        if f.exists():
            return
        g_r, a_r = _ranges(gyr, acc)
        np.savez(f, gyr=gyr, acc=acc, quat=quat, scored=scored, dt=dt,
                 gyr_range=np.full(3, np.inf) if g_r is None else g_r,
                 acc_range=np.full(3, np.inf) if a_r is None else a_r, **(extra or {}))

    if broad_dir:
        for path in broad.list_trials(broad_dir):
            trial = None
            for rate in (None, 1000.0, 100.0, 50.0):
                name = path.stem
                kind = BROAD_KIND[name[:2]]
                key = f"BROAD-{kind}/{name[:2]}/{'native' if rate is None else int(rate)}"
                if _case_file(cache, key).exists():
                    keys.append(key)
                    continue
                trial = trial or broad.load_trial(path)
                if rate is None:
                    save(key, trial.gyr_rad_s, trial.acc_m_s2, trial.quat_E_S_opt,
                         trial.movement, trial.dt_s)
                else:
                    c = tv.resample_trial(trial, rate)
                    save(key, c.gyr_rad_s, c.acc_m_s2, c.quat_E_S, c.scored, 1.0 / c.rate_hz)
    for kind in rr.ALL_MOTIONS:
        for seed in seeds:
            for rate in RATES:
                key = f"{kind}/{seed}/{int(rate)}"
                if _case_file(cache, key).exists():
                    keys.append(key)
                    continue
                rec = rr.recording(kind, seed, 60.0, rate_hz=rate)
                n = rec.gyr_rad_s.shape[0]
                save(key, rec.gyr_rad_s, rec.acc_m_s2, rec.quat_E_S,
                     np.arange(n) * rec.dt_s >= rr.SCORE_FROM_S, rec.dt_s)
    for seed in shock_seeds:
        for rate in RATES:
            key = f"shock/{seed}/{int(rate)}"
            if _case_file(cache, key).exists():
                keys.append(key)
                continue
            rec = shock_recording(seed, rate)
            t = np.arange(rec.gyr_rad_s.shape[0]) * rec.dt_s
            scored = (t >= rec.impact_s) & (t < rec.impact_s + SHOCK_WINDOW_S)
            save(key, rec.gyr_rad_s, rec.acc_m_s2, rec.quat_E_S, scored, rec.dt_s,
                 {"impact_s": rec.impact_s, "rest_s": rec.rest_s})
    return keys


def fault_keys(seeds) -> list[str]:
    from verticality.tilt.evaluation.faults import FAULTS

    return [f"fault-{fault}/{seed}/100" for fault in FAULTS for seed in seeds]


# ---------------------------------------------------------------------------- runs


def run_stream(params: TiltParams, gyr, acc, dt, gyr_range=None, acc_range=None):
    """Our filter through the plain-Python ``Stream``: (quat (N, 4), up (N, 3), σ (N,) rad,
    flags (N,))."""
    block = block_samples(params, dt)
    s = tilt_stream.Stream(params, block, gyr_range_rad_s=gyr_range, acc_range_m_s2=acc_range)
    n = gyr.shape[0]
    quat = np.empty((n, 4))
    up = np.empty((n, 3))
    sig2 = np.empty(n)
    flags = np.empty(n, dtype=np.int64)
    calib = (params.acc_calib_m_s2 / params.g_m_s2) ** 2
    init2 = params.init_tilt_rad ** 2
    step = s.step
    g_rows, a_rows = gyr.tolist(), acc.tolist()
    last_P, pv = None, 0.0
    for k in range(n):
        o = step(g_rows[k], a_rows[k], dt)
        quat[k] = o[3]
        up[k] = o[2]
        flags[k] = o[5]
        if s.P is not last_P:
            last_P = s.P
            pv = float(last_P[0, 0] + last_P[1, 1])
        sig2[k] = pv + 2.0 * (s.qmiss if s.initialized else init2) + calib
    return quat, up, np.sqrt(sig2), flags


def run_batch(params: TiltParams, gyr, acc, dt, gyr_range=None, acc_range=None):
    """The same through the JAX batch filter (``tilt.estimate``'s path), for variants of the
    parameters it implements (no recompilation per parameter set): the same outputs to ~1e-9."""
    from verticality.tilt import estimator
    from verticality.tilt.output import tilt_sigma_rad

    out = estimator.estimate_steps(gyr, acc, dt, params, gyr_range_rad_s=gyr_range,
                                   acc_range_m_s2=acc_range)
    return (np.asarray(out.quat_E_S), np.asarray(out.up_S),
            np.asarray(tilt_sigma_rad(out.var, params)), np.asarray(out.flags))


def _vqf_quat(gyr, acc, dt):
    from vqf import VQF

    return VQF(float(dt)).updateBatch(np.ascontiguousarray(gyr), np.ascontiguousarray(acc))[
        "quat6D"]


def score_key(args) -> dict:
    """One (variant, case): RMSE (deg), share of scored samples within 2σ, VQF's RMSE, and the
    shock metrics."""
    params_dict, key, cache, engine = args
    params = TiltParams(**params_dict)
    run = run_batch if engine == "batch" else run_stream
    if key.startswith("fault-"):
        return _score_fault(params, key, run)
    d = np.load(_case_file(Path(cache), key))
    gyr, acc, quat_true, scored, dt = d["gyr"], d["acc"], d["quat"], d["scored"], float(d["dt"])
    g_r = None if not np.any(np.isfinite(d["gyr_range"])) else d["gyr_range"]
    a_r = None if not np.any(np.isfinite(d["acc_range"])) else d["acc_range"]
    quat, _, sigma, flags = run(params, gyr, acc, dt, g_r, a_r)
    err = broad.inclination_error_deg(quat, quat_true)
    sel = scored & np.isfinite(err)
    res = {"rmse": float(np.sqrt(np.mean(err[sel] ** 2))),
           "within_2sigma": float(np.mean(err[sel] <= 2.0 * np.degrees(sigma[sel])))}
    if "impact_s" in d:
        ok = sel & (flags == 0)
        res["unflagged"] = float(np.mean(ok[sel]))
        res["within_2sigma_unflagged"] = float(np.mean(err[ok] <= 2.0 * np.degrees(sigma[ok])))
        k0 = int(round(float(d["impact_s"]) / dt))
        for s in SHOCK_AFTER_S:
            k = k0 + int(round(s / dt))
            res[f"err_{s:g}s"] = float(err[k])
            res[f"sigma_{s:g}s"] = float(np.degrees(sigma[k]))
            res[f"flags_{s:g}s"] = int(flags[k])
    return res


def vqf_key(args) -> dict:
    key, cache = args
    d = np.load(_case_file(Path(cache), key))
    quat = _vqf_quat(d["gyr"], d["acc"], float(d["dt"]))
    err = broad.inclination_error_deg(quat, d["quat"])
    sel = d["scored"] & np.isfinite(err)
    res = {"rmse": float(np.sqrt(np.mean(err[sel] ** 2)))}
    if "impact_s" in d:
        k0 = int(round(float(d["impact_s"]) / float(d["dt"])))
        for s in SHOCK_AFTER_S:
            res[f"err_{s:g}s"] = float(err[k0 + int(round(s / float(d["dt"])))])
    return res


def _score_fault(params, key, run) -> dict:
    from verticality.core import so3
    from verticality.tilt.evaluation.faults import fault_recording

    fault, seed = key[len("fault-"):].split("/")[:2]
    gyr, acc, dt, up_true = fault_recording(fault, seed=int(seed))
    # (clipping inferred from the flat tops, as tilt.estimate does)
    g_r, a_r = _ranges(gyr, acc)
    _, up, sigma, flags = run(params, gyr, acc, dt, g_r, a_r)
    err = np.asarray(so3.angle_between_unit_vectors(up, up_true))
    ok = flags == 0
    return {"within_2sigma": float(np.mean(err[ok] <= 2 * sigma[ok])), "unflagged": float(
        ok.mean()), "n_ok": int(ok.sum()), "n_in": int(np.sum(err[ok] <= 2 * sigma[ok]))}


# ---------------------------------------------------------------------------- tables


def case_class(key: str) -> tuple[str, str]:
    """(class, rate label) of a case key."""
    cls, _, rate = key.split("/")
    return cls, rate


def summarize(scores: dict, vqf: dict) -> dict:
    """``{(class, rate): {"n", "ours", "vqf", "ratio", "min_2sigma"}}`` (means over the cases)."""
    groups: dict = {}
    for key in scores:
        groups.setdefault(case_class(key), []).append(key)
    rows = {}
    for g, keys in sorted(groups.items()):
        if g[0].startswith("fault-"):
            n_ok = sum(scores[k]["n_ok"] for k in keys)
            rows[g] = {"n": len(keys), "pooled_2sigma": sum(scores[k]["n_in"] for k in keys)
                       / max(n_ok, 1),
                       "min_2sigma": min(scores[k]["within_2sigma"] for k in keys)}
            continue
        ours = float(np.mean([scores[k]["rmse"] for k in keys]))
        theirs = float(np.mean([vqf[k]["rmse"] for k in keys]))
        row = {"n": len(keys), "ours": ours, "vqf": theirs, "ratio": ours / theirs,
               "min_2sigma": min(scores[k]["within_2sigma"] for k in keys)}
        if "err_5s" in scores[keys[0]]:
            for s in SHOCK_AFTER_S:
                row[f"err_{s:g}s"] = float(np.mean([scores[k][f"err_{s:g}s"] for k in keys]))
                row[f"max_err_{s:g}s"] = float(np.max([scores[k][f"err_{s:g}s"] for k in keys]))
                row[f"vqf_err_{s:g}s"] = float(np.mean([vqf[k][f"err_{s:g}s"] for k in keys]))
        rows[g] = row
    return rows


def leave_one_class_out(per_variant: dict) -> dict:
    """For each class held out, the variant whose mean log ratio to VQF over the other classes
    (every rate) is smallest, and its held-out ratio: ``{class: (variant, {rate: ratio})}``."""
    classes = sorted({c for rows in per_variant.values() for (c, _) in rows
                      if not c.startswith("fault-")})
    out = {}
    for held in classes:
        def cost(v, held=held):
            rs = [r["ratio"] for (c, _), r in per_variant[v].items()
                  if c != held and "ratio" in r]
            return float(np.mean(np.log(rs)))
        best = min(per_variant, key=cost)
        out[held] = (best, {rate: r["ratio"] for (c, rate), r in per_variant[best].items()
                            if c == held})
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--broad", help="folder of BROAD .hdf5 files")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--fault-seeds", type=int, default=5)
    ap.add_argument("--shock-seeds", type=int, default=6)
    ap.add_argument("--variants", default="current")
    ap.add_argument("--only", default="", help="run only the cases whose key matches this "
                    "regular expression")
    ap.add_argument("--cache", required=True, help="folder for the cases and the scores (reused "
                    "across runs; written only there)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json")
    ap.add_argument("--engine", choices=("stream", "batch"), default="stream",
                    help="batch: the JAX batch filter (parameters it implements only)")
    args = ap.parse_args(argv)
    cache = Path(args.cache)
    keys = (build_cases(args.broad, range(args.seeds), cache, range(args.shock_seeds))
            + fault_keys(range(args.fault_seeds)))
    if args.only:
        import re

        keys = [k for k in keys if re.search(args.only, k)]
    store = _Store(cache / "scores")
    names = args.variants.split(",")
    if args.engine == "batch":
        from verticality.sweep.engine import use_compile_cache

        use_compile_cache(str(cache / "jax"))
    todo = []
    for v in names:
        p = variant(v)._asdict()
        tag = _tag(p, args.engine)
        for k in keys:
            if f"{tag}|{k}" not in store.data:
                todo.append((f"{tag}|{k}", (p, k, str(cache), args.engine)))
    vqf_todo = [(f"vqf|{k}", (k, str(cache))) for k in keys
                if not k.startswith("fault-") and f"vqf|{k}" not in store.data]
    pool = None
    if args.jobs > 1:
        import multiprocessing

        # (spawned: a forked child of a process that has run JAX can deadlock)
        pool = multiprocessing.get_context("spawn").Pool(args.jobs)
    mapper = pool.imap if pool is not None else map
    for (sk, _), res in zip(vqf_todo, mapper(vqf_key, [a for _, a in vqf_todo]), strict=True):
        store.put(sk, res)
    for i, ((sk, a), res) in enumerate(zip(todo, mapper(score_key, [a for _, a in todo]),
                                           strict=True)):
        store.put(sk, res)
        print(f"\r{i + 1}/{len(todo)} {a[1]}     ", end="", file=sys.stderr)
        if i % 20 == 19:
            store.flush()
    if pool is not None:
        pool.close()
    print(file=sys.stderr)
    store.flush()
    store = store.data
    vqf = {k: store[f"vqf|{k}"] for k in keys if not k.startswith("fault-")}
    per_variant = {}
    for v in names:
        p = variant(v)._asdict()
        tag = _tag(p, args.engine)
        per_variant[v] = summarize({k: store[f"{tag}|{k}"] for k in keys}, vqf)
    print(f"{'class':26s} {'Hz':>6s} " + " ".join(f"{v[:14]:>14s}" for v in names) + "   VQF")
    for g in per_variant[names[0]]:
        rows = [per_variant[v][g] for v in names]
        if "ratio" in rows[0]:
            cells = " ".join(f"{r['ours']:6.3f} {r['ratio']:5.3f}"
                             + ("*" if r["min_2sigma"] < 0.95 else " ") for r in rows)
            print(f"{g[0]:26s} {g[1]:>6s} {cells}  {rows[0]['vqf']:6.3f}")
        else:
            cells = " ".join(f"{100 * r['pooled_2sigma']:6.1f}/{100 * r['min_2sigma']:5.1f}%"
                             for r in rows)
            print(f"{g[0]:26s} {g[1]:>6s} {cells}")
    for g in per_variant[names[0]]:
        if "err_5s" in per_variant[names[0]][g]:
            print(f"{g[0]} {g[1]} Hz, error after the impact (mean / max over seeds), deg:")
            for v in names:
                r = per_variant[v][g]
                print(f"  {v:20s} " + "  ".join(
                    f"+{s:g}s {r[f'err_{s:g}s']:5.2f}/{r[f'max_err_{s:g}s']:5.2f}"
                    for s in SHOCK_AFTER_S))
            r = per_variant[names[0]][g]
            print(f"  {'vqf':20s} " + "  ".join(f"+{s:g}s {r[f'vqf_err_{s:g}s']:5.2f}"
                                                for s in SHOCK_AFTER_S))
    if len(names) > 1:
        print("\nleave one class out (the variant best on the other classes):")
        for held, (v, ratios) in leave_one_class_out(per_variant).items():
            print(f"  {held:26s} {v:20s} " + " ".join(f"{rate}:{r:.3f}"
                                                      for rate, r in ratios.items()))
    if args.json:
        Path(args.json).write_text(json.dumps(
            {v: {f"{c}/{r}": row for (c, r), row in rows.items()}
             for v, rows in per_variant.items()}, indent=1))


if __name__ == "__main__":
    main()
