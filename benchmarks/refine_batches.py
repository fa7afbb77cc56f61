"""Refinement batches of equal size against batches of `BATCH` and a remainder, same process.

    python benchmarks/refine_batches.py [--repeats 12] [--n-paths 100000] [--dt 0.8]

One run of the public reference set (exact stepping) records every call of the exact
refinement (`bridge.Refiner.first_crossing`: the candidate steps of each stepping buffer);
the recorded calls are then replayed, alternating the two ways of cutting a thread's
candidates into batches (`bridge._batch_cuts`, stickslip's, and the former cut: batches of
`BATCH` and a remainder) `--repeats` times, so that a drift of the machine's speed falls on
both. Both are compiled and warmed before timing. Prints the minimum and median of the
replay of all calls and of the first call alone (every path's onset step), and checks that
both give the same refinements to the last bit (the per-candidate miss bounds to
rounding).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def remainder_cuts(lo: int, hi: int, batch: int):
    """The former batches: `batch` candidates each, and the remainder."""
    return np.r_[np.arange(lo, hi, batch), hi]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=12)
    parser.add_argument("--n-paths", type=int, default=100_000)
    parser.add_argument("--dt", type=float, default=0.8)
    args = parser.parse_args(argv)

    import stickslip as ss
    from stickslip._simulate import bridge

    model = ss.get_model("langevin")(**PUBLIC)
    calls = []
    first_crossing = bridge.Refiner.first_crossing

    def record(self, *a):
        calls.append((self, [np.array(x) for x in a]))
        return first_crossing(self, *a)

    bridge.Refiner.first_crossing = record
    try:
        ss.simulate(model, args.n_paths, args.dt, 100.0, seed=1, solver="exact", progress=False)
    finally:
        bridge.Refiner.first_crossing = first_crossing
    equal = bridge._batch_cuts
    ways = {"equal batches": equal, "BATCH + remainder": remainder_cuts}

    def replay(cuts, upto=None):
        bridge._batch_cuts = cuts
        try:
            start = time.perf_counter()
            out = [first_crossing(r, *a) for r, a in calls[:upto]]
            return time.perf_counter() - start, out
        finally:
            bridge._batch_cuts = equal

    for cuts in ways.values():  # compile (new buffer sizes) and warm both
        replay(cuts)
    times = {name: ([], []) for name in ways}
    results = {}
    for _ in range(args.repeats):
        for name, cuts in ways.items():
            seconds, out = replay(cuts)
            times[name][0].append(seconds)
            times[name][1].append(replay(cuts, upto=1)[0])
            results[name] = out
    # Sticks, states, counts to the last bit; the per-candidate miss bounds to rounding (the
    # order of a scatter-add's sums can follow the buffer's size).
    same = all(
        all(np.array_equal(x, y) for x, y in zip(a[:3] + a[4:], b[:3] + b[4:], strict=True))
        and np.allclose(a[3], b[3], rtol=1e-12, atol=0)
        for a, b in zip(*results.values(), strict=True)
    )
    n_cand = sum(a[0].shape[1] for _, a in calls)
    print(
        f"public set, exact stepping, dt = {args.dt}, {args.n_paths} paths: {len(calls)} "
        f"refinement calls, {n_cand} candidates (first call {calls[0][1][0].shape[1]})"
    )
    for name, (every, first) in times.items():
        print(
            f"  {name:18s} all calls: min {min(every) * 1e3:6.1f} ms, median "
            f"{np.median(every) * 1e3:6.1f} ms | first call: min {min(first) * 1e3:5.1f} ms, "
            f"median {np.median(first) * 1e3:5.1f} ms"
        )
    (a, fa), (b, fb) = times.values()
    print(
        f"  ratio (remainder / equal, min): all calls {min(b) / min(a):.2f}x, first call "
        f"{min(fb) / min(fa):.2f}x; same refinements to the last bit: {same}"
    )
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
