"""Speed of the Newton-observer Lissajous experiment: JAX (jit + lax.scan + jacfwd) vs NumPy.

    python benchmarks/bench_newton.py [--numpy-seconds 1.0] [--repeats 3]

For each `newton-lissajous` condition the JAX closed loop (plant at 1 ms, PD, Newton observer
every 25 ms, 10 s simulated) is compiled once, then timed (best of ``--repeats``); the real-time
factor is simulated/wall. The peer is a straightforward NumPy implementation of the same observer
(same window, model, damped least squares and stopping rule) with a forward-difference Jacobian
and Python loops over samples, run on the same closed loop for ``--numpy-seconds`` of simulated
time (it is slow); its cost of a full 10 s run is extrapolated from the measured time before the
first window and the measured cost per sample once the observer solves at every sample, and
gives the ratio. "compile s" is first call minus a timed call (0 when the compiled loop is reused:
the condition is a traced flag, so one compilation serves all four conditions). The two
implementations' estimates are compared over that stretch as a cross-check.
"""

from __future__ import annotations

import argparse
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from verticality.models import lissajous_plant as lp
from verticality.simulation.newton_loop import (
    CONFIG,
    DT_S,
    KD,
    KP,
    NOISE_RAD,
    OBS_SUBSTEPS,
    SUBSTEPS,
    simulate,
)

CASES = [("fixed", "exact"), ("stabilized", "exact"), ("fixed", "perturbed"),
         ("stabilized", "perturbed")]


# ---------------------------------------------------------------- NumPy peer (Python loops)
def np_dyn(x, tau, ah, az, p):
    th_s, w_s, th_h, w_h = x
    c, s = math.cos(th_h), math.sin(th_h)
    a_h, a_z = c * ah - s * az, s * ah + c * az
    grav = -p.m_kg * p.l_m * ((p.g_m_s2 + a_z) * math.sin(th_s) + a_h * math.cos(th_s))
    return np.array([w_s, (grav - p.beta_Nms * (w_s - w_h)) / p.J_kg_m2, w_h, tau / p.K_kg_m2])


def np_rk4(x, u0, uh, u1, p, h):
    k1 = np_dyn(x, *u0, p)
    k2 = np_dyn(x + 0.5 * h * k1, *uh, p)
    k3 = np_dyn(x + 0.5 * h * k2, *uh, p)
    k4 = np_dyn(x + h * k3, *u1, p)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def np_block(x, ublk, p, sub=OBS_SUBSTEPS):
    """Same sub-stepped model as lissajous_plant.observer_model (mean + first-moment ramp)."""
    k = ublk.shape[0] // sub
    c = (np.arange(k) + 0.5) / k - 0.5
    h = SUBSTEPS * DT_S / sub
    for i in range(sub):
        seg = ublk[i * k:(i + 1) * k]  # (k, 3)
        mean = seg.mean(axis=0)
        ramp = 12.0 * (seg * c[:, None]).mean(axis=0)
        x = np_rk4(x, mean - 0.5 * ramp, mean, mean + 0.5 * ramp, p, h)
    return x


def np_map(xi, U, p):
    xs = [xi]
    for j in range(1, U.shape[0]):
        xs.append(np_block(xs[-1], U[j], p))
    xs = np.array(xs)
    return xs[:, 0] - xs[:, 2], xs


def np_solve(xi0, U, Y, p, cfg=CONFIG):
    def lin(xi):
        Yp, xs = np_map(xi, U, p)
        J = np.zeros((Y.shape[0], 4))
        for j in range(4):  # forward differences
            h = 1e-7 * max(1.0, abs(xi[j]))
            e = np.zeros(4)
            e[j] = h
            J[:, j] = (np_map(xi + e, U, p)[0] - Yp) / h
        r = Y - Yp
        scale = np.maximum(np.linalg.norm(J, axis=0), 1e-100)
        Us, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
        return r @ r, xs, (Us, s, Vt, scale, r)

    m = Y.shape[0]
    y_scale = 1.0 + math.sqrt(Y @ Y / m)

    def proposal(L, mu2):
        Us, s, Vt, scale, r = L
        smax = max(s.max(), 1e-100)
        gain = np.where(s > cfg.rcond * smax, s / (s * s + mu2 * smax * smax), 0.0)
        coef = gain * (Us.T @ r)
        return ((Vt.T @ coef) / scale,
                math.sqrt(np.sum((s * coef) ** 2) / m) <= cfg.step_tol * y_scale)

    xi = xi0
    cost, xs, L = lin(xi)
    mu2 = cfg.damping
    delta, small = proposal(L, mu2)
    i = 0
    while i < cfg.iterations and not small:
        cand = xi + delta
        cc, xsc, Lc = lin(cand)
        if cc <= cost:
            xi, cost, xs, L, mu2 = cand, cc, xsc, Lc, max(mu2 / 3, cfg.damping_min)
        else:
            mu2 *= 8
        delta, small = proposal(L, mu2)
        i += 1
    return xs


