"""Running tilt filters over BROAD trials: ours and, when the optional ``peers`` extra is installed,
VQF (vqf, 6D, defaults, ``VQF(Ts).updateBatch``), Madgwick and Mahony (ahrs, 6D, defaults); and
the offline estimators, our smoother (``tilt.smooth``) and VQF's ``offlineVQF`` (6D, defaults).

Peers are imported lazily; a missing one is reported by :func:`peer_status` with the reason and
left out of the results (never silently replaced). Every filter gets the same gyro/accelerometer
arrays; the score is the official BROAD inclination RMSE (:mod:`verticality.io.broad`). Our filter
also reports its uncertainty, and :func:`sigma_calibration` scores that against the same errors.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.io import broad
from verticality.tilt.output import tilt_sigma_rad
from verticality.tilt.params import DEFAULT_PARAMS

OURS = "verticality"
PEERS = ("vqf", "madgwick", "mahony")
FILTERS = (OURS,) + PEERS
# the offline estimators (the whole recording at once): our smoother (tilt.smooth) and VQF's
# offline variant (vqf.offlineVQF, 6D, defaults); evaluate broad runs them beside the filters
OURS_OFFLINE = "verticality-offline"
VQF_OFFLINE = "vqf-offline"
OFFLINE = (OURS_OFFLINE, VQF_OFFLINE)
_PEER_MODULE = {"vqf": "vqf", "madgwick": "ahrs", "mahony": "ahrs", VQF_OFFLINE: "vqf"}


def peer_status() -> dict[str, str | None]:
    """``{peer: None}`` when importable, else ``{peer: "reason"}``."""
    import importlib

    status: dict[str, str | None] = {}
    for name in PEERS + (VQF_OFFLINE,):
        try:
            importlib.import_module(_PEER_MODULE[name])
            status[name] = None
        except ImportError as exc:
            status[name] = (f"{_PEER_MODULE[name]} not installed ({exc.msg}); "
                            "install the peers extra: pip install 'verticality[peers]'")
    return status


def choose_filters(requested=None) -> tuple[list[str], list[str]]:
    """``(filters, notes)``: the ``requested`` filter names (checked), or ours, every installed
    peer, our smoother and VQF's offline variant (when vqf is installed); a note for each wanted
    peer that is not installed."""
    status = peer_status()
    peers = PEERS + (VQF_OFFLINE,)
    if requested is None:
        filters = ([OURS] + [p for p in PEERS if status[p] is None] + [OURS_OFFLINE]
                   + ([VQF_OFFLINE] if status[VQF_OFFLINE] is None else []))
    else:
        filters = list(requested)
        for f in filters:
            if f not in _RUNNERS:
                raise InputError(f"unknown filter {f!r}; choose from {', '.join(_RUNNERS)}")
    notes = [f"note: skipping {p}: {status[p]}" for p in peers
             if status[p] is not None and p in (requested or peers)]
    return filters, notes


def _ours(gyr, acc, dt_s):
    from verticality.tilt import estimator

    out = estimator.estimate_steps(gyr, acc, dt_s)
    return out.quat_E_S, out.bias_S_rad_s, tilt_sigma_rad(out.var, DEFAULT_PARAMS)


def _ours_offline(gyr, acc, dt_s):
    from verticality.tilt import estimator

    out = estimator.smooth_steps(gyr, acc, dt_s)
    return out.quat_E_S, out.bias_S_rad_s, tilt_sigma_rad(out.var, DEFAULT_PARAMS)


def _vqf_offline(gyr, acc, dt_s):
    from vqf import offlineVQF

    res = offlineVQF(np.ascontiguousarray(gyr, dtype=np.float64),
                     np.ascontiguousarray(acc, dtype=np.float64), None, float(np.median(dt_s)))
    return res["quat6D"], res["bias"], None


def _vqf(gyr, acc, dt_s):
    from vqf import VQF

    res = VQF(float(np.median(dt_s))).updateBatch(np.ascontiguousarray(gyr, dtype=np.float64),
                                                  np.ascontiguousarray(acc, dtype=np.float64))
    return res["quat6D"], res["bias"], None


def _madgwick(gyr, acc, dt_s):
    from ahrs.filters import Madgwick

    f = Madgwick(gyr=np.asarray(gyr), acc=np.asarray(acc), frequency=1.0 / float(np.median(dt_s)))
    return f.Q, np.zeros_like(gyr), None


def _mahony(gyr, acc, dt_s):
    from ahrs.filters import Mahony

    f = Mahony(gyr=np.asarray(gyr), acc=np.asarray(acc), frequency=1.0 / float(np.median(dt_s)))
    return f.Q, np.zeros_like(gyr), None


_RUNNERS: dict[str, Callable] = {OURS: _ours, "vqf": _vqf, "madgwick": _madgwick,
                                 "mahony": _mahony, OURS_OFFLINE: _ours_offline,
                                 VQF_OFFLINE: _vqf_offline}
_OURS_ALL = (OURS, OURS_OFFLINE)  # ours: any samples, and a σ


def run_filter(name: str, gyr_rad_s, acc_m_s2, dt_s):
    """Quaternions ``q_E_S`` (N, 4) wxyz and gyro bias (N, 3) of filter ``name``. Peers need a
    constant rate (the median step is used) and finite samples; they report no bias except VQF
    (zeros otherwise)."""
    return run_filter_sigma(name, gyr_rad_s, acc_m_s2, dt_s)[:2]


def run_filter_sigma(name: str, gyr_rad_s, acc_m_s2, dt_s):
    """:func:`run_filter` and the tilt's standard deviation (N,) rad, or None for the peers."""
    if name not in _RUNNERS:
        raise InputError(f"unknown filter {name!r}; choose one of {', '.join(_RUNNERS)}")
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    dts = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), gyr.shape[:1])
    if name not in _OURS_ALL:
        reason = peer_status()[name]
        if reason is not None:
            raise InputError(f"filter {name}: {reason}")
        if not (np.all(np.isfinite(gyr)) and np.all(np.isfinite(acc))):
            raise InputError(f"filter {name} does not accept NaN samples; use --filter {OURS}")
    return _RUNNERS[name](gyr, acc, dts)


