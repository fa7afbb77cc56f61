"""Simulator throughput against NumPy baselines run in the same process.

    python benchmarks/throughput.py [--n-paths 100000] [--dt 0.005] [--json out.json]

First passages of the public reference set (Langevin, OU noise). The simulator runs once to
compile (its compile time is reported apart) and is then timed; the baselines are
(a) a vectorised NumPy Euler-Maruyama loop over all paths and (b) a vectorised NumPy exact
stepping loop that drops finished paths, with the same model, dt and number of paths.
Ratios are baseline time / simulator time (> 1: the simulator is faster).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import _baselines  # noqa: E402

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def _timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, default=100_000)
    parser.add_argument("--dt", type=float, default=0.005)
    parser.add_argument("--t-max", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=pathlib.Path, help="also write the results here")
    args = parser.parse_args(argv)

    import stickslip as ss

    model = ss.get_model("langevin")(**PUBLIC)
    n, dt, t_max = args.n_paths, args.dt, args.t_max
    rows = []

    def ours(label, **kw):
        first, t_first = _timed(lambda: ss.simulate(model, n, dt, t_max, seed=args.seed, **kw))
        ens, t = _timed(lambda: ss.simulate(model, n, dt, t_max, seed=args.seed, **kw))
        rows.append(
            dict(
                method=label,
                seconds=t,
                compile_seconds=first.stats["compile_seconds"],
                path_steps=ens.stats["path_steps"],
                mean_slip_time=float(np.nanmean(ens.slip_time)),
            )
        )
        return t

    def baseline(label, fn):
        (T, steps), t = _timed(lambda: fn(n, dt, t_max, args.seed, **PUBLIC))
        rows.append(
            dict(method=label, seconds=t, compile_seconds=0.0, path_steps=steps,
                 mean_slip_time=float(np.nanmean(T)))
        )  # fmt: skip
        return t

    t_exact_cont = ours("stickslip exact, continuous monitoring (default)")
    t_exact_grid = ours("stickslip exact, grid monitoring", monitor="grid")
    t_euler_grid = ours("stickslip Euler-Maruyama, grid monitoring", solver="euler", monitor="grid")
    t_np_exact = baseline("NumPy exact stepping, drops finished paths", _baselines.exact_dropping)
    t_np_euler = baseline("NumPy Euler-Maruyama, all paths", _baselines.euler_all)

    ratios = {
        "numpy_exact_dropping / stickslip_exact_continuous": t_np_exact / t_exact_cont,
        "numpy_exact_dropping / stickslip_exact_grid": t_np_exact / t_exact_grid,
        "numpy_euler_all / stickslip_euler_grid": t_np_euler / t_euler_grid,
        "numpy_euler_all / stickslip_exact_continuous": t_np_euler / t_exact_cont,
    }
    print(f"{n} first passages, public reference set, dt = {dt}, t_max = {t_max}")
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; python {platform.python_version()}"
    )
    print(
        f"{'method':52s} {'run s':>8s} {'compile s':>10s} {'path-steps/s':>13s} {'mean T_sl':>10s}"
    )
    for r in rows:
        rate = r["path_steps"] / r["seconds"]
        print(
            f"{r['method']:52s} {r['seconds']:8.2f} {r['compile_seconds']:10.2f} "
            f"{rate:13.3g} {r['mean_slip_time']:10.4f}"
        )
    print("ratios (baseline time / stickslip time, same process):")
    for k, v in ratios.items():
        print(f"  {k:52s} {v:6.2f}x")
    if args.json:
        args.json.write_text(
            json.dumps(dict(n_paths=n, dt=dt, t_max=t_max, rows=rows, ratios=ratios), indent=2)
        )
    return rows, ratios


if __name__ == "__main__":
    main()
