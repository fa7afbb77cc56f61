"""Time of `fit` with intervals and p-values (the speed bar: a two-parameter fit of
3000 cycles in <= 60 s on 2 cores).

    python benchmarks/fit_speed.py [--n 3000] [--n-rep 100 200 400] [--json out.json]

3000 slip times of the Langevin model (truth D = 0.4, tau = 0.1, data seed 12345), D and
tau free, default `n_sim` (1e5): first `fit(..., check=False)` (estimate and intervals
alone: the baseline), then `fit(...)` with its default goodness-of-fit check (the p-values
included: the number the bar is about), then `goodness_of_fit` alone on that result for
each `--n-rep`. Ratios are against the baseline fit of the same run.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time
import warnings

import numpy as np

import stickslip as ss

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
TRUTH = dict(D=0.4, tau=0.1)
FREE = {"D": (0.1, 1.0), "tau": (0.02, 0.5)}  # not centred on the truth


def slip_times(n: int, seed: int) -> np.ndarray:
    model = ss.get_model("langevin")(**BASE, **TRUTH)
    e = ss.simulate(model, int(n * 1.3) + 100, 0.2, 200.0, seed, progress=False)
    keep = np.asarray(e.stuck) & ~np.asarray(e.immediate)  # slips of positive length that ended
    return np.asarray(e.slip_time)[keep][:n]


def _timed(fn):
    """`fn()`, its wall-clock seconds and this process's CPU seconds (all threads: on a
    shared machine the wall clock includes the other jobs' share, the CPU time does not)."""
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=3000, help="cycles of data")
    parser.add_argument("--n-rep", type=int, nargs="*", default=[100, 200, 400])
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    data = {"slip_time": slip_times(args.n, 12345)}
    rows = []
    base, t_base, c_base = _timed(lambda: ss.fit("langevin", data, FREE, BASE, seed=1, check=False))
    rows.append(dict(what="fit, check=False (baseline)", seconds=t_base, cpu=c_base))
    full, t_full, c_full = _timed(lambda: ss.fit("langevin", data, FREE, BASE, seed=1))
    rows.append(dict(what=f"fit, check=True (n_rep {full.goodness.n_rep})", seconds=t_full,
                     cpu=c_full, p_values=full.p_values))  # fmt: skip
    for n_rep in args.n_rep:
        g, t, c = _timed(lambda n_rep=n_rep: ss.goodness_of_fit(base, n_rep=n_rep, seed=1))
        rows.append(dict(what=f"goodness_of_fit alone, n_rep {n_rep}", seconds=t, cpu=c,
                         p_values=g.p_values))  # fmt: skip
    print(f"{args.n} slip times, D and tau free, n_sim {base.diagnostics['n_sim']}; "
          f"{base.diagnostics['evaluations']} points evaluated")  # fmt: skip
    print(base.summary())
    for r in rows:
        ps = r.get("p_values")
        shown = "" if ps is None else "  p: " + ", ".join(f"{k} {p:.3g}" for k, p in ps.items())
        print(f"{r['what']:40s} {r['seconds']:7.1f} s wall ({r['cpu']:6.1f} s CPU)  / baseline "
              f"fit: {r['seconds'] / t_base:5.2f}{shown}")  # fmt: skip
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
