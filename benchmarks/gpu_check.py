"""The host and the device scheduler on whatever backend JAX finds, in one short run.

    python benchmarks/gpu_check.py [--n-paths 100000 1000000] [--dt 0.8] [--json out.json]

Public reference set (Langevin, OU noise), exact stepping with exact-in-law stick detection,
dt = 0.8. For each number of paths (10^5 and 10^6, and 10^7 where JAX sees an accelerator)
and each scheduler (`simulate(scheduler="host" | "device")`): the first call (compiling, or
loading from the on-disk cache if warm), the compiled time (median of the runs after it),
the compiled calls (`stats["dispatches"]`) and arrays read back (`stats["transfers"]`); then
the comparison of the two ensembles of one seed:

- `same`: the fraction of paths with the same stick decision and slip times equal to 1e-9
  (the noise is keyed by seed, path, step and tree node: the schedulers differ only where
  floating point rounds differently), and the largest slip-time difference;
- each ensemble's mean slip time and chi-square p-values of its slip-time and slip-distance
  histograms against the independent reference (`tests/data/langevin_ou_public.*`, the
  tests' own test, `benchmarks/throughput.py`).

Meant to take under 5 minutes (device time is scarce: run it once, then give the machine
back); timings on a shared machine vary by up to 30 %.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import _baselines  # noqa: E402

_timed = _baselines.timed

# Compiled code is timed: every buffer size compiled where first met (`_compile.policy`).
os.environ.setdefault("STICKSLIP_COMPILE", "eager")

HERE = pathlib.Path(__file__).resolve().parent
PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
SCHEDULERS = ("host", "device")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, nargs="+", help="default 1e5 1e6 (and 1e7 on "
                        "an accelerator)")  # fmt: skip
    parser.add_argument("--dt", type=float, default=0.8)
    parser.add_argument("--t-max", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--runs", type=int, default=2, help="compiled runs (median) below 1e7")
    parser.add_argument("--json", type=pathlib.Path, help="also write the results here")
    args = parser.parse_args(argv)

    import jax

    import stickslip as ss

    sys.path.insert(0, str(HERE))
    from throughput import _passes

    device = jax.devices()[0]
    accelerator = device.platform != "cpu"
    sizes = args.n_paths or [100_000, 1_000_000] + ([10_000_000] if accelerator else [])
    print(f"backend {device.platform}: {device.device_kind}; {os.cpu_count()} CPU cores; "
          f"dt {args.dt}, t_max {args.t_max}", flush=True)  # fmt: skip
    model = ss.get_model("langevin")(**PUBLIC)
    rows, ensembles = [], {}
    for n in sizes:
        runs = args.runs if n < 10_000_000 else 1
        for scheduler in SCHEDULERS:

            def run(n=n, scheduler=scheduler):
                return ss.simulate(model, n, args.dt, args.t_max, seed=args.seed,
                                   scheduler=scheduler)  # fmt: skip

            ens, first = _timed(run)
            times = [_timed(run)[1] for _ in range(runs)]
            ensembles[scheduler] = ens
            ok, ps = _passes(ens.slip_time, ens.slip_distance)
            mean, se = ens.mean("slip_time")
            rows.append(dict(
                backend=device.platform, device=device.device_kind, n_paths=n,
                scheduler=scheduler, first_seconds=first, compiled_seconds=float(np.median(times)),
                dispatches=int(ens.stats["dispatches"]), transfers=int(ens.stats["transfers"]),
                mean_slip_time=mean, se=se, p_T=ps[0], p_d=ps[1], passes=bool(ok),
                miss_bound=float(ens.stats["miss_bound"]),
            ))  # fmt: skip
            print(f"  {scheduler:>6} {n:>9} paths: first {first:7.2f} s, compiled "
                  f"{np.median(times):7.3f} s", flush=True)  # fmt: skip
        host, dev = ensembles["host"], ensembles["device"]
        stuck = host.stuck & dev.stuck
        diff = np.abs(host.slip_time - dev.slip_time)
        same = (host.stuck == dev.stuck) & np.where(stuck, diff <= 1e-9, True)
        for r in rows[-2:]:
            r.update(same=float(same.mean()), max_abs_diff=float(np.max(diff[stuck], initial=0)))
        del host, dev
        ensembles.clear()  # (10^7 paths' ensembles are ~3 GB each)

    head = (f"{'paths':>9} {'scheduler':>9} {'first s':>8} {'compiled s':>10} {'calls':>6} "
            f"{'copies':>7} {'same':>8} {'max|dT|':>8} {'mean T_sl':>16} {'p(T)':>7} "
            f"{'p(d)':>7} {'miss bound':>10}")  # fmt: skip
    print("\n" + head)
    for r in rows:
        print(
            f"{r['n_paths']:>9} {r['scheduler']:>9} {r['first_seconds']:>8.2f} "
            f"{r['compiled_seconds']:>10.3f} {r['dispatches']:>6} {r['transfers']:>7} "
            f"{r['same']:>8.6f} {r['max_abs_diff']:>8.1e} "
            f"{r['mean_slip_time']:>8.4f}±{r['se']:.4f} {r['p_T']:>7.3g} {r['p_d']:>7.3g} "
            f"{r['miss_bound']:>10.3g}"
        )
    for n in sizes:
        t = {r["scheduler"]: r["compiled_seconds"] for r in rows if r["n_paths"] == n}
        print(f"{n:>9} paths: device scheduler {t['host'] / t['device']:.2f}x the host's speed "
              f"(compiled, {device.platform})")  # fmt: skip
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