def sigma_calibration(quat_est_wxyz, sigma_rad, trial: broad.BroadTrial) -> dict[str, float]:
    """How the reported tilt σ compares with the official inclination error, over the samples the
    metric scores (``movement``, valid reference): ``within_1sigma`` and ``within_2sigma``, the
    fractions of samples whose error is at most σ and 2σ (a calibrated σ of a 2-D Gaussian error
    gives 0.632 and 0.982), and ``rms_sigma_deg``, the RMS of σ (deg), to set beside the RMSE."""
    err = broad.inclination_error_deg(quat_est_wxyz, trial.quat_E_S_opt)
    sel = trial.movement & np.isfinite(err)
    if not np.any(sel):
        raise InputError(f"{trial.name}: no movement samples with a valid optical reference")
    e, s = err[sel], np.degrees(np.asarray(sigma_rad)[sel])
    return {"within_1sigma": float(np.mean(e <= s)), "within_2sigma": float(np.mean(e <= 2 * s)),
            "rms_sigma_deg": float(np.sqrt(np.mean(s**2)))}


def evaluate_trial(path, filters, progress: Callable[[str], None] | None = None,
                   compile_cache: str | None = None) -> dict:
    """One trial of :func:`evaluate_trials` (one task when distributed): ``{"name": NAME,
    "rmse": {FILTER: rmse_deg}, "runtime_s": {FILTER: s}, "samples": int, "sigma":
    sigma_calibration or None, "sigma_offline": ... or None}``. ``compile_cache``: JAX's
    persistent compilation cache for a worker process."""
    from verticality.sweep.engine import use_compile_cache

    use_compile_cache(compile_cache)
    trial = broad.load_trial(path)
    res = {"name": trial.name, "rmse": {}, "runtime_s": {}, "samples": trial.gyr_rad_s.shape[0],
           "sigma": None, "sigma_offline": None}
    for name in filters:
        if progress is not None:
            progress(f"{trial.name}: {name}")
        t0 = time.perf_counter()
        quat, _, sig = run_filter_sigma(name, trial.gyr_rad_s, trial.acc_m_s2, trial.dt_s)
        res["runtime_s"][name] = time.perf_counter() - t0
        res["rmse"][name] = broad.inclination_rmse_deg(np.asarray(quat), trial)
        if sig is not None:
            res["sigma" if name == OURS else "sigma_offline"] = sigma_calibration(
                np.asarray(quat), sig, trial)
    return res


def evaluate_trials(paths: Iterable[Path], filters: Iterable[str],
                    progress: Callable[[str], None] | None = None, *,
                    scheduler: str | None = None, workers: int | None = None,
                    compile_cache: str | Path | None = None) -> dict:
    """``{"trials": {NAME: {FILTER: rmse_deg}}, "mean": {FILTER: rmse_deg},
    "runtime_s": {FILTER: s}, "samples": int, "sigma": {NAME: sigma_calibration},
    "sigma_offline": {NAME: sigma_calibration}}`` for the given filters over the given trials
    (``sigma`` for our filter, ``sigma_offline`` for our smoother, when they run).

    With ``scheduler`` (a running Dask scheduler) or ``workers`` (a ``LocalCluster`` of that many
    worker processes), one task per trial (:func:`evaluate_trial`, on
    :mod:`verticality.sweep.engine`, with a progress bar instead of ``progress``'s messages); the
    table is the same to the bit, the runtimes are the workers' (summed over trials).
    ``compile_cache``: the workers' JAX compilation cache (default: this process's)."""
    filters = list(filters)
    paths = list(paths)
    if scheduler or workers is not None:
        from verticality.sweep import engine

        if compile_cache is None:
            import jax

            compile_cache = jax.config.jax_compilation_cache_dir
        cache = str(compile_cache) if compile_cache else None
        done = engine.map_tasks(evaluate_trial,
                                {f"broad-trial-{i}": (str(p), filters, None, cache)
                                 for i, p in enumerate(paths)},
                                scheduler=scheduler, workers=workers,
                                progress=progress is not None, description="evaluate broad")
        per_trial = list(done.values())
    else:
        per_trial = [evaluate_trial(p, filters, progress) for p in paths]
    trials = {r["name"]: r["rmse"] for r in per_trial}
    runtime = {f: 0.0 for f in filters}
    for r in per_trial:
        for f in filters:
            runtime[f] += r["runtime_s"][f]
    sigma = {r["name"]: r["sigma"] for r in per_trial if r["sigma"] is not None}
    sigma_offline = {r["name"]: r["sigma_offline"] for r in per_trial
                     if r["sigma_offline"] is not None}
    mean = {f: float(np.mean([t[f] for t in trials.values()])) for f in filters}
    return {"trials": trials, "mean": mean, "runtime_s": runtime,
            "samples": sum(r["samples"] for r in per_trial), "sigma": sigma,
            "sigma_offline": sigma_offline}
