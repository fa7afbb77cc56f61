"""The same ensemble on the CPU and on the default backend (a GPU where JAX sees one).

    python benchmarks/backends.py [--n-paths 100000 1000000] [--dt 0.8 0.1] [--json out.json]

Public reference set (Langevin, OU noise), exact stepping with exact-in-law stick detection.
Each backend runs in a process of its own (`JAX_PLATFORMS=cpu` for the CPU, nothing set for
the default), so that neither shares compiled code or a cache key with the other. For each
(dt, paths): the first call (compiling; from the on-disk cache if warm) and the compiled time
(median of 3 runs after it), then, against the CPU's ensemble of the same seed:

- `same`: the fraction of paths whose slip time agrees to 1e-9 (relative). The noise is a
  function of (seed, path, step, level) on every backend (threefry), so the ensembles differ
  only where floating point rounds differently: a refinement decision or a located stick time
  that differs in its last bits;
- both ensembles' chi-square p-values against the independent reference data
  (`tests/data/langevin_ou_public.*`, the test `benchmarks/throughput.py` uses), and their
  mean slip times.

On a machine with no accelerator the default backend is the CPU and only the CPU runs.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def _worker(out, sizes, dts, t_max, seed):
    """Run every (dt, paths) on this process's default backend; save ensembles and times."""
    import jax

    import stickslip as ss

    device = jax.devices()[0]
    model = ss.get_model("langevin")(**PUBLIC)
    saved = dict(platform=device.platform, device=device.device_kind)
    for dt in dts:
        for n in sizes:
            start = time.perf_counter()
            ens = ss.simulate(model, n, dt, t_max, seed=seed)
            first = time.perf_counter() - start
            times = []
            for _ in range(3):
                start = time.perf_counter()
                ss.simulate(model, n, dt, t_max, seed=seed)
                times.append(time.perf_counter() - start)
            tag = f"{dt}_{n}"
            saved[f"T_{tag}"] = np.asarray(ens.slip_time)
            saved[f"d_{tag}"] = np.asarray(ens.slip_distance)
            saved[f"first_{tag}"] = first
            saved[f"compiled_{tag}"] = float(np.median(times))
            print(f"  {device.platform} dt {dt} {n} paths: first {first:.2f} s, "
                  f"compiled {np.median(times):.3f} s", flush=True)  # fmt: skip
    np.savez(out, **saved)


def _run(env_extra, args, path):
    env = dict(os.environ, **env_extra)
    cmd = [sys.executable, __file__, "--worker", str(path), "--seed", str(args.seed),
           "--t-max", str(args.t_max), "--n-paths", *map(str, args.n_paths),
           "--dt", *map(str, args.dt)]  # fmt: skip
    subprocess.run(cmd, env=env, check=True)
    with np.load(path) as f:
        return {k: f[k] for k in f.files}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--dt", type=float, nargs="+", default=[0.8, 0.1])
    parser.add_argument("--t-max", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=pathlib.Path, help="also write the results here")
    parser.add_argument("--worker", type=pathlib.Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        return _worker(args.worker, args.n_paths, args.dt, args.t_max, args.seed)

    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    from throughput import _passes

    with tempfile.TemporaryDirectory() as tmp:
        print("default backend:", flush=True)
        default = _run({}, args, pathlib.Path(tmp, "default.npz"))
        runs = {str(default["platform"]): default}
        if str(default["platform"]) != "cpu":
            print("CPU:", flush=True)
            runs["cpu"] = _run({"JAX_PLATFORMS": "cpu"}, args, pathlib.Path(tmp, "cpu.npz"))

    rows = []
    cpu = runs["cpu"]
    for name, r in runs.items():
        for dt in args.dt:
            for n in args.n_paths:
                tag = f"{dt}_{n}"
                T, d = r[f"T_{tag}"], r[f"d_{tag}"]
                T0 = cpu[f"T_{tag}"]
                both = np.isfinite(T) & np.isfinite(T0)
                same = np.isclose(T, T0, rtol=1e-9, atol=0) | (~np.isfinite(T) & ~np.isfinite(T0))
                ok, ps = _passes(T, d)
                finite = T[np.isfinite(T)]
                rows.append(dict(
                    backend=name, device=str(r["device"]), dt=dt, n_paths=n,
                    first_seconds=float(r[f"first_{tag}"]),
                    compiled_seconds=float(r[f"compiled_{tag}"]),
                    same_as_cpu=float(same.mean()),
                    max_abs_diff=float(np.max(np.abs(T[both] - T0[both]), initial=0.0)),
                    mean_slip_time=float(finite.mean()),
                    se=float(finite.std() / np.sqrt(finite.size)),
                    p_T=ps[0], p_d=ps[1], passes=bool(ok),
                ))  # fmt: skip
    head = f"{'backend':>8} {'dt':>5} {'paths':>8} {'first s':>8} {'compiled s':>10} "
    print("\n" + head + f"{'same':>8} {'max|dT|':>9} {'mean T_sl':>16} {'p(T)':>8} {'p(d)':>8}")
    for r in rows:
        print(
            f"{r['backend']:>8} {r['dt']:>5} {r['n_paths']:>8} {r['first_seconds']:>8.2f} "
            f"{r['compiled_seconds']:>10.3f} {r['same_as_cpu']:>8.5f} "
            f"{r['max_abs_diff']:>9.1e} {r['mean_slip_time']:>8.4f}±{r['se']:.4f} "
            f"{r['p_T']:>8.3g} {r['p_d']:>8.3g}"
        )
    for name, r in runs.items():
        print(f"{name}: {r['device']}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
