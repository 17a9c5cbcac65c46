"""Speed of the perception models: one 100 s paradigm at 100 Hz, and a vmap batch of parameter sets.

    python benchmarks/bench_perception.py [--batch 1000] [--repeats 3]

For each model (the Merfeld–Zupan observer, human preset; the Laurens–Angelaki filter) the sensor
signals of the OVAR paradigm (20°, 60°/s, 100 s, 10 000 samples) are computed once; then the
model's ``run`` is compiled and timed (best of ``--repeats``, after compilation) on one parameter
set, and on ``--batch`` parameter sets at once (``jax.vmap`` over the estimator values: the
Merfeld–Zupan gains kω, kf, kfω, ka drawn ±30 % around the preset; for Laurens–Angelaki the
gains of σΩ drawn ±30 %, each from its own Riccati equation, outside the timing). Reported:
the single run's wall time and real-time factor, and the batch's throughput relative to the
single run (parameter sets per second, batch / single) — a ratio, so that the figure does not
depend on the machine.
"""

from __future__ import annotations

import argparse
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from verticality.perception import paradigms as pp
from verticality.perception import perceive as pc
from verticality.perception.laurens import laurens_angelaki
from verticality.perception.merfeld import MerfeldZupan
from verticality.perception.params import LAURENS_PRESETS, MERFELD_PRESETS


def _best(f, repeats):
    jax.block_until_ready(f())  # compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f())
        times.append(time.perf_counter() - t0)
    return min(times)


def _estimators(model: str, n: int, rng):
    if model == "merfeld":
        p = MERFELD_PRESETS["human"]
        scale = rng.uniform(0.7, 1.3, size=(n, 4))
        one = MerfeldZupan(p)
        many = MerfeldZupan(p._replace(k_omega=jnp.asarray(p.k_omega * scale[:, 0]),
                                       k_f=jnp.asarray(p.k_f * scale[:, 1]),
                                       k_f_omega=jnp.asarray(p.k_f_omega * scale[:, 2]),
                                       k_a=jnp.asarray(p.k_a * scale[:, 3]),
                                       tau_s=jnp.full(n, p.tau_s), tau_a_s=jnp.full(n, p.tau_a_s),
                                       tau_v_s=jnp.full(n, p.tau_v_s)))
        return one, many
    p = LAURENS_PRESETS["default"]
    ests = [laurens_angelaki(p._replace(sigma_omega_rad_s=p.sigma_omega_rad_s * s))
            for s in rng.uniform(0.7, 1.3, size=n)]
    many = jax.tree_util.tree_map(lambda *a: jnp.stack(a), *ests)
    return laurens_angelaki(p), many


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    rec = pp.ovar(20.0, 60.0, on_s=100.0 - 1.0)
    rng = np.random.default_rng(0)
    print(f"OVAR paradigm: {rec.t_s.size} samples, {rec.t_s[-1]:.0f} s at 100 Hz; "
          f"batch {args.batch}")
    print(f"{'model':<10} {'single ms':>10} {'real-time x':>12} {'batch s':>9} "
          f"{'throughput ratio':>17}")
    for model in ("merfeld", "laurens"):
        params = MERFELD_PRESETS["human"] if model == "merfeld" else LAURENS_PRESETS["default"]
        alpha = pc.canal_signals(pc.canal_model(params), rec.omega_H_rad_s, rec.t_s)
        ys = jnp.asarray(np.concatenate([alpha, pc.otolith_signals(rec)], axis=1))
        dts = jnp.full(ys.shape[0], 0.01)
        one, many = _estimators(model, args.batch, rng)

        def run1(est, ys=ys, dts=dts):
            return est.run(est.init(None), None, ys, dts)[1].g_H

        single = jax.jit(run1)
        batch = jax.jit(jax.vmap(run1))
        t1 = _best(lambda single=single, one=one: single(one), args.repeats)
        tb = _best(lambda batch=batch, many=many: batch(many), max(1, args.repeats - 1))
        ratio = (args.batch / tb) / (1.0 / t1)
        print(f"{model:<10} {1e3 * t1:>10.1f} {float(rec.t_s[-1]) / t1:>12.0f} {tb:>9.2f} "
              f"{ratio:>17.1f}")
        assert math.isfinite(ratio)


if __name__ == "__main__":
    main()
