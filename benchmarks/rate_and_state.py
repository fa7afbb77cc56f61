"""Cycles per second of the `rate-and-state` plugin against SciPy's `solve_ivp` (Radau with
events, one cycle per call), at equal accuracy, in one process; and the cost of noisy
cycles.

    python benchmarks/rate_and_state.py            # the paper-like slider, k 168 N/m, 42 um/s
    python benchmarks/rate_and_state.py --quick    # fewer paths

Noise-free: `simulate_cycles` runs `--paths` paths of the slider (identical without noise:
the work is that of as many different slider runs) for `--cycles` cycles each; the baseline
integrates the same equations in SI variables, one path at a time, with Radau and events at
v = V (the force's peaks and troughs). Both are warmed (a first run compiles, or imports)
and timed on the cycles after the first. Accuracy: the slip and stick times and the drops
of each against a Radau reference at rtol 1e-11; the baseline's tolerance is chosen so that
its error is no smaller than ours (equal accuracy or better for the baseline).

Noisy: Ornstein-Uhlenbeck friction noise (tau 2 ms, grid tau / 10, the noise's sd 0.3 N a),
cycles per second of `simulate_cycles` over `--paths` paths, and what 10^5 cycles cost at
that rate.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

import stickslip as ss

P = dict(mass=0.0307, normal_force=0.301, mu0=0.3, a=0.01, b=0.015, d_c=1e-6, v_ref=1e-6)
K, V = 168.0, 42e-6


def _mu(v, theta):
    psi = (P["mu0"] + P["b"] * math.log(P["v_ref"] * theta / P["d_c"])) / P["a"]
    return P["a"] * math.asinh(v / (2 * P["v_ref"]) * math.exp(psi))


def _rhs(t, y):
    e, v, theta = y
    return [V - v, (K * e - P["normal_force"] * _mu(v, theta)) / P["mass"],
            1.0 - v * theta / P["d_c"]]  # fmt: skip


def _start(v):
    theta = P["d_c"] / v
    return [P["normal_force"] * _mu(v, theta) / K, v, theta]


def radau_cycles(t_end, rtol):
    """(slip times, stick times, drops) of the cycles from steady sliding at 1.5 V."""
    up = lambda t, y: y[1] - V  # noqa: E731
    up.direction = 1.0
    down = lambda t, y: y[1] - V  # noqa: E731
    down.direction = -1.0
    sol = solve_ivp(_rhs, (0.0, t_end), _start(1.5 * V), method="Radau", rtol=rtol,
                    atol=[1e-16, 1e-15, 1e-14], events=[up, down], dense_output=True)  # fmt: skip
    peaks, troughs = np.r_[0.0, sol.t_events[0]], sol.t_events[1]
    n = min(peaks.size - 1, troughs.size)
    slip = troughs[:n] - peaks[:n]
    stick = peaks[1 : n + 1] - troughs[:n]
    drop = K * (sol.sol(peaks[:n])[0] - sol.sol(troughs[:n])[0])
    return slip, stick, drop


def errors(got, ref, n):
    return max(float(np.max(np.abs(g[1:n] / r[1:n] - 1))) for g, r in zip(got, ref, strict=True))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=256)
    parser.add_argument("--cycles", type=int, default=6)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--noisy-periods", type=float, default=2.5,
                        help="how long the noisy runs are, in noise-free periods")  # fmt: skip
    args = parser.parse_args(argv)
    paths = 32 if args.quick else args.paths
    m = ss.get_model("rate-and-state")(stiffness=K, v_b=V, **P)
    period = 6.3  # (about: the noise-free limit cycle's, s)
    t_end = (args.cycles + 0.5) * period

    ref = radau_cycles(t_end, 1e-11)
    n = ref[0].size
    # Ours, warmed, then timed.
    ss.simulate_cycles(m, paths, 1e-3, t_end, seed=0, record=False)
    t0 = time.perf_counter()
    c = ss.simulate_cycles(m, paths, 1e-3, t_end, seed=1, record=False).cycles
    ours_s = time.perf_counter() - t0
    rows = c["path"] == 0
    got = (c["slip_time"][rows], c["stick_time"][rows], c["force_drop"][rows])
    k = min(n, int(np.sum(np.isfinite(got[1]))))
    ours_err = errors(got, ref, k)
    ours_cycles = int(np.sum(np.isfinite(c["period"])))
    # The baseline: the loosest tolerance whose error is no larger than ours.
    base = None
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        radau_cycles(t_end, rtol)  # (warm: imports, caches)
        t0 = time.perf_counter()
        got_b = radau_cycles(t_end, rtol)
        secs = time.perf_counter() - t0
        err = errors(got_b, ref, min(k, got_b[0].size))
        print(f"  Radau rtol {rtol:g}: {secs:.2f} s for {got_b[0].size} cycles, error {err:.2e}")
        if err <= ours_err:
            base = (rtol, secs, got_b[0].size, err)
            break
    ours_rate = ours_cycles / ours_s
    print(f"noise-free, {paths} paths x {args.cycles} cycles: {ours_rate:.1f} cycles/s "
          f"({ours_s:.2f} s; largest relative error {ours_err:.2e}, Radau at 1e-11)")  # fmt: skip
    if base is not None:
        rtol, secs, cycles, err = base
        rate = cycles / secs
        print(f"solve_ivp Radau + events at rtol {rtol:g} (error {err:.2e}): {rate:.2f} cycles/s;"
              f" ratio {ours_rate / rate:.1f}x")  # fmt: skip

    # Noisy cycles.
    tau = 2e-3
    D = (0.3 * P["normal_force"] * P["a"] / P["mass"]) ** 2 * tau
    noisy = ss.get_model("rate-and-state")(stiffness=K, v_b=V, D=D, tau=tau, **P)
    n_noisy = max(4, paths // 32)
    t_noisy = args.noisy_periods * period
    ss.simulate_cycles(noisy, n_noisy, tau / 10, 0.5, seed=0, record=False)  # (warm)
    t0 = time.perf_counter()
    cn = ss.simulate_cycles(noisy, n_noisy, tau / 10, t_noisy, seed=2, record=False)
    secs = time.perf_counter() - t0
    done = int(np.sum(np.isfinite(cn.cycles["period"])))
    rate = done / secs
    print(f"noisy (tau {tau:g} s, grid tau/10), {n_noisy} paths to {t_noisy:.1f} s: {done} "
          f"cycles in {secs:.1f} s = {rate:.2f} cycles/s; 10^5 cycles: {1e5 / rate / 3600:.1f} h "
          f"({cn.stats['steps'] / max(done, 1):.0f} implicit steps a cycle)")  # fmt: skip
    # The baseline with the same noise: path 0's white noise at the grid's nodes, linearly
    # interpolated, as a known forcing of the same equations in SI variables, by Radau with
    # events at the plugin's tolerance (1e-6); its cycles against the plugin's path 0.
    from stickslip._jax import jax, jnp
    from stickslip._simulate.creep import Motion, _node

    h = tau / 10
    key = Motion(noisy, h, t_noisy, 2).keys(np.zeros(1, np.uint32))[0]
    nodes = np.asarray(jax.vmap(lambda j: _node(key, j, 1)[0])(jnp.arange(int(t_noisy / h) + 2)))
    grid = h * np.arange(nodes.size)
    g = math.sqrt(2 * D) / tau

    def rhs(t, y):
        e, v, theta, eta = y
        xi = np.interp(t, grid, nodes) / math.sqrt(h)
        dv = (K * e - P["normal_force"] * _mu(v, theta)) / P["mass"] + eta
        return [V - v, dv, 1.0 - v * theta / P["d_c"], -eta / tau + g * xi]

    up = lambda t, y: y[1] - V  # noqa: E731
    up.direction = 1.0
    down = lambda t, y: y[1] - V  # noqa: E731
    down.direction = -1.0
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_noisy), [*_start(1.5 * V), 0.0], method="Radau", rtol=1e-6,
                    atol=[1e-14, 1e-13, 1e-12, 1e-6], events=[up, down], max_step=h)  # fmt: skip
    secs_b = time.perf_counter() - t0
    peaks = np.r_[0.0, sol.t_events[0]]
    n_b = min(peaks.size - 1, sol.t_events[1].size)
    ours0 = cn.cycles["release_time"][cn.cycles["path"] == 0]
    m = min(ours0.size, peaks.size)
    print(f"solve_ivp Radau, same noise (path 0), rtol 1e-6, steps <= the grid: {n_b} cycles in "
          f"{secs_b:.1f} s = {n_b / secs_b:.3f} cycles/s; ratio {rate / (n_b / secs_b):.1f}x; "
          f"the first {m} slip starts differ by at most "
          f"{np.max(np.abs(ours0[:m] - peaks[:m])):.2e} s")  # fmt: skip


if __name__ == "__main__":
    main()
