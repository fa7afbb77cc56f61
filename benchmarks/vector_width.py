"""XLA's vector width on a CPU with AVX-512: 512-bit (stickslip's choice there) against
XLA's default 256-bit, same machine, alternating processes.

    python benchmarks/vector_width.py [--rounds 3] [--n-paths 100000]

The width is an option of XLA's code generation, fixed when JAX starts its backend, so each
side runs in processes of its own (`XLA_FLAGS=--xla_cpu_prefer_vector_width=...`, which
stickslip keeps when the user sets it), alternated `--rounds` times so that a drift of the
machine's speed falls on both. Each process times, once compiled (a first call of the same
size not counted; the minimum of 5 runs), first passages of the public reference set with
exact stepping at dt 0.8 and 0.2 and Euler-Maruyama at dt 0.01, and checks that the
results are the same to the last bit under both widths (a hash of the slip times). Prints
the medians over rounds and the ratios 256 / 512 (> 1: 512 is faster).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys

PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
CASES = (("exact", 0.8), ("exact", 0.2), ("euler", 0.01))


def child(n_paths: int) -> dict:
    import time

    import numpy as np

    import stickslip as ss

    model = ss.get_model("langevin")(**PUBLIC)
    out = {}
    for solver, dt in CASES:
        n = n_paths if solver == "exact" else n_paths // 10
        opts = dict(solver=solver, progress=False)
        ens = ss.simulate(model, n, dt, 100.0, seed=0, **opts)
        times = []
        for k in range(5):
            start = time.perf_counter()
            ss.simulate(model, n, dt, 100.0, seed=k + 1, **opts)
            times.append(time.perf_counter() - start)
        digest = hashlib.sha256(np.nan_to_num(ens.slip_time, nan=-1.0).tobytes()).hexdigest()
        out[f"{solver} dt={dt} N={n}"] = (min(times), digest[:16])
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--n-paths", type=int, default=100_000)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.n_paths)))
        return 0
    results = {256: [], 512: []}
    for _ in range(args.rounds):
        for width in (256, 512):
            env = dict(os.environ, XLA_FLAGS=f"--xla_cpu_prefer_vector_width={width}")
            text = subprocess.run(
                [sys.executable, __file__, "--child", "--n-paths", str(args.n_paths)],
                env=env, check=True, capture_output=True, text=True,
            ).stdout  # fmt: skip
            results[width].append(json.loads(text.strip().splitlines()[-1]))
    print(f"{'case':28s} {'256-bit s':>10s} {'512-bit s':>10s} {'ratio':>6s}  same bits")
    for case in results[256][0]:
        med = {}
        for width in (256, 512):
            times = sorted(r[case][0] for r in results[width])
            med[width] = times[len(times) // 2]
        same = len({r[case][1] for w in (256, 512) for r in results[w]}) == 1
        print(f"{case:28s} {med[256]:10.3f} {med[512]:10.3f} {med[256] / med[512]:6.2f}  {same}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
