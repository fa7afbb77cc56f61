"""Fitting the noisy rate-and-state slider to a force trace it did not make.

    python benchmarks/rate_and_state_fit.py [--free d_c D] [--seeds 1] [--n-sim 1000]
        [--log FILE.jsonl]
    python benchmarks/rate_and_state_fit.py --summary FILE.jsonl
    python benchmarks/rate_and_state_fit.py --point [--runs 2] [--n-sim 1000]
    python benchmarks/rate_and_state_fit.py --law [--grids 10 20 40 80] [--n-sim 3000]
    python benchmarks/rate_and_state_fit.py --profile --grids 10 40 [--n-sim 2000]
    python benchmarks/rate_and_state_fit.py --point-grids --grids 10 40 [--runs 1]
    python benchmarks/rate_and_state_fit.py --joint [--free d_c] [--seeds 1] [--log FILE]
    python benchmarks/rate_and_state_fit.py --versus [--seeds 1]

The data: `force_trace`, an independent generator (Euler-Maruyama in SI variables
(e, v, theta, eta), steps of 1 us with white-noise increments of its own, from steady
sliding at 1.5 V, the first 2 s left out), at k = 1002 N/m and 300 um/s (~310 cycles of
96 ms in 30 s), sampled at 2 kHz, with white sensor noise of 0.2 mN, read by
`extract_cycles`. The truth is the orientation set (a 0.01, b 0.015, d_c 1 um) with
Ornstein-Uhlenbeck friction noise (tau 2 ms, sd 0.3 N a). `fit` searches the `--free`
parameters over boxes not centred on the truth, the others fixed at it, and prints the
estimate, its 95 % interval, whether it covers the truth, the evaluated points and the
seconds each cost; with `--log`, one JSON line a trace, which `--summary` counts
(coverage of each parameter, estimates above the truth, z-scores' sd). `--point` times
one evaluated point instead: `n_sim` model cycles of the orientation set (with the noise
above) through the measurement of the public k = 1002 N/m, 42 um/s run
(`examples/data/slider_paper_on_paper`), this version's split into paths against the first
version's (ten burn-ins' worth of cycles a path), both warmed, then alternated `--runs`
times with the same seeds. `--law` sets the model's measured cycles against the
generator's, with no fit: one long trace of the generator (300 s, ~3100 cycles) read by
`extract_cycles`, and `n_sim` model cycles at the truth through its measurement on noise
grids of tau over each of `--grids` (and `--rtol`, the noisy steps' tolerance): each
column's mean difference in standard errors and ratio of sds (1 where the model's law is
the generator's). `--profile` asks where the likelihood of D peaks on data of a fit's
size, at the model's noise grid of tau over each of `--grids`: one 300 s trace cut into
ten 30 s segments, each read by `extract_cycles` and scored against `n_sim` model cycles
through its own measurement at D 0.8, 1 and 1.25 times the truth (the rest at it; the same
seed); the vertex of the parabola in log D through the three, per segment, and their
geometric mean with its standard error. `--point-grids` times `--point`'s point on the
noise grids of tau over each of `--grids` instead (all warmed, then alternated `--runs`
times with the same seeds). `--joint` fits one parameter set to two runs of the generator
at once (`fit(model, [cycles, cycles])`, each run through its own measurement, spring and
speed): the trace above and one on a stiffer spring (`K_STIFF`, 1400 N/m: ~470 cycles of
64 ms), with its goodness of fit per run (KS p-values through each run's measurement).
`--versus` fits the law (d_c free) and a memoryless random threshold (in a reference
`Slider`'s units) to one trace and compares them (`compare_fits`, across their units).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

PAPER = dict(mass=0.0307, normal_force=0.301, mu0=0.3, a=0.01, b=0.015, d_c=1e-6, v_ref=1e-6)
K, V, TAU, H = 1002.0, 300e-6, 2e-3, 5e-4
D = (0.3 * PAPER["normal_force"] * PAPER["a"] / PAPER["mass"]) ** 2 * TAU
SENSOR_SD = 2e-4  # N
# `--joint`'s second spring: stick-slip at V still (the linear analysis's k_c with inertia is
# 2.9 kN/m there), ~470 cycles of 64 ms and drops of 16 mN in 30 s (21 mN at K)
K_STIFF, JOINT_SEED = 1400.0, 10_000
# Boxes not centred on the truth (log scale: the truth off their geometric centre).
BOXES = {"d_c": (0.6e-6, 1.4e-6), "D": (D / 4, D * 4), "a": (0.007, 0.012),
         "b": (0.012, 0.02)}  # fmt: skip


def force_trace(p, k, v_b, D, tau, t_end, h_out, h_em, seed, burn):
    """The spring force k e every `h_out` over `t_end` seconds, after `burn` seconds of
    Euler-Maruyama steps of `h_em` in SI variables (e, v, theta, eta) from steady sliding
    at 1.5 v_b, with the regularised law and Dieterich's aging law written here from their
    definitions, and the friction noise d eta = -eta / tau dt + sqrt(2 D) / tau dW driven
    by JAX's normals of `seed` (a JAX scan: 3e7 steps in a few seconds)."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    M, N, a, b, d_c, v_ref, mu0 = (p[x] for x in ("mass", "normal_force", "a", "b", "d_c",
                                                   "v_ref", "mu0"))  # fmt: skip

    def mu(v, th):
        psi = mu0 + b * jnp.log(v_ref * th / d_c)
        return a * jnp.arcsinh(v / (2 * v_ref) * jnp.exp(psi / a))

    v0 = 1.5 * v_b
    th0 = d_c / v0
    s0 = (N * float(mu(v0, th0)) / k, v0, th0, 0.0)
    every = int(round(h_out / h_em))
    g = math.sqrt(2 * D * h_em) / tau

    def step(s, z):
        e, v, th, eta = s
        dv = (k * e - N * mu(v, th)) / M + eta
        return (e + h_em * (v_b - v), v + h_em * dv, th + h_em * (1.0 - v * th / d_c),
                eta - h_em * eta / tau + g * z), None  # fmt: skip

    def block(s, key):
        s, _ = jax.lax.scan(step, s, jax.random.normal(key, (every,)))
        return s, k * s[0]

    keys = jax.random.split(jax.random.key(seed), int(round((t_end + burn) / h_out)))
    _, F = jax.jit(lambda s, keys: jax.lax.scan(block, s, keys))(
        tuple(jnp.float64(x) for x in s0), keys)  # fmt: skip
    return np.asarray(F)[int(round(burn / h_out)) :]


