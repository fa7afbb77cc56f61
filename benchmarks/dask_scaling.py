"""An ensemble on local Dask worker processes against one process: parallel efficiency.

    python benchmarks/dask_scaling.py [--n-paths 1000000] [--dt 0.1] [--workers 2] [--repeat 3]

The public set (OU friction noise, exact stepping, exact stick detection) with `--n-paths`
paths at step `--dt`: once in this process (`simulate` without a client: the fair baseline,
same code, same compiled executables), then on a `LocalCluster` of 1 and of `--workers`
single-threaded worker processes. Every side runs once untimed first (the workers compile or
load their code), then `--repeat` times; the median is reported. Efficiency is
T(1 process) / (workers x T(cluster)); the results are checked to be identical.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def timed(fn, repeat):
    fn()  # warm-up: compile or load from the disk cache
    times, result = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, default=1_000_000)
    parser.add_argument("--dt", type=float, default=0.1)
    parser.add_argument("--t-max", type=float, default=30.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)

    import distributed

    import stickslip as ss

    model = ss.get_model("langevin")(**PUBLIC)
    run = lambda client=None: ss.simulate(
        model, args.n_paths, args.dt, args.t_max, seed=0, progress=False, client=client
    )
    print(f"{args.n_paths} paths, public set, dt = {args.dt}, t_max = {args.t_max}")
    t_local, min_local, local = timed(run, args.repeat)
    print(f"one process (no client):      median {t_local:7.2f} s  (min {min_local:.2f})")
    rows = [("local", 1, t_local)]
    for n in sorted({1, args.workers}):
        with (
            distributed.LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            t, tmin, ens = timed(lambda c=client: run(c), args.repeat)
        same = all(
            np.array_equal(getattr(local, k), getattr(ens, k), equal_nan=True)
            for k in ("slip_time", "slip_distance", "stick_time", "period")
        )
        eff = t_local / (n * t)
        print(
            f"LocalCluster, {n} worker process(es): median {t:7.2f} s  (min {tmin:.2f}), "
            f"{ens.stats['tasks']} tasks, speed-up {t_local / t:.2f}x, efficiency {eff:.2f}, "
            f"identical: {same}"
        )
        rows.append((f"{n} workers", n, t))
    return rows


if __name__ == "__main__":
    main()
