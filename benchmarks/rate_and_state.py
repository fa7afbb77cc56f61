"""Cycles per second of the `rate-and-state` plugin against SciPy's `solve_ivp` (Radau with
events), at equal accuracy, in one process: noise-free, and with friction noise.

    python benchmarks/rate_and_state.py            # the paper-like slider, k 168 N/m, 42 um/s
    python benchmarks/rate_and_state.py --quick    # fewer paths
    python benchmarks/rate_and_state.py --before TREE [--runs 3]   # noisy, against a tree

Noise-free: `simulate_cycles` runs `--paths` paths of the slider (identical without noise:
the work is that of as many different slider runs) for `--cycles` cycles each; the baseline
integrates the same equations in SI variables, one path at a time, with Radau and events at
v = V (the force's peaks and troughs). Both are warmed (a first run compiles, or imports)
and timed on the cycles after the first. Accuracy: the slip and stick times and the drops
of each against a Radau reference at rtol 1e-11; the baseline's tolerance is chosen so that
its error is no smaller than ours (equal accuracy or better for the baseline).

Noisy (`--skip-noisy` leaves it out): Ornstein-Uhlenbeck friction noise (tau 2 ms, grid
tau / 10, the noise's sd 0.3 N a) on the stiffer k = 1002 N/m (sticks of ~0.6 s), cycles
per second of `simulate_cycles` over `--noisy-paths` paths for `--noisy-time` s from the
velocity step; the baseline integrates path 0 in SI variables driven by the same noise (the
plugin's normals at the grid's nodes, linear between them), Radau with events, steps no
longer than the grid's. Accuracy: stick times and drops of the slips above 1 mN against
Radau at rtol 1e-8, the baseline at the loosest tolerance whose error is no larger than
ours.

`--before TREE`: the noisy slider alone (k = 1002 N/m, 8 paths for 2 s), each run a whole
process that warms (0.3 s) and then times `simulate_cycles`, with another checkout's `src`
first on the path (say the tree before a change: `git worktree add /tmp/before HEAD~1`),
alternating with this one's; the cycles' counts and medians of each.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
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
    parser.add_argument("--noisy-paths", type=int, default=64)
    parser.add_argument("--noisy-time", type=float, default=4.0,
                        help="how long the noisy runs are (s)")  # fmt: skip
    parser.add_argument("--skip-noisy", action="store_true")
    parser.add_argument("--before", help="the noisy slider against another checkout only")
    parser.add_argument("--runs", type=int, default=3, help="with --before")
    args = parser.parse_args(argv)
    if args.before:
        before(args.before, args.runs)
        return
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

    if not args.skip_noisy:
        noisy(args)


# The noisy comparison: a stiffer spring than the noise-free one (k = 1002 N/m, sticks of
# ~0.6 s), so that the SI Radau baseline with steps no longer than the noise's grid runs a
# few cycles in minutes. Drops and stick times of the slips above 1 mN (the noise's
# micro-slips near the peaks left out), path by path against Radau at rtol 1e-8.
K_NOISY, TAU = 1002.0, 2e-3
BIG = 1e-3  # N


def _noise_of(model, h, t_end, paths):
    """Each path's white noise at the grid's nodes (the plugin's own draws)."""
    from stickslip._jax import jax, jnp
    from stickslip._simulate.creep import Motion
    from stickslip._simulate.rosenbrock import node

    keys = Motion(model, h, t_end, 5).keys(np.arange(paths, dtype=np.uint32))
    j = jnp.arange(int(t_end / h) + 2)
    return [np.asarray(jax.vmap(lambda i, key=key: node(key, i, 1)[0])(j)) for key in keys]


def radau_noisy(z, h, t_end, D, rtol):
    """(stick times, drops) of the slips above `BIG` of one path driven by the normals `z`
    (linear between nodes), SI variables, Radau with events at v = V, steps <= h; its
    seconds."""
    grid = h * np.arange(z.size)
    g = math.sqrt(2 * D) / TAU

    def rhs(t, y):
        e, v, theta, eta = y
        xi = np.interp(t, grid, z) / math.sqrt(h)
        dv = (K_NOISY * e - P["normal_force"] * _mu(v, theta)) / P["mass"] + eta
        return [V - v, dv, 1.0 - v * theta / P["d_c"], -eta / TAU + g * xi]

    up = lambda t, y: y[1] - V  # noqa: E731
    up.direction = 1.0
    down = lambda t, y: y[1] - V  # noqa: E731
    down.direction = -1.0
    theta0 = P["d_c"] / (1.5 * V)
    y0 = [P["normal_force"] * _mu(1.5 * V, theta0) / K_NOISY, 1.5 * V, theta0, 0.0]
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="Radau", rtol=rtol, max_step=h,
                    atol=[1e-15, 1e-14, 1e-13, 1e-8], events=[up, down])  # fmt: skip
    secs = time.perf_counter() - t0
    starts, e_starts = np.r_[0.0, sol.t_events[0]], np.r_[y0[0], sol.y_events[0][:, 0]]
    troughs, e_troughs = sol.t_events[1], sol.y_events[1][:, 0]
    n = min(troughs.size, starts.size - 1)
    drops = K_NOISY * (e_starts[:n] - e_troughs[:n])
    sticks = starts[1 : n + 1] - troughs[:n]
    big = (drops > BIG) & np.isfinite(sticks)
    return sticks[big], drops[big], secs, n