def measured(seed: int, t_end: float = 30.0, k: float = K):
    """One generated trace as the sensor gives it: `(t, force)` in s and N, its white
    sensor noise keyed by `seed`."""
    F = force_trace(PAPER, k, V, D, TAU, t_end, H, 1e-6, seed, burn=2.0)
    F = F + SENSOR_SD * np.random.default_rng([seed, 101]).standard_normal(F.size)
    return H * np.arange(F.size), F


def data(seed: int, t_end: float = 30.0, k: float = K):
    """The cycles of one generated trace (`extract_cycles`, SI)."""
    import stickslip as ss

    t, F = measured(seed, t_end, k)
    return ss.extract_cycles(t, force=F, stiffness=k, v_b=V)


def campaign(seed: int) -> list:
    """`--joint`'s data: the cycles of two runs of the generator, on the springs `K` and
    `K_STIFF` at the same speed, with streams of their own (`seed`, `seed + JOINT_SEED`)."""
    return [data(seed), data(seed + JOINT_SEED, k=K_STIFF)]


def truth() -> dict:
    return dict(PAPER, D=D)


def main():
    import warnings

    import stickslip as ss

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--free", nargs="+", default=["d_c", "D"], choices=sorted(BOXES))
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--n-sim", type=int, default=1000)
    ap.add_argument("--log", help="append one JSON line a trace")
    ap.add_argument("--summary", help="count a --log file's coverage and stop")
    ap.add_argument("--point", action="store_true", help="time one point on the real run")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--law", action="store_true", help="the model's cycles against the data's")
    ap.add_argument("--profile", action="store_true", help="D's likelihood on 30 s segments")
    ap.add_argument("--point-grids", action="store_true", help="a point's cost per noise grid")
    ap.add_argument("--grids", type=float, nargs="+", default=[10, 20, 40, 80])
    ap.add_argument("--rtol", type=float, help="the noisy steps' tolerance (default: the solver's)")
    ap.add_argument("--joint", action="store_true", help="fit two runs (K and K_STIFF) at once")
    ap.add_argument("--stiffness", type=float, default=K, help="--law's spring (N/m)")
    ap.add_argument("--versus", action="store_true",
                    help="compare_fits: the law against a random threshold on one trace")
    args = ap.parse_args()
    if args.law:
        return law(args.grids, 3000 if args.n_sim == 1000 else args.n_sim, args.rtol,
                   args.stiffness)
    if args.point_grids:
        return point_grids(args.grids, args.n_sim, args.runs)
    if args.profile:
        return profile(args.grids, 2000 if args.n_sim == 1000 else args.n_sim)
    if args.summary:
        return summary(args.summary)
    if args.point:
        return point(args.n_sim, args.runs)
    if args.versus:
        return versus(args.seeds[0], args.n_sim)
    true = truth()
    for seed in args.seeds:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cycles = campaign(seed) if args.joint else data(seed)
        own = dict(tau=TAU) if args.joint else dict(stiffness=K, v_b=V, tau=TAU)
        fixed = {k: v for k, v in dict(true, **own).items() if k not in args.free}
        t0 = time.perf_counter()
        r = ss.fit("rate-and-state", cycles, free={k: BOXES[k] for k in args.free},
                   fixed=fixed, n_sim=args.n_sim, seed=11, check=args.joint)  # fmt: skip
        secs = time.perf_counter() - t0
        n = r.diagnostics.evaluations
        sizes = [c.table["period"].size for c in (cycles if args.joint else [cycles])]
        print(f"seed {seed}: {' + '.join(map(str, sizes))} cycles; {n} points in {secs:.0f} s "
              f"({secs / n:.1f} s a point)")  # fmt: skip
        for row in r.diagnostics.runs or ():
            shown = ", ".join(f"{k} {p:.3g}" for k, p in row.get("p_values", {}).items())
            print(f"  {row['name']} (k = {row['stiffness']:g} N/m): KS p {shown}")
        for k in args.free:
            lo, hi = r.ci[k] if r.ci.get(k) is not None else (math.nan, math.nan)
            print(
                f"  {k}: estimate {r.estimate[k]:.4g} [{lo:.4g}, {hi:.4g}], truth {true[k]:.4g}"
                f" ({'covered' if lo <= true[k] <= hi else 'NOT covered'})"
            )
        for w in r.diagnostics.warnings:
            print(f"  warning: {w}")
        if args.log:
            line = dict(seed=seed, cycles=int(sum(sizes)), seconds=secs, joint=args.joint,
                        points=n, truth={k: true[k] for k in args.free},
                        estimate={k: r.estimate[k] for k in args.free},
                        ci={k: r.ci.get(k) and list(r.ci[k]) for k in args.free},
                        warnings=list(r.diagnostics.warnings))  # fmt: skip
            with open(args.log, "a") as f:
                f.write(json.dumps(line) + "\n")


