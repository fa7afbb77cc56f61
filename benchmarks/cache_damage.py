"""What a damaged compiled-code cache costs: the same run in a new process on an empty cache
(cold), on the clean cache it left (warm), and on a copy of that cache with bytes changed
in every entry, sizes kept (damaged: each entry is found damaged, removed and made again).
Each is the median of `--repeats` runs; the slip times must agree to the bit every time.

    python benchmarks/cache_damage.py [--repeats 3] [--paths 20000]

The run: the public reference set (Langevin, OU friction noise), `--paths` paths at dt 0.2,
under `STICKSLIP_COMPILE=eager` (every buffer size compiled where it is first needed, so
that cold and damaged runs compile the same programs).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

RUN = """
import hashlib, json, sys, time, warnings
import numpy as np
import stickslip as ss
warnings.simplefilter("ignore")
m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
e = ss.simulate(m, int(sys.argv[1]), 0.2, 30.0, seed=1)
print(json.dumps({"digest": hashlib.sha256(e.slip_time.tobytes()).hexdigest(),
                  "compiles": ss.cache_info()["compiles"]}))
"""


def run(cache: pathlib.Path, paths: int) -> tuple[float, dict]:
    env = dict(os.environ, STICKSLIP_CACHE_DIR=str(cache), STICKSLIP_COMPILE="eager")
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", RUN, str(paths)], env=env, check=True,
                          capture_output=True, text=True)  # fmt: skip
    return time.perf_counter() - start, json.loads(done.stdout.strip().splitlines()[-1])


def damage(cache: pathlib.Path) -> int:
    """Change three bytes in every entry of stickslip's (sizes kept); the count."""
    entries = sorted(cache.glob("stickslip-exported/*.bin"))
    entries += sorted(cache.glob("stickslip-executable/*/*.bin"))
    for file in entries:
        data = bytearray(file.read_bytes())
        for at in (len(data) // 5, len(data) // 2, len(data) - 2):
            data[at] ^= 0x5A
        file.write_bytes(bytes(data))
    return len(entries)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--paths", type=int, default=20000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        cold, warm, damaged, digests, entries = [], [], [], set(), 0
        for k in range(args.repeats):
            cache = tmp / f"cold{k}"
            seconds, out = run(cache, args.paths)
            cold.append(seconds)
            digests.add(out["digest"])
        clean = tmp / "cold0"
        for _ in range(args.repeats):
            seconds, out = run(clean, args.paths)
            warm.append(seconds)
            digests.add(out["digest"])
        for k in range(args.repeats):
            copy = tmp / f"damaged{k}"
            shutil.copytree(clean, copy)
            entries = damage(copy)
            seconds, out = run(copy, args.paths)
            damaged.append(seconds)
            digests.add(out["digest"])
    if len(digests) != 1:
        print(f"the slip times differ between runs: {sorted(digests)}")
        return 1
    c, w, d = (statistics.median(x) for x in (cold, warm, damaged))
    print(f"{args.paths} paths, median of {args.repeats} new processes each; {entries} entries "
          f"damaged; slip times identical in all {3 * args.repeats} runs "
          f"(sha256 {next(iter(digests))[:12]})")  # fmt: skip
    print(f"cold (empty cache)   {c:6.2f} s")
    print(f"warm (clean cache)   {w:6.2f} s")
    print(f"damaged cache        {d:6.2f} s   = {d / w:.2f} x warm, {d / c:.2f} x cold")
    return 0


if __name__ == "__main__":
    sys.exit(main())
