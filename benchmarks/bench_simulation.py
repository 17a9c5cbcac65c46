"""Speed of the simulator: the 3-D medial model under the P13 impact motion, 60 s at
1 ms, one run and a vmap batch of 256 runs.

    python benchmarks/bench_simulation.py [--batch 256] [--duration 60]

Prints compile time, wall and CPU times, the real-time factor (simulated s per CPU s; CPU time is
the fair "one core" measure on a shared machine, wall time is printed beside it), the batch
throughput against the single run, and, as a peer measured in the same run, a naive
implementation: the same RK4 step jitted alone and called from a Python loop.

XLA is pinned to one thread (``--xla_cpu_multi_thread_eigen=false``) so that CPU time is one core.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false "
                                   "intra_op_parallelism_threads=1")

import dataclasses  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from verticality.core.integrate import rk4_step_staged  # noqa: E402
from verticality.models.gimbal import GimbalInput  # noqa: E402
from verticality.simulation import closed_loop as sim
from verticality.simulation import trajectories as tr


def timed(fn, *args, repeat=3):
    best_wall, best_cpu = float("inf"), float("inf")
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        jax.block_until_ready(fn(*args))
        best_wall = min(best_wall, time.perf_counter() - w0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    return best_wall, best_cpu


def batched_plant(n: int):
    """``n`` plants (one batch axis on every parameter leaf) whose pendula differ: m ±10 %, β ±20 %,
    J = m l² (1, 1, 1/20) of the spread m."""
    base = sim.DEFAULT_PLANT
    spread = jnp.linspace(-1.0, 1.0, n)
    pend = base.otoliths.pendula[0]
    p = pend.params
    m = p.m_kg * (1.0 + 0.1 * spread)
    p_b = p._replace(m_kg=m, beta_Nms=p.beta_Nms * (1.0 + 0.2 * spread),
                     J_pivot_S=m[:, None] * jnp.array([0.06**2, 0.06**2, 0.06**2 / 20.0]))
    p_b = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(jnp.asarray(a, float),
                                                            (n,) + jnp.shape(a))
                                 if jnp.shape(a)[:1] != (n,) else a, p_b)
    gimbal_b = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(jnp.asarray(a, float),
                                                                 (n,) + jnp.shape(a)), base.gimbal)
    otoliths_b = dataclasses.replace(base.otoliths,
                                     pendula=(dataclasses.replace(pend, params=p_b),))
    return dataclasses.replace(base, gimbal=gimbal_b, otoliths=otoliths_b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--duration", type=float, default=60.0)
    args = ap.parse_args()
    T = args.duration
    traj = tr.impact(duration_s=max(T, 10.0))
    print(f"3-D medial model, P13 impact motion, {T:g} s at 1 ms (plant RK4 1 ms, records every "
          f"20 ms); load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores\n")
    rows = []
    for condition in ("fixed", "stabilized"):
        cfg = sim.SimConfig(duration_s=T, condition=condition)
        ctrl = sim.p13_controller() if condition == "stabilized" else None
        run = sim.make_simulator(traj, cfg, controller=ctrl)
        key = jax.random.PRNGKey(0)
        w0 = time.perf_counter()
        jax.block_until_ready(run(key, sim.DEFAULT_PLANT, sim.NoiseParams()))
        compile_s = time.perf_counter() - w0
        wall, cpu = timed(run, key, sim.DEFAULT_PLANT, sim.NoiseParams())
        # a batch whose plants differ (β and m spread ±20 %/±10 %), so that nothing is shared
        keys = jax.random.split(key, args.batch)
        params_b = batched_plant(args.batch)
        batch = jax.jit(jax.vmap(run, in_axes=(0, 0, None)))
        w0 = time.perf_counter()
        jax.block_until_ready(batch(keys, params_b, sim.NoiseParams()))
        compile_b = time.perf_counter() - w0
        wall_b, cpu_b = timed(batch, keys, params_b, sim.NoiseParams(), repeat=2)
        # Monte Carlo use: each run reduced to a few numbers inside the jit (records not kept)
        def summary(k, p, n, run=run):
            rec = run(k, p, n).record
            return (jnp.max(jnp.abs(rec.otolith_rad)), jnp.sqrt(jnp.mean(rec.y ** 2)),
                    sim.tilt_metrics(rec)["max_tilt_error_deg"])

        single_s = jax.jit(summary)
        batch_s = jax.jit(jax.vmap(summary, in_axes=(0, 0, None)))
        jax.block_until_ready(single_s(key, sim.DEFAULT_PLANT, sim.NoiseParams()))
        jax.block_until_ready(batch_s(keys, params_b, sim.NoiseParams()))
        wall_s1, cpu_s1 = timed(single_s, key, sim.DEFAULT_PLANT, sim.NoiseParams())
        wall_sb, cpu_sb = timed(batch_s, keys, params_b, sim.NoiseParams(), repeat=2)
        print(f"[{condition}] summaries only (no records kept): single CPU {cpu_s1:.3f} s "
              f"({T / cpu_s1:.0f}x real time); batch of {args.batch} CPU {cpu_sb:.2f} s -> "
              f"throughput {args.batch * cpu_s1 / cpu_sb:.1f}x the single run (CPU), "
              f"{args.batch * wall_s1 / wall_sb:.1f}x (wall)")
        rows.append((condition, compile_s, wall, cpu, compile_b, wall_b, cpu_b, cpu_s1, cpu_sb))
        print(f"[{condition}] compile+first run {compile_s:.1f} s; run: wall {wall:.3f} s, "
              f"CPU {cpu:.3f} s -> {T / cpu:.0f}x real time (CPU), {T / wall:.0f}x (wall)")
        print(f"[{condition}] vmap batch of {args.batch}: compile+first {compile_b:.1f} s; "
              f"wall {wall_b:.2f} s, CPU {cpu_b:.2f} s -> throughput "
              f"{args.batch * cpu / cpu_b:.1f}x the single run (CPU), "
              f"{args.batch * wall / wall_b:.1f}x (wall); {args.batch * T / cpu_b:.0f}x real time")

    # peer: the same plant step, jitted alone and driven from Python (the naive way), 2 s
    plant = sim.with_condition(sim.DEFAULT_PLANT, "fixed")
    x = sim.initial_state(plant, traj.motion(0.0))._replace(gimbal=None)  # locked: not integrated
    h = 1e-3

    def f(trunk, xx):
        return plant.rate_and_motion(xx, GimbalInput(jnp.zeros(2), trunk))[0], jnp.zeros(0)

    @jax.jit
    def step(x, t):
        w3 = jax.vmap(traj.motion)(t + jnp.array([0.0, 0.5 * h, h]))
        return rk4_step_staged(f, w3, x, h, project=plant.project)[0]

    jax.block_until_ready(step(x, 0.0))
    n_naive = 2000
    w0, c0 = time.perf_counter(), time.process_time()
    for i in range(n_naive):
        x = step(x, i * h)
    jax.block_until_ready(x)
    naive_cpu = (time.process_time() - c0) * (T / (n_naive * h))
    naive_wall = (time.perf_counter() - w0) * (T / (n_naive * h))
    cond, _, wall, cpu, *_ = rows[0]
    print(f"\npeer (naive Python loop over a jitted RK4 step, extrapolated to {T:g} s): CPU "
          f"{naive_cpu:.1f} s, wall {naive_wall:.1f} s -> the scan is {naive_cpu / cpu:.0f}x "
          f"(CPU) / {naive_wall / wall:.0f}x (wall) faster")
    print(f"required: >= 100x real time on one core (fixed: {T / rows[0][3]:.0f}x); batch >= 10x "
          f"the single-run throughput (fixed, full records: "
          f"{args.batch * rows[0][3] / rows[0][6]:.1f}x; summaries: "
          f"{args.batch * rows[0][7] / rows[0][8]:.1f}x)")


if __name__ == "__main__":
    main()