def _error(a, b):
    n = min(a[0].size, b[0].size)
    return max(float(np.max(np.abs(x[:n] / y[:n] - 1))) for x, y in zip(a, b, strict=True))


def noisy(args):
    """Cycles a second of the noisy slider (`--noisy-paths` paths) against SciPy Radau
    driven by the same noise (path 0), at equal accuracy: the loosest Radau tolerance
    whose error (against Radau at 1e-8) is no larger than ours."""
    h, t_end = TAU / 10, args.noisy_time
    D = (0.3 * P["normal_force"] * P["a"] / P["mass"]) ** 2 * TAU
    model = ss.get_model("rate-and-state")(stiffness=K_NOISY, v_b=V, D=D, tau=TAU, **P)
    n = args.noisy_paths
    ss.simulate_cycles(model, n, h, 0.5, seed=0, record=False)  # (warm)
    t0 = time.perf_counter()
    run = ss.simulate_cycles(model, n, h, t_end, seed=5, record=False)
    secs = time.perf_counter() - t0
    c = run.cycles
    done = np.isfinite(c["stick_time"])
    big = done & (c["force_drop"] > BIG)
    rate, rate_big = int(done.sum()) / secs, int(big.sum()) / secs
    print(f"noisy (k {K_NOISY:g} N/m, tau {TAU:g} s, grid tau/10), {n} paths to {t_end:g} s: "
          f"{int(done.sum())} cycles ({int(big.sum())} with drops above {BIG * 1e3:g} mN) in "
          f"{secs:.1f} s = {rate:.1f} cycles/s ({rate_big:.1f} above {BIG * 1e3:g} mN); "
          f"{run.stats['steps'] / max(int(done.sum()), 1):.0f} steps a cycle")  # fmt: skip
    z = _noise_of(model, h, t_end, 1)[0]
    ref = radau_noisy(z, h, t_end, D, 1e-8)
    rows = (c["path"] == 0) & big
    ours = (c["stick_time"][rows], c["force_drop"][rows])
    ours_err = _error(ours, ref[:2])
    print(f"  ours against Radau 1e-8 (path 0, {ours[0].size} slips): largest relative error "
          f"{ours_err:.2e}")  # fmt: skip
    for rtol in (1e-4, 1e-5, 1e-6, 1e-7):
        got = radau_noisy(z, h, t_end, D, rtol)
        err = _error(got[:2], ref[:2])
        print(f"  Radau rtol {rtol:g}: {got[3]} cycles in {got[2]:.1f} s, error {err:.2e}")
        if err <= ours_err:
            base = got[3] / got[2]
            print(f"Radau, same noise, rtol {rtol:g} (error {err:.2e} <= ours): {base:.3f} "
                  f"cycles/s; ratio {rate / base:.0f}x")  # fmt: skip
            return
    print("no Radau tolerance tried was as accurate as ours")


# One process of `--before`: the noisy slider's cycles, warmed, then timed.
NOISY_RUN = """
import json, time
import numpy as np
import stickslip as ss
P = dict(mass=0.0307, normal_force=0.301, mu0=0.3, a=0.01, b=0.015, d_c=1e-6, v_ref=1e-6)
tau = 2e-3
D = (0.3 * P["normal_force"] * P["a"] / P["mass"]) ** 2 * tau
m = ss.get_model("rate-and-state")(stiffness=1002.0, v_b=42e-6, D=D, tau=tau, **P)
ss.simulate_cycles(m, 8, tau / 10, 0.3, seed=0, record=False)
t0 = time.perf_counter()
c = ss.simulate_cycles(m, 8, tau / 10, 2.0, seed=5, record=False).cycles
secs = time.perf_counter() - t0
done = np.isfinite(c["stick_time"])
big = done & (c["force_drop"] > 1e-3)
print(json.dumps(dict(seconds=secs, cycles=int(done.sum()), big=int(big.sum()),
                      drop=float(np.median(c["force_drop"][big])),
                      stick=float(np.median(c["stick_time"][big])))))
"""


def before(tree, runs):
    """`--before`: this tree's noisy runs against `tree`'s, alternating (whole processes)."""
    got = {"this tree": [], "before": []}
    for _ in range(runs):
        for label, src in (("this tree", None), ("before", os.path.join(tree, "src"))):
            env = dict(os.environ)
            if src is not None:
                rest = [p for p in [env.get("PYTHONPATH")] if p]
                env["PYTHONPATH"] = os.pathsep.join([src, *rest])
            out = subprocess.run([sys.executable, "-c", NOISY_RUN], env=env, check=True,
                                 capture_output=True, text=True)  # fmt: skip
            got[label].append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(f"noisy slider, k {K_NOISY:g} N/m, 8 paths for 2 s, {runs} runs each (seconds)")
    for label, rows in got.items():
        secs = sorted(r["seconds"] for r in rows)
        r = rows[0]
        print(f"  {label:9s} median {secs[len(secs) // 2]:6.1f} (min {secs[0]:.1f}, max "
              f"{secs[-1]:.1f}); {r['cycles']} cycles, {r['big']} above 1 mN, median drop "
              f"{r['drop']:.6g} N, stick {r['stick']:.6g} s")  # fmt: skip
    a = sorted(r["seconds"] for r in got["this tree"])
    b = sorted(r["seconds"] for r in got["before"])
    print(f"  ratio of the medians: {b[len(b) // 2] / a[len(a) // 2]:.1f}x")


if __name__ == "__main__":
    main()