def versus(seed: int, n_sim: int):
    """`--versus`: on one trace of the generator, the law (d_c free, the rest at the truth)
    against a memoryless random threshold (`random-threshold-held`: an effective mass, the
    noise and the threshold's mean and sd free in SI, its units a reference `Slider` of
    the rig's mass), each fitted to the trace's cycles, then `compare_fits` across their
    units (the law in SI, the threshold in the slider's)."""
    import warnings

    import stickslip as ss

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = data(seed)
    cycles = ss.Cycles({c: full[c] for c in ("slip_time", "stick_time", "slip_distance")},
                       full.info)  # fmt: skip
    ref = ss.Slider.from_cycles(full, mass=PAPER["mass"])
    law_fixed = {k: v for k, v in dict(truth(), tau=TAU).items() if k != "d_c"}
    mu_k = ref.kinetic_friction
    rt_free = {"mass": (0.005, 0.2), "noise": (1e-10, 1e-7),
               "threshold.mean": (mu_k + 2e-3, mu_k + 0.04), "threshold.sd": (1e-4, 0.02)}
    rt_fixed = {"kinetic_friction": mu_k, "damping": ref.damping, "noise_time": TAU}
    fits, t0 = {}, time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fits["rate and state"] = ss.fit("rate-and-state", [cycles], {"d_c": BOXES["d_c"]},
                                        law_fixed, n_sim=n_sim, seed=11)  # fmt: skip
        print(f"rate and state: {time.perf_counter() - t0:.0f} s", flush=True)
        t0 = time.perf_counter()
        fits["random threshold"] = ss.fit("random-threshold-held", [(cycles, ref)], rt_free,
                                          rt_fixed, n_sim=n_sim, seed=11)  # fmt: skip
        print(f"random threshold: {time.perf_counter() - t0:.0f} s", flush=True)
    for name, r in fits.items():
        print(name, r.summary(), sep="\n")
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c = ss.compare_fits(fits, seed=21)
    print(c.summary())
    print(f"compare_fits: {time.perf_counter() - t0:.0f} s")


