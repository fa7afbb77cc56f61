"""The first call on a fresh machine: a new process, an empty compiled-code cache.

    python benchmarks/cold_start.py [--runs 3] [--n-paths 100000] [--dt 0.8]
    python benchmarks/cold_start.py --main-job [--runs 3]
    python benchmarks/cold_start.py --creep [--runs 3] [--before TREE]

Each run makes a new, empty `STICKSLIP_CACHE_DIR` and times, as whole processes (start-up,
imports and exit included), `import stickslip` + `simulate` of the public set (OU friction
noise, the exact detector):

- `cold`: the first process under the default policy (`"background"`): it compiles what
  nothing can stand in for and leaves the other buffer sizes to the background compiler;
- `background`: the background compiler's own time until its queue is empty (it runs
  after the first process, niced; nobody waits for it);
- `warm`: a second process once it is done (everything loads from disk);
- `eager cold`: a first process under `"eager"` in another empty cache (one compilation per
  buffer size: the behaviour before stand-in sizes), the same numbers to the last bit.

Prints the median and the spread of each, the compilations and traces of the first process
(`cache_info()`), and checks that the four processes' ensembles are identical.

`--main-job`: the README's main job instead, `stickslip run examples/public_reference.yaml
--out DIR` as a whole process: `cold` (an empty cache), `warm` (the same cache, once the
background compiler is done), with the compilations of the cold process, and checks that
every `results.nc` holds the same numbers (the timings `seconds_*` and `created` aside).

`--creep`: the rate-and-state slider instead (`RateAndState.example()`, 8 paths for 20 s
of its noise-free cycles: ~30 cycles each), `cold` (an empty cache: the shipped trace
and a compilation) and `warm` (the same cache again: loaded from disk); with `--before
TREE`, the same two processes with another checkout's `src` and `plugins` first on the
path (say the tree before a change: `git worktree add /tmp/before HEAD~1`), alternating
with this one's, and a check that both give the same cycles.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

SCRIPT = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import stickslip as ss
m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
e = ss.simulate(m, int(sys.argv[1]), float(sys.argv[2]), 50.0, seed=1, progress=False)
info = ss.cache_info()
digest = __import__("hashlib").sha256(np.nan_to_num(np.stack(
    [e.slip_time, e.stick_time, e.slip_distance])).tobytes()).hexdigest()
print(json.dumps(dict(info=info, digest=digest, inside=time.perf_counter() - t0)))
"""


def process(cache, policy, n, dt):
    env = dict(os.environ, STICKSLIP_CACHE_DIR=cache, STICKSLIP_COMPILE=policy)
    start = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(n), str(dt)], env=env, capture_output=True,
        text=True, check=True,
    )  # fmt: skip
    wall = time.perf_counter() - start
    return wall, json.loads(out.stdout.strip().splitlines()[-1])


# The `stickslip` command itself (`cli.console`: it leaves by `cli.quick_exit`, which runs
# the exit handlers, this one among them).
JOB = """
import atexit, json, sys
from stickslip import _compile
from stickslip.cli import console
atexit.register(lambda: print(json.dumps(_compile.cache_info())))
sys.argv = ["stickslip", "run", sys.argv[1], "--out", sys.argv[2], "--force"]
console()
"""


def main_job(cache, study, out):
    """One process of the main job; `(wall seconds, cache_info, results digest)`."""
    env = dict(os.environ, STICKSLIP_CACHE_DIR=cache)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", JOB, study, out], env=env, capture_output=True, text=True,
        check=True,
    )  # fmt: skip
    wall = time.perf_counter() - start
    return wall, json.loads(done.stdout.strip().splitlines()[-1]), results_digest(out)


def results_digest(out):
    """A digest of every variable and attribute of `out/results.nc` but the timings."""
    import hashlib

    import numpy as np
    import xarray as xr

    digest = hashlib.sha256()
    with xr.open_dataset(os.path.join(out, "results.nc")) as ds:
        for name in sorted(ds.variables):
            if not str(name).startswith("seconds_"):
                digest.update(str(name).encode())
                digest.update(np.ascontiguousarray(ds[name].values).tobytes())
        for key in sorted(ds.attrs):
            if key != "created" and not key.startswith("seconds_"):
                digest.update(f"{key}={ds.attrs[key]}".encode())
    return digest.hexdigest()


