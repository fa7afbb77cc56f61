"""Stepping past candidate steps in small buffers against refining each before going on.

    python benchmarks/speculate.py [--repeats 12] [--n-paths 10000 100000] [--dt 0.8]

Exact stepping of the public reference set. In buffers of `host.SPECULATE_BELOW` paths
or fewer the simulator steps on past a candidate step that ends below the stick level (as
if refuted) and refines all such candidates at the end, each path's in step order
(`host.HostRun._chunk`): inside the stepping loop, up to `host.PAST_SLOTS` candidates per
path and call (`hybrid.SteppingPastHybrid`), and by the host between calls for the rest.
Three ways: the baseline refines every candidate before stepping on (`SPECULATE_BELOW =
0`); "host" steps past between calls only (`PAST_SLOTS = 0`, the scheme before
2026-11-26's second change); "loop" is the default. All run in the same process, compiled
and warmed alike, alternated `--repeats` times with the same seeds, so that a drift of the
machine's speed falls on all. Prints the minimum and median wall time of each, the ratios
to the baseline, the stepping calls, and whether all give the same slip times, slip
distances and stick states to the last bit (they must: every draw is keyed by path, step
and tree node).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=12)
    parser.add_argument("--n-paths", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--dt", type=float, default=0.8)
    args = parser.parse_args(argv)

    import stickslip as ss
    from stickslip._simulate import host
    from stickslip.selection import calibration_seconds

    model = ss.get_model("langevin")(**PUBLIC)
    default = (host.SPECULATE_BELOW, host.PAST_SLOTS)
    ways = {
        "refine each first": (0, default[1]),
        f"step past, host (<= {default[0]})": (default[0], 0),
        f"step past, loop ({default[1]} slots)": default,
    }

    def run(n, way, seed):
        host.SPECULATE_BELOW, host.PAST_SLOTS = way
        try:
            start = time.perf_counter()
            ens = ss.simulate(model, n, args.dt, 100.0, seed=seed, solver="exact", progress=False)
            return time.perf_counter() - start, ens
        finally:
            host.SPECULATE_BELOW, host.PAST_SLOTS = default

    print(f"public set, exact stepping, dt = {args.dt}, calibration "
          f"{calibration_seconds() * 1e3:.1f} ms")  # fmt: skip
    same = True
    for n in args.n_paths:
        for way in ways.values():  # compile and warm all
            run(n, way, seed=99)
        times = {name: [] for name in ways}
        calls = {}
        for rep in range(args.repeats):
            out = []
            for name, way in ways.items():
                seconds, ens = run(n, way, seed=rep + 1)
                times[name].append(seconds)
                calls[name] = ens.stats["buffers"]
                out.append(ens)
            same &= all(
                np.array_equal(getattr(out[0], f), getattr(b, f), equal_nan=True)
                for b in out[1:]
                for f in ("slip_time", "slip_distance", "stick_state")
            )
        print(f"  {n} paths:")
        base = times["refine each first"]
        for name, t in times.items():
            print(f"    {name:26s} min {min(t) * 1e3:6.1f} ms, median {np.median(t) * 1e3:6.1f} ms"
                  f" ({min(base) / min(t):.2f}x, {np.median(base) / np.median(t):.2f}x),"
                  f" {calls[name]} stepping calls")  # fmt: skip
    print(f"  same sticks to the last bit: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