RUN = "examples/data/slider_paper_on_paper/k1002Nm_v42.mat"
RUN_SCALE = 0.301167  # its force column is F / (m g): m g in N


RUN_K = 1002.0  # N/m, its spring


def _real_run():
    """The measured k = 1002 N/m, 42 um/s run's `Measurement` (SI, forces over k) and the
    model of the orientation set with the noise above on that spring and speed."""
    import pathlib
    import warnings

    from scipy.io import loadmat

    import stickslip as ss
    from stickslip.units import Scales

    mat = loadmat(pathlib.Path(__file__).resolve().parents[1] / RUN)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = ss.extract_cycles(mat["t"][:, 0], force=mat["Fnorm"][:, 0] * RUN_SCALE,
                                stiffness=RUN_K, v_b=42e-6)  # fmt: skip
        measurement = ss.Measurement.from_cycles(run, scales=Scales.si(RUN_K))
    model = ss.get_model("rate-and-state")(stiffness=RUN_K, v_b=42e-6, D=D, tau=TAU, **PAPER)
    return measurement, model


def point(n_sim: int, runs: int):
    """`--point`: one fit point's forward model through a measured run's measurement."""
    import warnings

    from stickslip._inference import creeping
    from stickslip._inference.measurement import measured_cycles

    measurement, model = _real_run()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rules = {"this version": creeping.paths, "before (paths of 10 burn-ins)": _paths_before}
        for rule in rules.values():  # warm both (each path count compiles once)
            creeping.paths = rule
            measured_cycles(model, measurement, n_sim, seed=0)
        for i in range(runs):
            for name, rule in rules.items():  # alternating, the same seed
                creeping.paths = rule
                t0 = time.perf_counter()
                sim = measured_cycles(model, measurement, n_sim, seed=1 + i)
                secs = time.perf_counter() - t0
                medians = ", ".join(f"{c} {np.median(sim[c]):.4g}"
                                    for c in ("stick_time", "slip_time"))  # fmt: skip
                print(
                    f"{name}: {n_sim} model cycles through the run's measurement in "
                    f"{secs:.1f} s ({sim['period'].size} cycles measured; {medians})"
                )
        creeping.paths = rules["this version"]


def point_grids(grids, n_sim: int, runs: int):
    """`--point-grids`: `--point`'s point on each noise grid."""
    import warnings

    from stickslip._inference import creeping
    from stickslip._inference.measurement import measured_cycles

    measurement, model = _real_run()
    before = creeping.NOISE_GRID
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for grid in grids:  # warm each
            creeping.NOISE_GRID = grid
            measured_cycles(model, measurement, n_sim, seed=0)
        for i in range(runs):
            for grid in grids:
                creeping.NOISE_GRID = grid
                t0 = time.perf_counter()
                sim = measured_cycles(model, measurement, n_sim, seed=1 + i)
                drop = np.median(sim["force_drop"]) * RUN_K * 1e3
                print(f"grid tau/{grid:g}: {n_sim} model cycles through the run's measurement "
                      f"in {time.perf_counter() - t0:.1f} s (median drop {drop:.2f} mN)",
                      flush=True)  # fmt: skip
    creeping.NOISE_GRID = before


def law(grids, n_sim: int, rtol: float | None, k: float = K):
    """`--law`: the model's measured cycles at the truth against the generator's (on the
    spring `k`)."""
    import warnings

    import stickslip as ss
    from stickslip._inference.measurement import measured_cycles
    from stickslip._simulate import creep
    from stickslip.units import Scales

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = data(1, t_end=300.0, k=k)
    measurement = ss.Measurement.from_cycles(cycles, scales=Scales.si(k))
    columns = ("force_drop", "slip_time", "stick_time")
    ref = {c: np.asarray(cycles.table[c], float) for c in columns}
    ref["force_drop"] = ref["force_drop"] / k  # (the model's measured drops are over k)
    print(f"generator: {ref['force_drop'].size} cycles")
    if rtol is not None:
        creep.NOISY_RTOL = creep.NOISY_ATOL = rtol
    model = ss.get_model("rate-and-state")(stiffness=k, v_b=V, D=D, tau=TAU, **PAPER)
    for grid in grids:
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sim = measured_cycles(model, measurement, n_sim, seed=5, dt=TAU / grid)
        parts = []
        for c in columns:
            x, y = sim[c][np.isfinite(sim[c])], ref[c]
            se = math.hypot(x.std() / math.sqrt(x.size), y.std() / math.sqrt(y.size))
            sd_se = math.sqrt(0.5 / x.size + 0.5 / y.size)
            parts.append(f"{c} mean {(x.mean() - y.mean()) / se:+.1f} SE, "
                         f"sd x{x.std() / y.std():.3f} (+-{sd_se:.3f})")  # fmt: skip
        print(f"grid tau/{grid:g}: {sim['period'].size} cycles in "
              f"{time.perf_counter() - t0:.0f} s; " + "; ".join(parts), flush=True)  # fmt: skip


