"""What the shape fits' stopping rule costs and changes: a fit point through the measured
slider's measurement (`measured_cycles`, 1000 model cycles) and the public runs' cycles,
with the rule as shipped (`_force._GAIN_TOL`, a step gaining under 1e-3 in chi^2 ends a
fit) against the earlier one (1e-8 of the cost), in one process, warmed alike.

    python benchmarks/shape_fit_stop.py [--points 5]

Prints the seconds a point under each rule (the mean over the same seeds, after a warm-up
point under each; the rules alternate seed by seed) and, per public run, the cycles found
under each and the largest change of a release, slip time, stick time and force drop
between them.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time
import warnings

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
EARLIER = 1e-8  # the stop before: a step gaining under 1e-8 of the cost (max(cost, 1))
RUNS = (("k168Nm_v42.mat", 168.0, 42e-6), ("k1002Nm_v42.mat", 1002.0, 42e-6),
        ("k168Nm_v1100.mat", 168.0, 1100e-6))  # fmt: skip


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=5)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.path.insert(0, str(ROOT / "examples"))
    from fit_forward import slider_problem
    from slider_trace import load

    import stickslip as ss
    from stickslip._extract import _force
    from stickslip._inference import measurement as meas

    warnings.simplefilter("ignore")
    shipped = _force._GAIN_TOL
    cycles, slider, known, _ = slider_problem()
    model = ss.get_model("langevin")(omega0=1.2, D=0.4, **known)
    m = ss.Measurement.from_cycles(cycles, scales=slider)
    rules = {"earlier (1e-8 of the cost)": EARLIER, f"shipped ({shipped:g} in chi^2)": shipped}
    for tol in rules.values():  # warm-up, each rule alike
        _force._GAIN_TOL = tol
        meas.measured_cycles(model, m, 1000, 99)
    seconds = dict.fromkeys(rules, 0.0)
    for seed in range(args.points):  # the rules in turn at each seed: a load shared alike
        for name, tol in rules.items():
            _force._GAIN_TOL = tol
            t0 = time.perf_counter()
            meas.measured_cycles(model, m, 1000, seed)
            seconds[name] += (time.perf_counter() - t0) / args.points
    base = seconds[next(iter(rules))]
    for name, s in seconds.items():
        print(f"{name:28s} {s:.3f} s a point  x{base / s:.2f}")
    for file, k, v in RUNS:
        t, f = load(file)
        found = {}
        for name, tol in rules.items():
            _force._GAIN_TOL = tol
            found[name] = ss.extract_cycles(t, force=f, stiffness=k, v_b=v)
        a, b = found.values()
        line = f"{file}: {len(a)} and {len(b)} cycles"
        if len(a) == len(b):
            for col in ("release_time", "slip_time", "stick_time", "force_drop"):
                line += f"; {col} {np.max(np.abs(a[col] - b[col])):.2g}"
        print(line)
    _force._GAIN_TOL = shipped


if __name__ == "__main__":
    main()
