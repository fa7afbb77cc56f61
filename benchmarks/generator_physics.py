"""Does the fitted model, at the truth, make the independent generator's cycles? The
generator's noise-free cycles (`independent_slider.make_trace`'s truth: no sensor, no
extraction) against the model's own (`simulate_cycles` of `random-threshold-held`, or
`langevin` for the fixed threshold, at the rig mapped through `Slider`), per-cycle slip
time, stick time and force drop in SI, two-sample Kolmogorov-Smirnov. A small p-value
puts a fit's misses in the physics or the mapping; large ones put them in the
measurement, the extraction or the estimator.

`--noise-scan 0.85,1,1.15` reads the generator's effective friction-noise intensity: the
spread that noise adds to a slip at a given release force (the residual sd of slip time
and of force drop about a quadratic in the release force's gap above F_k), the
generator's against the model's at the truth's noise times each factor, interpolated,
with delta-method standard errors. KS alone would miss a noise a few per cent off.

    python benchmarks/generator_physics.py [--case random|fixed] [--traces 3] [--seconds 1000]
    python benchmarks/generator_physics.py --noise-scan 0.85,1,1.15 --traces 30 --paths 100 \
        --t-max 40000
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
SPREADS = ("slip_time", "force_drop")


def generator_cycles(case: str, traces: int, seconds: float) -> dict:
    rig = fi.rig_of(case)
    out = {k: [] for k in (*QUANTITIES, "gap")}
    for i in range(traces):
        _, _, truth = gen.make_trace(50_000 + i, seconds, rig)
        for k in QUANTITIES:
            out[k].append(np.asarray(truth[k], float))
        out["gap"].append(np.asarray(truth["peak_force"], float) - rig.kinetic_friction)
    return {k: np.concatenate(v) for k, v in out.items()}


def model_cycles(case: str, n_paths: int, t_max: float, seed: int, noise: float = 1.0) -> dict:
    """The model's cycles in SI at the truth, its noise intensity times `noise`."""
    import stickslip as ss

    slider = fi.truth_slider(fi.rig_of(case))
    model = fi.truth_model(case, release="stick", noise=noise)
    series = ss.simulate_cycles(model, n_paths, 0.01, t_max, seed=seed, record=False)
    c = series.cycles
    ok = np.isfinite(np.asarray(c["period"], float))
    s = slider.scales
    drop = np.asarray(c["slip_distance"], float)[ok]
    return {
        "slip_time": np.asarray(c["slip_time"], float)[ok] * s.time,
        "stick_time": np.asarray(c["stick_time"], float)[ok] * s.time,
        "force_drop": drop * s.force,
        # the release's force above F_k: where the slip stuck plus how far it slipped
        "gap": (np.asarray(c["stick_position"], float)[ok] + drop) * s.force,
    }


def residual_spread(gap: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The sd of `y` (slip time or force drop) about a quadratic in the release's gap above
    F_k (the spread the friction noise adds to a slip from a given force), and its standard
    error (delta method on the residuals' squares)."""
    x = np.c_[np.ones_like(gap), gap, gap * gap]
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ coef
    sd = float(r.std())
    return sd, float(np.sqrt(np.var(r * r) / (4 * sd * sd * r.size)))


def noise_spreads(cycles: dict) -> tuple[np.ndarray, np.ndarray]:
    """`residual_spread` of slip time and force drop: (sds, standard errors)."""
    out = np.array([residual_spread(cycles["gap"], cycles[k]) for k in SPREADS])
    return out[:, 0], out[:, 1]


def noise_scan(case: str, factors, g: dict, paths: int, t_max: float) -> None:
    """The generator's effective noise intensity, as a factor of the truth's, per spread."""
    gs, gse = noise_spreads(g)
    rows = []
    for f in factors:
        m = model_cycles(case, paths, t_max, seed=11, noise=f)
        rows.append((f, *noise_spreads(m), m["gap"].size))
    print(f"generator: {g['gap'].size} cycles; model: {rows[0][3]}-{rows[-1][3]} a factor")
    print("| spread | generator (SE) | " + " | ".join(f"model x {f:g}" for f, *_ in rows)
          + " | generator's noise factor (SE) |")  # fmt: skip
    print("|---|---|" + "---|" * len(rows) + "---|")
    fs = np.array([r[0] for r in rows])
    for j, k in enumerate(SPREADS):
        ms = np.array([r[1][j] for r in rows])
        slope = np.polyfit(fs, ms, 1)[0]  # the spread's change per unit factor
        at = np.interp(gs[j], ms, fs)
        i1 = int(np.argmin(abs(fs - 1.0)))
        se = np.hypot(gse[j], rows[i1][2][j]) / abs(slope)
        print(f"| {k} residual | {gs[j]:.4g} ({gse[j]:.1g}) | "
              + " | ".join(f"{v:.4g}" for v in ms) + f" | {at:.3f} ({se:.3f}) |")  # fmt: skip


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("random", "fixed"), default="random")
    parser.add_argument("--traces", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=1000.0)
    parser.add_argument("--paths", type=int, default=40)
    parser.add_argument("--t-max", type=float, default=8000.0, help="model time units a path")
    parser.add_argument(
        "--noise-scan",
        default=None,
        help="comma-separated noise factors: the generator's effective noise",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    g = generator_cycles(args.case, args.traces, args.seconds)
    if args.noise_scan:
        factors = sorted(float(f) for f in args.noise_scan.split(","))
        noise_scan(args.case, factors, g, args.paths, args.t_max)
        print(f"{time.perf_counter() - t0:.0f} s")
        return
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
