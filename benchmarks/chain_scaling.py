"""Cost of the Burridge-Knopoff chain simulator against the number of blocks and of paths.

    python benchmarks/chain_scaling.py [--quick]

Cost per simulated time unit (wall seconds per time unit of one path) for N = 16 ... 1024
blocks (one path) and for 1 ... 64 paths (N = 64), with compilation excluded (each
configuration runs once to compile, then is timed). The baseline, run in the same process,
is a vectorised NumPy loop of the same step (Heun's method with exact OU noise, sticks and
releases inside the step; no event bookkeeping), run after a warm-up like the simulator:
the ratios say how much faster the JAX/diffrax simulator is. The log-log slope of cost
against N says how it scales; cost per block-step is printed too.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def numpy_chain(model, t_max, dt, n_paths, seed):
    """The chain step in NumPy (free ends, any law with `force`): Heun's method in (u, V)
    with exact OU noise, sticks and releases located inside the step, as the simulator;
    no event bookkeeping."""
    rng = np.random.default_rng(seed)
    N, kc, kp, vb = model.n_blocks, model.k_c, model.k_p, model.v_b
    D, tau = model.D, model.tau
    Fs = float(model.friction.static_limit)
    law = model.friction
    F = lambda V: np.asarray(law.force(np.maximum(V, 0.0)))
    F0 = float(law.force(0.0))
    u = np.zeros((n_paths, N))
    V = np.zeros((n_paths, N))
    eta = np.zeros((n_paths, N))
    stuck = np.ones((n_paths, N), bool)
    a = np.exp(-dt / tau)
    sd = np.sqrt(D / tau * (1 - a * a))

    def force(u, t):
        pad = np.concatenate([u[:, :1], u, u[:, -1:]], axis=1)
        return kc * (pad[:, 2:] + pad[:, :-2] - 2 * u) + kp * (vb * t - u)

    for k in range(int(round(t_max / dt))):
        t0, t1 = k * dt, (k + 1) * dt
        slipping = ~stuck
        f0 = force(u, t0)
        eta1 = eta * a + sd * rng.standard_normal((n_paths, N))
        a0 = f0 - F(V) + eta
        Vp = V + a0 * dt
        up = np.where(slipping, u + V * dt, u)
        V1 = V + 0.5 * (a0 + force(up, t1) - F(Vp) + eta1) * dt
        sticks = slipping & (V1 <= 0)
        theta = np.where(sticks, V / np.where(sticks, V - V1, 1.0), 1.0)
        u1 = np.where(slipping, u + np.where(sticks, 0.5 * theta * V, 0.5 * (V + Vp)) * dt, u)
        V1 = np.where(slipping & ~sticks, V1, 0.0)
        f1 = force(u1, t1)
        release = stuck & (f1 > Fs)
        rho = np.clip(np.where(release, (Fs - f0) / np.where(release, f1 - f0, 1.0), 0.0), 0, 1)
        rest = (1 - rho) * dt
        V_rel = (f1 - F0) * rest
        u = np.where(release, u + 0.5 * V_rel * rest, u1)
        V = np.where(release, V_rel, V1)
        eta = np.where(release, 0.0, eta1)
        stuck = (stuck & ~release) | sticks
    return u


def timed(fn, repeat=1):
    best = np.inf
    for _ in range(repeat):
        w = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - w)
    return best


def main(argv=None):
    import stickslip as ss

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    args = parser.parse_args(argv)
    BK = ss.get_model("burridge-knopoff")
    dt = 0.02
    T = 200.0 if args.quick else 1000.0

    def model(n):
        return BK(n, 10.0, 1.0, 0.01, "velocity-weakening",
                  {"F0": 1.0, "alpha": 2.5, "sigma": 0.01}, D=1e-4, tau=0.1)  # fmt: skip

    print(f"dt = {dt}, {T:g} time units per run; cost = wall seconds per time unit per path")
    head = ("N", 6), ("paths", 6), ("stickslip", 12), ("numpy", 12), ("ratio", 7)
    print(" ".join(f"{name:>{width}}" for name, width in head), f"{'ns/block-step':>14}")
    rows = []
    for n, p in [(16, 1), (64, 1), (256, 1), (1024, 1), (64, 4), (64, 16), (64, 64)]:
        m = model(n)
        ss.simulate_chain(m, p, dt, T, seed=0)  # compile
        c = timed(lambda m=m, p=p: ss.simulate_chain(m, p, dt, T, seed=0)) / (T * p)
        Tn = T / 5
        numpy_chain(m, Tn / 10, dt, p, 1)  # warm-up, as the simulator's compile run
        b = timed(lambda m=m, p=p, Tn=Tn: numpy_chain(m, Tn, dt, p, 0)) / (Tn * p)
        rows.append((n, p, c, b))
        per = c * dt / n * 1e9
        print(f"{n:>6} {p:>6} {c:>12.3e} {b:>12.3e} {b / c:>7.1f} {per:>14.1f}")
    single = [(n, c) for n, p, c, _ in rows if p == 1]
    slope = np.polyfit(np.log([n for n, _ in single]), np.log([c for _, c in single]), 1)[0]
    tail = np.polyfit(np.log([n for n, _ in single[1:]]), np.log([c for _, c in single[1:]]), 1)[0]
    print(f"cost ~ N^{slope:.2f} over N = 16..1024 (N^{tail:.2f} over 64..1024)")
    return rows, slope


if __name__ == "__main__":
    main()