def run_main_job(runs):
    from stickslip import _background

    study = os.path.join(os.path.dirname(__file__), "..", "examples", "public_reference.yaml")
    rows = {"cold": [], "warm": []}
    digests, infos = set(), []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
            wall, info, digest = main_job(cache, study, os.path.join(out, "cold"))
            rows["cold"].append(wall)
            infos.append(info)
            digests.add(digest)
            _background.wait(cache, timeout=1800)
            wall, _, digest = main_job(cache, study, os.path.join(out, "warm"))
            rows["warm"].append(wall)
            digests.add(digest)
    print(f"stickslip run examples/public_reference.yaml; {runs} runs, each from an empty cache "
          "(whole processes, seconds)")  # fmt: skip
    _print_rows(rows, 5)
    for info in infos:
        print(f"  cold process: {info['compiles']} compilations, {info['traces']} traces, "
              f"{info['compile_seconds']:.2f} s compiling (summed over threads), "
              f"{info['trace_seconds']:.2f} s tracing")  # fmt: skip
    print(f"  the same results.nc in every process: {len(digests) == 1}")


CREEP = """
import hashlib, json, time
t0 = time.perf_counter()
import numpy as np
import stickslip as ss
m = ss.get_model("rate-and-state").example()
c = ss.simulate_cycles(m, 8, 1e-3, 20.0, seed=1).cycles
info = ss.cache_info()
digest = hashlib.sha256(np.nan_to_num(np.stack(
    [c["slip_time"], c["stick_time"], c["force_drop"]])).tobytes()).hexdigest()
print(json.dumps(dict(info=info, digest=digest, cycles=int(c["slip_time"].size),
                      inside=time.perf_counter() - t0)))
"""


def creep_process(cache, tree=None):
    """One process of the rate-and-state slider's cycles; `(wall seconds, its output)`."""
    env = dict(os.environ, STICKSLIP_CACHE_DIR=cache)
    if tree is not None:
        paths = [os.path.join(tree, "src"), os.path.join(tree, "plugins")]
        env["PYTHONPATH"] = os.pathsep.join(paths + [p for p in [env.get("PYTHONPATH")] if p])
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CREEP], env=env, capture_output=True, text=True,
                         check=True)  # fmt: skip
    return time.perf_counter() - start, json.loads(out.stdout.strip().splitlines()[-1])


def run_creep(runs, before=None):
    trees = {"": None} if before is None else {"": None, "before, ": before}
    rows = {f"{label}{kind}": [] for label in trees for kind in ("cold", "warm")}
    digests, cycles = set(), set()
    for _ in range(runs):
        for label, tree in trees.items():
            with tempfile.TemporaryDirectory() as cache:
                for kind in ("cold", "warm"):
                    wall, got = creep_process(cache, tree)
                    rows[f"{label}{kind}"].append(wall)
                    digests.add(got["digest"])
                    cycles.add(got["cycles"])
    print(f"the rate-and-state slider's example, 8 paths for 20 s ({sorted(cycles)} cycles); "
          f"{runs} runs, each from an empty cache (whole processes, seconds)")  # fmt: skip
    _print_rows(rows, 13)
    print(f"  the same cycles in every process: {len(digests) == 1}")


def _print_rows(rows: dict, width: int) -> None:
    """Each row's median, min and max (seconds)."""
    for name, values in rows.items():
        values = sorted(values)
        print(f"  {name:{width}s} median {values[len(values) // 2]:6.2f}  "
              f"(min {values[0]:.2f}, max {values[-1]:.2f})")  # fmt: skip


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--n-paths", type=int, default=100_000)
    parser.add_argument("--dt", type=float, default=0.8)
    parser.add_argument("--main-job", action="store_true", help="time the README's main job")
    parser.add_argument("--creep", action="store_true", help="time the rate-and-state slider")
    parser.add_argument("--before", help="with --creep: another checkout to time beside")
    args = parser.parse_args(argv)
    if args.creep:
        run_creep(args.runs, args.before)
        return
    if args.main_job:
        run_main_job(args.runs)
        return
    from stickslip import _background

    rows = {"cold": [], "background": [], "warm": [], "eager cold": []}
    digests, infos = set(), []
    for _ in range(args.runs):
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as other:
            wall, got = process(cache, "background", args.n_paths, args.dt)
            rows["cold"].append(wall)
            infos.append(got["info"])
            digests.add(got["digest"])
            start = time.perf_counter()
            _background.wait(cache, timeout=1800)
            rows["background"].append(time.perf_counter() - start)
            wall, got = process(cache, "background", args.n_paths, args.dt)
            rows["warm"].append(wall)
            digests.add(got["digest"])
            wall, got = process(other, "eager", args.n_paths, args.dt)
            rows["eager cold"].append(wall)
            digests.add(got["digest"])
    print(f"{args.n_paths} paths of the public set at dt = {args.dt}; {args.runs} runs, each "
          "from an empty cache (whole processes, seconds)")  # fmt: skip
    _print_rows(rows, 11)
    first = infos[0]
    print(f"  first process: {first['compiles']} compilations, {first['traces']} traces, "
          f"{first['compile_seconds']:.2f} s compiling, {first['trace_seconds']:.2f} s tracing, "
          f"{first['background']} executables left to the background compiler")  # fmt: skip
    print(f"  the same ensemble in every process: {len(digests) == 1}")


if __name__ == "__main__":
    main()