def np_simulate(fixed, level, noise, n_blocks):
    p_true, p_obs = lp.p11_head(1.0), lp.p11_head(1.0 + level)
    theta_dot0 = float(lp.trunk(0.0).Theta_dot_rad_s)
    x = np.array([0.0, 0.0, 0.0 if fixed else 0.1, theta_dot0 if fixed else 0.0])
    xh = np.zeros(4)
    N = CONFIG.window
    Ubuf, Ybuf, Xbuf = np.zeros((N, SUBSTEPS, 3)), np.zeros(N), np.tile(xh, (N, 1))
    est = []
    t_first_solve = None
    for b in range(n_blocks):
        if b + 1 == N:
            t_first_solve = time.perf_counter()
        ublk = np.zeros((SUBSTEPS, 3))
        for i in range(SUBSTEPS):
            t = (b * SUBSTEPS + i) * DT_S + 0.5 * DT_S
            w1, w2, w3 = 0.5 * math.pi, math.pi, 2 * math.pi
            ah_I, az_I = -0.25 * w1**2 * math.sin(w1 * t), -0.25 * w2**2 * math.sin(w2 * t)
            c, s = math.cos(x[2]), math.sin(x[2])
            u = (p_true.K_kg_m2 * -0.25 * math.pi * w3**2 * math.sin(w3 * t) if fixed
                 else -KP * xh[2] - KD * xh[3], c * ah_I + s * az_I, -s * ah_I + c * az_I)
            x = np_rk4(x, u, u, u, p_true, DT_S)
            xh = np_rk4(xh, u, u, u, p_obs, DT_S)
            ublk[i] = u
            est.append(xh[2])
        y = x[0] - x[2] + noise[b]
        x_pred = np_block(Xbuf[-1], ublk, p_obs)
        Ubuf = np.concatenate([Ubuf[1:], ublk[None]])
        Ybuf = np.concatenate([Ybuf[1:], [y]])
        Xbuf = np.concatenate([Xbuf[1:], x_pred[None]])
        if b + 1 >= N:
            Xbuf = np_solve(Xbuf[0], Ubuf, Ybuf, p_obs)
        xh = Xbuf[-1].copy()
        est[-1] = xh[2]
    return np.array(est), t_first_solve


# ---------------------------------------------------------------- JAX
def jax_runner(fixed, level, noise, n_blocks):
    p_true, p_obs = lp.p11_head(1.0), lp.p11_head(1.0 + level)
    key = jax.random.PRNGKey(11)
    return lambda: jax.block_until_ready(simulate(
        p_true, p_obs, jnp.asarray(fixed), jnp.asarray(noise, dtype=float), key, n_blocks))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--numpy-seconds", type=float, default=1.5)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    duration = 10.0
    n_blocks = int(round(duration / (SUBSTEPS * DT_S)))
    np_blocks = max(CONFIG.window + 4, int(round(args.numpy_seconds / (SUBSTEPS * DT_S))))
    print(f"newton-lissajous, {duration:.0f} s simulated per condition "
          f"(NumPy peer over {np_blocks * SUBSTEPS * DT_S:.2f} s)")
    print(f"{'condition':24s} {'compile s':>9s} {'jax wall s':>10s} {'x real time':>11s} "
          f"{'numpy s/sim-s':>13s} {'jax/numpy':>9s} {'max |dθ̂| deg':>13s}")
    for cond, model in CASES:
        fixed = cond == "fixed"
        level = 0.1 if model == "perturbed" else 0.0
        noise_sd = NOISE_RAD if model == "perturbed" else 0.0
        run = jax_runner(fixed, level, noise_sd, n_blocks)
        t0 = time.perf_counter()
        series = run()
        compile_s = time.perf_counter() - t0
        walls = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            run()
            walls.append(time.perf_counter() - t0)
        wall = min(walls)
        noise = np.asarray(noise_sd * jax.random.normal(jax.random.PRNGKey(11), (n_blocks,)))
        t0 = time.perf_counter()
        est_np, t_fs = np_simulate(fixed, level, noise, np_blocks)
        t1 = time.perf_counter()
        # extrapolate to the full run: the stretch before the first window as measured, then the
        # measured cost per observer sample once the observer solves at every sample
        per_block = (t1 - t_fs) / (np_blocks - CONFIG.window + 1)
        np_full = (t_fs - t0) + per_block * (n_blocks - CONFIG.window + 1)
        np_per_s = np_full / duration
        jax_per_s = wall / duration
        diff = np.rad2deg(np.max(np.abs(est_np - np.asarray(series.theta_H_hat_rad)[:est_np.size])))
        print(f"{cond + '/' + model:24s} {max(compile_s - wall, 0.0):9.1f} {wall:10.3f} "
              f"{duration / wall:11.1f} "
              f"{np_per_s:13.2f} {np_per_s / jax_per_s:9.0f} {diff:13.2e}", flush=True)


if __name__ == "__main__":
    main()