def profile(grids, n_sim: int, segments: int = 10):
    """`--profile`: the vertex in D of the likelihood on `segments` pieces of a 300 s trace."""
    import warnings

    import stickslip as ss
    from stickslip._inference import creeping, estimator, likelihood
    from stickslip._inference.data import to_fit_scale

    t, F = measured(1, 300.0)
    fixed = {k: v for k, v in dict(truth(), stiffness=K, v_b=V, tau=TAU).items() if k != "D"}
    Model = ss.get_model("rate-and-state")
    factors = (0.8, 1.0, 1.25)
    n = F.size // segments
    before = creeping.NOISE_GRID
    for grid in grids:
        creeping.NOISE_GRID = grid
        t0 = time.perf_counter()
        vertices = []
        for i in range(segments):
            cut = slice(i * n, (i + 1) * n)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cycles = ss.extract_cycles(t[cut] - t[cut][0], force=F[cut], stiffness=K, v_b=V)
                p = estimator.problem("rate-and-state", cycles, {"D": BOXES["D"]}, fixed,
                                      n_sim=n_sim)  # fmt: skip
                bw = {k: likelihood.bandwidth_of(to_fit_scale(k, p.data[k]), n_sim)
                      for k in p.data}  # fmt: skip
                L = []
                for f in factors:
                    sim = likelihood.sample(Model(**dict(fixed, D=D * f)), n_sim, p.dt, None,
                                            11, p.measured)  # fmt: skip
                    terms = likelihood.scored_samples(p.data, sim, bw, p.measured)
                    L.append(sum(float(np.sum(v)) for v in terms.values()))
            slope, curve = (L[2] - L[0]) / 2, (L[2] + L[0]) / 2 - L[1]
            vertices.append(-slope / (2 * curve) * math.log(1.25) if curve < 0 else math.nan)
        v = np.array(vertices)
        print(f"grid tau/{grid:g}: D's vertex / truth per segment "
              + " ".join(f"{math.exp(x):.3f}" for x in v)
              + f"; geometric mean {math.exp(np.nanmean(v)):.3f} (log SE "
              f"{np.nanstd(v, ddof=1) / math.sqrt(np.isfinite(v).sum()):.3f}); "
              f"{time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip
    creeping.NOISE_GRID = before


def _paths_before(n_cycles: int, burn_cycles: int) -> int:
    """The path count of the first version: each path ten burn-ins' worth of cycles (at
    least 50), at most 32 (then padded to a power of two by the solve)."""
    return int(min(32, max(1, round(n_cycles / max(50, 10 * burn_cycles)))))


def summary(path):
    """Each parameter's coverage over the logged traces (no interval: not covered), the
    estimates above the truth, and the sd of (estimate - truth) / SE (SE: the interval's
    half width over 1.96, on a log scale, as `fit` makes it for a positive box)."""
    rows = [json.loads(line) for line in open(path) if line.strip()]
    print(f"{len(rows)} traces, {np.median([r['seconds'] for r in rows]):.0f} s a fit (median)")
    for k in rows[0]["truth"]:
        covered = above = 0
        z = []
        for r in rows:
            t, e, ci = r["truth"][k], r["estimate"][k], r["ci"][k]
            above += e > t
            if ci is None:
                continue
            covered += ci[0] <= t <= ci[1]
            se = (math.log(ci[1]) - math.log(ci[0])) / (2 * 1.96)
            z.append((math.log(e) - math.log(t)) / se)
        print(
            f"  {k}: covered {covered} of {len(rows)}, above the truth {above}, "
            f"z sd {np.std(z, ddof=1) if len(z) > 1 else math.nan:.2f}, mean {np.mean(z):.2f}"
        )


if __name__ == "__main__":
    main()
