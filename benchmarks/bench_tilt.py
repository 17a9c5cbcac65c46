"""Throughput of the tilt filter (verticality.estimators.tilt) against vqf in the same run.

- batch: ``tilt.run`` on one BROAD trial (or a synthetic recording if the data are absent) vs
  ``vqf.VQF(Ts).updateBatch`` (C++), samples per second, best of several repetitions, compile
  excluded (one compiled shape serves every recording);
- streaming, one call per sample as a 1 kHz robot loop would, samples per second:
  ``tilt_stream.Stream.step`` (plain Python/NumPy twin of the filter, the real-time path) and the
  jitted packed JAX step ``tilt.make_step()`` (bounded by JAX's per-call cost).

Run: ``python benchmarks/bench_tilt.py [--reps 5]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

from verticality.estimators import tilt

BROAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"


def _data():
    trial = BROAD / "01_undisturbed_slow_rotation_A.hdf5"
    if trial.is_file():
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--stream-samples", type=int, default=2000)
    args = ap.parse_args()
    gyr, acc, dt, name = _data()
    gyr = np.ascontiguousarray(gyr)
    acc = np.ascontiguousarray(acc)
    n = gyr.shape[0]
    print(f"data: {name}, {n} samples")

    tilt.run(gyr, acc, dt)  # compile
    t_ours = _best(lambda: tilt.run(gyr, acc, dt), args.reps)
    rows = [("verticality tilt.run (batch)", n / t_ours)]
    try:
        from vqf import VQF

        t_vqf = _best(lambda: VQF(dt).updateBatch(gyr, acc), args.reps)
        rows.append(("vqf VQF.updateBatch (C++)", n / t_vqf))
    except ImportError:
        t_vqf = None
        print("note: vqf not installed (pip install 'verticality[peers]'): no peer ratio")

    # streaming: jitted step, params and block baked in, one call per sample
    stepper = tilt.make_step()
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

    from verticality.estimators.tilt_stream import Stream

    m_py = 4 * m

    def stream_py():
        s = Stream()
        for k in range(m_py):
            s.step(gyr[k], acc[k], dt)

    t_stream = _best(stream_py, max(1, args.reps // 2)) * m / m_py
    rows.append(("verticality tilt_stream.Stream.step (Python)", m / t_stream))

    print(f"{'implementation':45s} {'samples/s':>14s}")
    for label, sps in rows:
        print(f"{label:45s} {sps:14,.0f}")
    if t_vqf is not None:
        print(f"ratio batch ours/vqf: {t_vqf / t_ours:.2f} (required >= 1)")
    print(f"streaming (tilt_stream.Stream): {m / t_stream:,.0f} samples/s (required >= 20,000); "
          f"a 1 kHz loop costs {100 * 1000 * t_stream / m:.1f} % of a core")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
