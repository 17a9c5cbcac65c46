"""Throughput of the tilt filter (verticality.tilt) and its offline smoother against
vqf in the same run.

- batch: ``tilt.estimate`` (``TiltFilter.run`` from the start) on BROAD trial
  01 (``--broad BROAD_DIR``) or a synthetic recording vs ``vqf.VQF(Ts).updateBatch`` (C++), samples
  per second, best of several repetitions (the two alternate), compile excluded (one compiled shape
  serves every recording); also the time of the compiled chunks alone, the rest of the run's time
  being the host side;
- batch at common rates: the same ratio with the recording at 50, 100, 285.7 and 1000 Hz (the
  Kalman update interval is a time: 6, 11, 32 and 112 samples per block), as a user runs it
  (``tilt.estimate(gyr, acc, period_s=...)``, host side included, compile excluded): BROAD trial 01
  resampled to each rate (``validation.resample_trial``) with ``--broad``, and a synthetic
  recording of the same length (``evaluation.realistic``, slow rotation) at each rate;
- offline: ``tilt.smooth`` (the filter and its backward pass) vs ``vqf.offlineVQF`` (C++) on
  the same recording repeated to ``--offline-samples`` samples (10⁶ by default), alternating, best
  of ``--offline-reps``;
- streaming, one call per sample as a 1 kHz robot loop would, samples per second:
  ``tilt.Stream.step`` (the plain Python/NumPy implementation of the filter with its output type,
  the real-time path) and the jitted packed JAX step ``estimator.make_step(period_s=dt)`` (bounded
  by JAX's per-call cost).

Run: ``python benchmarks/bench_tilt.py [--broad BROAD_DIR] [--reps 5]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

from verticality import tilt
from verticality.tilt import estimator
from verticality.tilt.params import BLOCK


def _data(broad_dir: Path | None):
    """BROAD trial 01 from ``broad_dir`` (the folder of the dataset's trials) when given, else a
    synthetic recording of the same length."""
    if broad_dir is not None:
        trial = broad_dir / "01_undisturbed_slow_rotation_A.hdf5"
        from verticality.io import broad

        t = broad.load_trial(trial)
        return t.gyr_rad_s, t.acc_m_s2, t.dt_s, trial.name
    rng = np.random.default_rng(0)
    n = 60_000
    gyr = rng.normal(0, 0.5, (n, 3))
    acc = rng.normal(0, 0.5, (n, 3)) + [0, 0, 9.81]
    return gyr, acc, 0.0035, "synthetic"


def _best(fn, reps):
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _best_interleaved(fns, reps):
    best = dict.fromkeys(fns, np.inf)
    for _ in range(reps):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


RATES_HZ = (50.0, 100.0, 285.7, 1000.0)


def _at_rates(broad_dir: Path | None, duration_s: float):
    """``(label, rate, gyr, acc)`` of the recordings timed at :data:`RATES_HZ`: BROAD trial 01
    resampled to each rate (with ``broad_dir``; 285.7 Hz is its own rate) and a synthetic
    recording of ``duration_s`` at each rate."""
    from verticality.tilt.evaluation import realistic

    if broad_dir is not None:
        from verticality.io import broad
        from verticality.tilt.evaluation.validation import resample_trial

        trial = broad.load_trial(broad_dir / "01_undisturbed_slow_rotation_A.hdf5")
        for rate in RATES_HZ:
            if abs(rate - trial.sampling_rate_hz) < 0.5:
                yield "BROAD 01", trial.sampling_rate_hz, trial.gyr_rad_s, trial.acc_m_s2
            else:
                c = resample_trial(trial, rate)
                yield "BROAD 01", rate, c.gyr_rad_s, c.acc_m_s2
    for rate in RATES_HZ:
        rec = realistic.recording(realistic.MOTIONS[0], 0, duration_s, rate_hz=rate)
        yield "synthetic", rate, rec.gyr_rad_s, rec.acc_m_s2


def _ratios_at_rates(broad_dir: Path | None, duration_s: float, reps: int, VQF):
    """Rows ``(label, rate, n, ours s, vqf s)``: ``tilt.estimate`` and ``VQF.updateBatch``
    alternated, best of ``reps`` each, after one untimed run (the compilation)."""
    rows = []
    for label, rate, gyr, acc in _at_rates(broad_dir, duration_s):
        gyr, acc = np.ascontiguousarray(gyr), np.ascontiguousarray(acc)
        dt = 1.0 / rate
        tilt.estimate(gyr, acc, period_s=dt)  # compile
        best = _best_interleaved(
            {"ours": lambda g=gyr, a=acc, d=dt: tilt.estimate(g, a, period_s=d),
             "vqf": lambda g=gyr, a=acc, d=dt: VQF(d).updateBatch(g, a)}, reps)
        rows.append((label, rate, gyr.shape[0], best["ours"], best["vqf"]))
    return rows


def _device_time(gyr, acc, dt, reps):
    """Time of the compiled chunks alone (``tilt_kernels.run_chunk`` chained on the device, as
    in the batch run, inputs already packed): the run's time minus this is the host side
    (packing, transfers, writing the result arrays)."""
    from verticality.tilt import batch as tilt_batch
    from verticality.tilt import core as tilt_core
    from verticality.tilt import kernels as tilt_kernels

    nb = tilt_batch.chunk_blocks(BLOCK, False)
    chunk = nb * BLOCK
    n = gyr.shape[0]
    dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
    parts = [jax.device_put(tilt_batch.chunk_data(nb, BLOCK, 0, gyr[a:a + chunk],
                                                  acc[a:a + chunk], dts[a:a + chunk]))
             for a in range(0, n, chunk)]
    p = tilt.DEFAULT_PARAMS
    x0 = jax.device_put(tilt_core.initialize(tilt.TiltFilter().init().x, acc[0], p, xp=np))
    head = tilt_batch.chunk_head(None, nb, nb)  # the usual chunk header, as the batch run builds it
    p_vec = jax.device_put(np.asarray(p, dtype=np.float64))

    def chunks():
        x = x0
        for part in parts:
            x, _, outs = tilt_kernels.run_chunk(x, head, part, p_vec, BLOCK, p._fields)
        jax.block_until_ready((x, outs))

    chunks()
    return _best(chunks, reps), len(parts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--broad", type=Path, default=None, metavar="BROAD_DIR",
                    help="folder of the BROAD trials: time trial 01 (default: synthetic data)")
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--stream-samples", type=int, default=2000)
    ap.add_argument("--offline-samples", type=int, default=1_000_000)
    ap.add_argument("--offline-reps", type=int, default=5)
    ap.add_argument("--rates-reps", type=int, default=15,
                    help="repetitions of each run at the common rates (0: skip them)")
    ap.add_argument("--rates-duration", type=float, default=200.0, metavar="S",
                    help="length of the synthetic recording at the common rates (s)")
    args = ap.parse_args()
    gyr, acc, dt, name = _data(args.broad)
    gyr = np.ascontiguousarray(gyr)
    acc = np.ascontiguousarray(acc)
    n = gyr.shape[0]
    print(f"data: {name}, {n} samples")

    tilt.estimate(gyr, acc, period_s=dt)  # compile
    try:
        from vqf import VQF
    except ImportError:
        VQF = None
        print("note: vqf not installed (pip install 'verticality[peers]'): no peer ratio")
    # ours and vqf alternate (best of reps each), so that a change of the machine's load during
    # the benchmark affects both alike
    fns = {"ours": lambda: tilt.estimate(gyr, acc, period_s=dt)}
    if VQF is not None:
        fns["vqf"] = lambda: VQF(dt).updateBatch(gyr, acc)
    best = _best_interleaved(fns, args.reps)
    t_ours, t_vqf = best["ours"], best.get("vqf")
    rows = [("verticality tilt.estimate (batch)", n / t_ours)]
    if t_vqf is not None:
        rows.append(("vqf VQF.updateBatch (C++)", n / t_vqf))
    t_dev, n_chunks = _device_time(gyr, acc, dt, args.reps)

    # offline: the smoother against offlineVQF on a long recording (the trial repeated)
    m_off = args.offline_samples
    reps = -(-m_off // n)
    gyr_l = np.ascontiguousarray(np.tile(gyr, (reps, 1))[:m_off])
    acc_l = np.ascontiguousarray(np.tile(acc, (reps, 1))[:m_off])
    tilt.smooth(gyr_l, acc_l, period_s=dt)  # compile
    fns_off = {"smooth": lambda: tilt.smooth(gyr_l, acc_l, period_s=dt)}
    if VQF is not None:
        from vqf import offlineVQF

        fns_off["offlineVQF"] = lambda: offlineVQF(gyr_l, acc_l, None, dt)
    best_off = _best_interleaved(fns_off, args.offline_reps)
    rows.append((f"verticality tilt.smooth (offline, {m_off:.0e})",
                 m_off / best_off["smooth"]))
    if "offlineVQF" in best_off:
        rows.append((f"vqf offlineVQF (C++, {m_off:.0e})", m_off / best_off["offlineVQF"]))

    # streaming: jitted step, params and block baked in, one call per sample
    stepper = estimator.make_step(period_s=dt)
    step = stepper.step
    state = stepper.init()
    m = args.stream_samples
    state, out = step(state, gyr[0], acc[0], dt)
    jax.block_until_ready(out)

    def stream():
        s = state
        for k in range(m):
            s, o = step(s, gyr[k], acc[k], dt)
        jax.block_until_ready(o)

    t_jit = _best(stream, max(1, args.reps // 2))
    rows.append(("verticality make_step (jitted JAX, per call)", m / t_jit))

    m_py = 4 * m

    def stream_py():
        s = tilt.Stream(period_s=dt)
        for k in range(m_py):
            s.step(gyr[k], acc[k])

    t_stream = _best(stream_py, max(1, args.reps // 2)) * m / m_py
    rows.append(("verticality tilt.Stream.step (Python)", m / t_stream))

    print(f"{'implementation':45s} {'samples/s':>14s}")
    for label, sps in rows:
        print(f"{label:45s} {sps:14,.0f}")
    print(f"tilt.estimate: {1e3 * t_ours:.2f} ms, of which {n_chunks} compiled chunks "
          f"{1e3 * t_dev:.2f} ms ({1e9 * t_dev / n:.0f} ns/sample), host side "
          f"{1e3 * (t_ours - t_dev):.2f} ms")
    if t_vqf is not None:
        print(f"ratio batch ours/vqf: {t_vqf / t_ours:.2f} (required >= 1)")
    if VQF is not None and args.rates_reps > 0:
        print(f"batch at common rates, tilt.estimate vs VQF.updateBatch (best of "
              f"{args.rates_reps}, alternated; ratio = vqf time / ours, required >= 0.9):")
        print(f"  {'recording':10s} {'rate Hz':>8s} {'samples':>8s} {'ours ms':>8s} "
              f"{'vqf ms':>8s} {'ratio':>6s}")
        for label, rate, n_r, t_o, t_v in _ratios_at_rates(args.broad, args.rates_duration,
                                                          args.rates_reps, VQF):
            print(f"  {label:10s} {rate:8.1f} {n_r:8d} {1e3 * t_o:8.2f} {1e3 * t_v:8.2f} "
                  f"{t_v / t_o:6.2f}")
    if "offlineVQF" in best_off:
        print(f"ratio offline ours/offlineVQF: {best_off['offlineVQF'] / best_off['smooth']:.2f}; "
              f"smoother {m_off / best_off['smooth'] / 1e6:.2f} M samples/s (required >= 1)")
    print(f"streaming (tilt.Stream): {m / t_stream:,.0f} samples/s (required >= 20,000); "
          f"a 1 kHz loop costs {100 * 1000 * t_stream / m:.1f} % of a core")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
