"""Time of `extract_cycles` against trace length (the aim: linear, and the measured
751 281-sample force trace in <= 2 s on 2 cores).

    python benchmarks/extract_cycles.py [--json out.json]

Velocity traces of 1e5, 1e6, 1e7 samples (a sine-shaped slip every 4.6 time units) given
as v and as x, and the measured force trace shipped in examples/data/slider_paper_on_paper/
(best of 3). Ratios are per sample against the 1e5 trace of the same run.

Measured on the shared 2-core machine (other jobs running), `--max 1e6`: the force trace
in 0.6-0.7 s, 252 cycles (was 2.4 s with one scipy least_squares per slip).
Quiet, `--max 1e5`, alternated with the tree before (3 runs each): 0.32-0.34 s against
0.37-0.38 s with np.median over the whole trace and the slip shape's trigonometry over
whole windows (the same cycles to the bit).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time
import warnings

import numpy as np

import stickslip as ss

ROOT = pathlib.Path(__file__).resolve().parents[1]
REAL = ROOT / "examples" / "data" / "slider_paper_on_paper" / "k168Nm_v42.mat"


def _best(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, min(times)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--json", default=None)
    parser.add_argument("--max", type=float, default=1e7, help="longest velocity trace")
    args = parser.parse_args()
    rows = []
    for n in (10**5, 10**6, 10**7):
        if n > args.max:
            continue
        t = np.arange(n) * 0.01
        v = 1.0 - np.maximum(0.0, np.sin(np.pi * t / 2.3))
        x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.01)])
        for name, kw in (("v", dict(v=v)), ("x", dict(x=x))):
            found, sec = _best(
                lambda kw=kw, t=t: ss.extract_cycles(t, v_b=1.0, **kw), 1 + (n < 10**7)
            )
            rows.append(dict(trace=f"{name}, {n:.0e} samples", n=n, cycles=len(found), seconds=sec))
    if REAL.exists():
        from scipy.io import loadmat

        raw = loadmat(REAL)
        t, force = raw["t"].ravel(), raw["Fnorm"].ravel() * 0.0307 * 9.81
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found, sec = _best(
                lambda: ss.extract_cycles(t, force=force, stiffness=168.0, v_b=42e-6), 3
            )
        rows.append(dict(trace="measured force, k168Nm_v42", n=t.size, cycles=len(found),
                         seconds=sec))  # fmt: skip
    base = {r["trace"].split(",")[0]: r["seconds"] / r["n"] for r in rows if r["n"] == 10**5}
    for r in rows:
        key = r["trace"].split(",")[0]
        ratio = r["seconds"] / r["n"] / base[key] if key in base else float("nan")
        print(f"{r['trace']:32s} {r['cycles']:7d} cycles {r['seconds']:8.3f} s  "
              f"per-sample time / 1e5's: {ratio:.2f}")  # fmt: skip
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
