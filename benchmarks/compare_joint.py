"""`compare_fits` on fits of one slider to several runs: a fixed against a random static
threshold, on two force traces of the independent generator (`independent_slider.py`,
which shares no code with the library) on springs of 168 and 400 N/m.

    python benchmarks/compare_joint.py --gap-sd 0.0028 [--seed 500] [--n-sim 1000]
    python benchmarks/compare_joint.py --gap-sd 0          # the fixed threshold true

Each trace is 200 s at 2 kHz with the generator's sensor noise, spikes, drift and a mains
hum, read by `extract_cycles`; both laws are fitted jointly to the two runs (`langevin`:
mass, noise and static friction free; `random-threshold-held`: mass, noise and the
threshold's mean and sd free; the kinetic friction, damping and noise time fixed at the
generator's; boxes not centred on the truth), then `compare_fits` chooses. Prints the
fits' estimates and times and the comparison's table.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import time
import warnings

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def runs_of(gap_sd: float, seed: int):
    """The two runs as `(Cycles, Slider)` pairs, and the generator's rig."""
    import independent_slider as gen

    import stickslip as ss

    runs, rig = [], None
    for i, k in enumerate((168.0, 400.0)):
        rig = dataclasses.replace(gen.Rig(gap_sd=gap_sd, hum=1.5e-4), stiffness=k)
        t, force, _ = gen.make_trace(seed + i, 200.0, rig)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cycles = ss.extract_cycles(t, force=force, stiffness=k, v_b=rig.v_b)
        columns = ("slip_time", "stick_time", "slip_distance")
        runs.append((ss.Cycles({c: cycles[c] for c in columns}, cycles.info),
                     ss.Slider.from_cycles(cycles, mass=0.03)))  # fmt: skip
    return runs, rig


def laws(rig) -> dict:
    """{name: (model, free, fixed)} in SI."""
    fixed = {"kinetic_friction": rig.kinetic_friction, "damping": rig.damping,
             "noise_time": rig.noise_time}  # fmt: skip
    shared = {"mass": (0.005, 0.05), "noise": (3e-9, 3e-7)}
    gap = (rig.kinetic_friction + 1e-3, rig.kinetic_friction + 0.012)
    return {
        "fixed": ("langevin", {**shared, "static_friction": gap}, fixed),
        "random": ("random-threshold-held",
                   {**shared, "threshold.mean": gap, "threshold.sd": (1e-4, 0.01)}, fixed),
    }  # fmt: skip


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gap-sd", type=float, required=True, help="the threshold's sd, N")
    parser.add_argument("--seed", type=int, default=500)
    parser.add_argument("--n-sim", type=int, default=1000)
    args = parser.parse_args(argv)

    import stickslip as ss

    runs, rig = runs_of(args.gap_sd, args.seed)
    print("cycles per run:", [len(c) for c, _ in runs])
    fits = {}
    for name, (model, free, fixed) in laws(rig).items():
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fits[name] = ss.fit(model, runs, free, fixed, n_sim=args.n_sim, seed=7)
        shown = ", ".join(f"{k} {v:.4g}" for k, v in fits[name].estimate.items())
        print(f"{name}: {time.perf_counter() - t0:.0f} s, log-likelihood "
              f"{fits[name].log_likelihood:.2f}: {shown}")  # fmt: skip
    t0 = time.perf_counter()
    comparison = ss.compare_fits(fits, seed=11)
    print(f"compared in {time.perf_counter() - t0:.0f} s")
    print(comparison.summary())


if __name__ == "__main__":
    main()
