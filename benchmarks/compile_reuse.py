"""Compiled-code reuse in one process: 20 step sizes, memory and the compile counter.

    python benchmarks/compile_reuse.py [--n-paths 1000] [--model langevin] [--tau 0.1]

Simulates the public set (OU friction noise: the exact detector) at 20 step sizes from 0.01
to 1.6 in one process and prints, after each, the wall time, the compile seconds of the run,
`stickslip.cache_info()` (traces, compilations, loads from disk) and the resident memory.
The first step size compiles (or loads from the disk cache); the others should neither trace
nor compile. `--tau 0` runs white friction noise instead (the Brownian-bridge locator, whose
interpolation nodes follow dt in powers of two: one small compilation per node count).
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np


def rss_mb() -> float:
    try:
        import os

        pages = int(pathlib.Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except (OSError, ValueError, IndexError):
        return float("nan")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, default=1000)
    parser.add_argument("--tau", type=float, default=0.1)
    parser.add_argument("--t-max", type=float, default=50.0)
    args = parser.parse_args(argv)

    import stickslip as ss

    params = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
    if args.tau > 0:
        params["tau"] = args.tau
    model = ss.get_model("langevin")(**params)
    dts = np.geomspace(0.01, 1.6, 20)
    print(f"{args.n_paths} paths, {len(dts)} step sizes; tau = {args.tau}")
    print(f"{'dt':>7s} {'wall s':>7s} {'compile s':>9s} {'traces':>6s} {'compiles':>8s} "
          f"{'loaded':>6s} {'RSS MB':>7s}")  # fmt: skip
    rss0 = None
    for dt in dts:
        t0 = time.perf_counter()
        ens = ss.simulate(model, args.n_paths, float(dt), args.t_max, seed=1, progress=False)
        wall = time.perf_counter() - t0
        info = ss.cache_info()
        rss = rss_mb()
        rss0 = rss if rss0 is None else rss0
        print(
            f"{dt:7.4f} {wall:7.3f} {ens.stats['compile_seconds']:9.3f} {info['traces']:6d} "
            f"{info['compiles']:8d} {info['exported_loaded'] + info['executables_loaded']:6d} "
            f"{rss:7.0f}"
        )
    print(f"memory growth after the first step size: {rss - rss0:.0f} MB")


if __name__ == "__main__":
    main()
