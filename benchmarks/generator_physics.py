"""Does the fitted model, at the truth, make the independent generator's cycles? The
generator's noise-free cycles (`independent_slider.make_trace`'s truth: no sensor, no
extraction) against the model's own (`simulate_cycles` of `random-threshold-held`, or
`langevin` for the fixed threshold, at the rig mapped through `Slider`), per-cycle slip
time, stick time and force drop in SI, two-sample Kolmogorov-Smirnov. A small p-value
puts a fit's misses in the physics or the mapping; large ones put them in the
measurement, the extraction or the estimator.

    python benchmarks/generator_physics.py [--case random|fixed] [--traces 3] [--seconds 1000]
"""

from __future__ import annotations

import argparse
import importlib.util
import pathlib
import sys
import time
import warnings

import numpy as np
from scipy import stats

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
_spec = importlib.util.spec_from_file_location("fit_independent", HERE / "fit_independent.py")
fi = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fi)
gen = fi.gen
QUANTITIES = ("slip_time", "stick_time", "force_drop")


def generator_cycles(case: str, traces: int, seconds: float) -> dict:
    rig = fi.rig_of(case)
    out = {k: [] for k in QUANTITIES}
    for i in range(traces):
        _, _, truth = gen.make_trace(50_000 + i, seconds, rig)
        for k in QUANTITIES:
            out[k].append(np.asarray(truth[k], float))
    return {k: np.concatenate(v) for k, v in out.items()}


def model_cycles(case: str, n_paths: int, t_max: float, seed: int) -> dict:
    import stickslip as ss

    slider = fi.truth_slider(fi.rig_of(case))
    dim = slider.dimensionless()
    name, _, fixed, truth = fi.problem(case, release="stick")
    params = {k: dim[k] for k in ("omega0", "zeta", "D", "v_b", "tau")}
    if case == "random":
        model = ss.get_model(name)(**params, threshold="normal",
                                   threshold_params=dim["threshold_params"])  # fmt: skip
    else:
        model = ss.get_model(name)(**params, x0=dim["x0"])
    series = ss.simulate_cycles(model, n_paths, 0.01, t_max, seed=seed)
    c = series.cycles
    ok = np.isfinite(np.asarray(c["period"], float))
    s = slider.scales
    return {
        "slip_time": np.asarray(c["slip_time"], float)[ok] * s.time,
        "stick_time": np.asarray(c["stick_time"], float)[ok] * s.time,
        "force_drop": np.asarray(c["slip_distance"], float)[ok] * s.force,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("random", "fixed"), default="random")
    parser.add_argument("--traces", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=1000.0)
    parser.add_argument("--paths", type=int, default=40)
    parser.add_argument("--t-max", type=float, default=8000.0, help="model time units a path")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    g = generator_cycles(args.case, args.traces, args.seconds)
    m = model_cycles(args.case, args.paths, args.t_max, seed=7)
    print(f"{args.case}: {g['slip_time'].size} generator cycles, {m['slip_time'].size} model "
          f"cycles ({time.perf_counter() - t0:.0f} s)")  # fmt: skip
    print("| quantity | generator median, sd | model median, sd | zero share (gen, model) | KS p |")
    print("|---|---|---|---|---|")
    for k in QUANTITIES:
        a, b = g[k], m[k]
        print(f"| {k} | {np.median(a):.4g}, {a.std():.4g} | {np.median(b):.4g}, {b.std():.4g} | "
              f"{np.mean(a == 0):.3f}, {np.mean(b == 0):.3f} | "
              f"{stats.ks_2samp(a, b).pvalue:.3g} |")  # fmt: skip


if __name__ == "__main__":
    main()
