"""Accuracy against cost of every method, on three parameter sets: the accuracy-cost chart.

    python benchmarks/accuracy_cost.py [--quick] --out DIR [--package] [--reuse]

For each parameter set (the public reference set, the paper's fig. 6A set, and a set just
below the deterministic critical driving speed) every method is run and compared with a
high-accuracy reference, a large-N Monte Carlo with exact Gaussian stepping (computed once
and cached in benchmarks/.cache/):

- the level-crossing approximations F_n^(k), normalised F_n^(k) and F_g^(k), k = 1, 2
  (keys Fn1, Fn1_norm, Fg1, Fn2, Fn2_norm, Fg2);
- Monte Carlo with exact stepping (`mc_exact`) and with Euler-Maruyama (`mc_euler`), each at
  several steps dt and numbers of paths.

Error: the L1 distance of the slip-time density (and of the period density) to the
reference histogram on a common grid (cell averages of the analytic densities). Cost: the
wall time of the run once compiled (Monte Carlo: the median of the repeats, after a first
call of the same configuration that is not counted); what a first call costs beyond that
(compilation, or loading compiled code) is reported apart. Writes
`accuracy_cost.csv` (one row per method, set and output, with the Pareto front marked, the
reference's noise floor and the noise constant A: an N-path histogram's L1 noise is about
A / sqrt(N), and the time of `stickslip.selection.calibration_seconds`'s fixed workload on
this machine, by which `method: auto` scales the costs to the machine it runs on) and
`accuracy_cost.png` (log-log, error against run time, Pareto front drawn). `--package` also
copies the table to the package (`stickslip/_data/accuracy_cost.csv`), where `method: auto`
reads it. `--quick` (fewer configurations, a smaller reference) runs in a few minutes.
`--reuse` re-runs only the reference and the Monte Carlo rows (exact stepping and
Euler-Maruyama) of `--sets` and keeps the analytic rows of the packaged table (for a change
to the simulator alone: the analytic rows do not depend on it; their L1 was measured against
the previous reference, whose own noise floor is about 0.004).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import pathlib
import shutil
import time
import warnings

import numpy as np

from stickslip.stability import ANALYTIC_METHODS as ANALYTIC  # key -> (method, order, normalized)

ROOT = pathlib.Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / ".cache"
PACKAGE_TABLE = ROOT / "src" / "stickslip" / "_data" / "accuracy_cost.csv"

# Parameter sets. x0 = 1 and tau = 0.1 (OU friction noise, the well-posed model) throughout.
SETS = {
    "public": dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1),
    # Paper fig. 6A (quasiperiodic regime).
    "paper_fig6a": dict(omega0=2.0, zeta=0.1, D=3.0, v_b=1.25, x0=1.0, tau=0.1),
    # 0.93 of the deterministic critical speed v_c = 1.2335 of (omega0, zeta, x0) = (1, 0.1, 1):
    # a slip may miss its first stick and stick cycles later (the multiperiodic regime).
    "near_critical": dict(omega0=1.0, zeta=0.1, D=0.1, v_b=1.15, x0=1.0, tau=0.1),
}
FULL = dict(
    ref_paths=2_000_000,
    # Exact in law at any step (the bridge detector; tests/test_exact_detection.py checks it
    # against the independent reference data): the reference needs no small step.
    ref_dt=0.1,
    analytic=list(ANALYTIC),
    period_analytic=list(ANALYTIC),
    # Exact stepping is exact in law at any step (docs/simulator.md): large steps too.
    mc={"exact": [0.8, 0.4, 0.2, 0.1, 0.05, 0.02], "euler": [0.02, 0.01, 0.005, 0.002]},
    n_paths=[1_000, 3_000, 10_000, 30_000, 100_000, 300_000],
    repeats=3,
    max_period_order2_window=40.0,  # the position-resolved second order costs ~ window^2
)
QUICK = dict(
    ref_paths=300_000,
    ref_dt=0.1,
    analytic=["Fn1", "Fg1", "Fn2", "Fg2"],
    period_analytic=["Fg1"],
    max_order2_window=30.0,  # second order costs ~ window^2: skipped on longer windows
    mc={"exact": [0.4, 0.05], "euler": [0.01, 0.002]},
    n_paths=[1_000, 10_000, 100_000],
    repeats=1,
)
LONG = 20.0  # seconds: an analytic run this long is timed once (compile included)
T_MAX = 100.0  # longest slip followed (reference and runs alike)
SLIP_BINS, PERIOD_BINS = 150, 100
REF_SEED = 20261121
FIELDS = [
    "set", "output", "method", "family", "solver", "dt", "n_paths", "l1", "l1_sd", "repeats",
    "ref_floor", "noise_constant", "run_seconds", "compile_seconds", "path_steps", "pareto",
    "note", "params", "calibration_seconds",
]  # fmt: skip


def reference(name, params, n_paths, dt):
    """Slip times and periods of the reference run (cached by parameters, size and seed)."""
    import stickslip as ss

    tag = json.dumps([params, n_paths, dt, T_MAX, REF_SEED, ss.__version__], sort_keys=True)
    path = CACHE / f"reference-{name}-{hashlib.sha1(tag.encode()).hexdigest()[:12]}.npz"
    if path.exists():
        with np.load(path) as data:
            return {k: data[k] for k in data.files}, 0.0
    model = ss.get_model("langevin")(**params)
    start = time.perf_counter()
    ens = ss.simulate(model, n_paths, dt, T_MAX, seed=REF_SEED, solver="exact", progress=False)
    seconds = time.perf_counter() - start
    out = dict(slip_time=ens.slip_time, period=ens.period, seconds=np.array(seconds))
    CACHE.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **out)
    return out, seconds


def grid(values, bins):
    """Cells on [0, 99.9% quantile of the reference], rounded up."""
    top = float(np.nanquantile(values, 0.999))
    step = 10 ** math.floor(math.log10(top)) / 2
    return np.linspace(0.0, step * math.ceil(top / step), bins + 1)


def density(values, n_paths, edges):
    """Histogram of one run, normalised by all its paths (unstuck paths count as missing
    mass), and its standard errors."""
    from stickslip._histogram import counts as histogram_counts

    counts = histogram_counts(values, edges)  # np.histogram's counts, faster (nan not counted)
    p = counts / n_paths
    return p / np.diff(edges), np.sqrt(p * (1 - p) / n_paths) / np.diff(edges)


def run_mc(model, solver, dt, n_paths, seed, edges):
    """Densities of one Monte Carlo run; (densities, run s, compile s, path-steps)."""
    import stickslip as ss

    ens = ss.simulate(model, n_paths, dt, T_MAX, seed=seed, solver=solver, progress=False)
    start = time.perf_counter()
    out = {q: density(getattr(ens, q), n_paths, edges[q])[0] for q in edges}
    stats = ens.stats
    run = stats["wall_seconds"] - stats["compile_seconds"] + time.perf_counter() - start
    return out, run, stats["compile_seconds"], stats["path_steps"]


def run_analytic(model, key, q, edges):
    """One approximation of one density as cell averages; (values, run s, compile s, notes).
    The run time is that of a fresh estimator (no cached grids) once the kernels are
    compiled; the compile time is the extra of the first call."""
    import stickslip as ss

    args = ANALYTIC[key]
    centres = 0.5 * (edges[1:] + edges[:-1])

    def once():
        est = ss.CrossingEstimator(model)
        start = time.perf_counter()
        if q == "slip_time":
            values = est.first_passage_cells(edges, *args)
        else:
            values = est.period_density(centres, *args)
        return np.asarray(values, float), time.perf_counter() - start

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ss.ApproximationWarning)
        values, first = once()
        if first > LONG:  # compile time is small beside it: time the one run
            return values, first, math.nan, _notes(caught)
        values, run = once()
    return values, run, max(0.0, first - run), _notes(caught)


def _notes(caught):
    return "; ".join(sorted({str(w.message).split(";")[0].split(" (")[0] for w in caught}))


def l1(a, b, edges):
    return float(np.sum(np.abs(a - b) * np.diff(edges)))


def pareto(rows):
    """Mark the rows no other row beats in both error and run time (per set and output)."""
    for row in rows:
        row["pareto"] = not any(
            o is not row
            and o["set"] == row["set"]
            and o["output"] == row["output"]
            and o["l1"] <= row["l1"]
            and o["run_seconds"] <= row["run_seconds"]
            and (o["l1"] < row["l1"] or o["run_seconds"] < row["run_seconds"])
            for o in rows
        )


def measure(name, params, cfg, say):
    import stickslip as ss

    model = ss.get_model("langevin")(**params)
    ref, seconds = reference(name, params, cfg["ref_paths"], cfg["ref_dt"])
    say(
        f"[{name}] reference: {cfg['ref_paths']} paths, dt = {cfg['ref_dt']}"
        + (f" ({seconds:.0f} s)" if seconds else " (cached)")
    )
    n_ref = ref["slip_time"].size
    edges = {
        "slip_time": grid(ref["slip_time"], SLIP_BINS),
        "period": grid(ref["period"], PERIOD_BINS),
    }
    refd, floor = {}, {}
    for q, e in edges.items():
        refd[q], se = density(ref[q], n_ref, e)
        floor[q] = float(math.sqrt(2 / math.pi) * np.sum(se * np.diff(e)))
    say(
        f"[{name}] reference noise floor (L1): slip time {floor['slip_time']:.4f}, "
        f"period {floor['period']:.4f}"
    )
    rows = []

    def add(
        q,
        method,
        family,
        l1_,
        run,
        comp,
        solver="",
        dt="",
        n="",
        note="",
        sd=0.0,
        repeats=1,
        steps="",
    ):
        rows.append(
            dict(
                set=name,
                output=q,
                method=method,
                family=family,
                solver=solver,
                dt=dt,
                n_paths=n,
                l1=l1_,
                l1_sd=sd,
                repeats=repeats,
                ref_floor=floor[q],
                noise_constant=floor[q] * math.sqrt(n_ref),
                params=json.dumps(params, sort_keys=True),
                run_seconds=run,
                compile_seconds=comp,
                path_steps=steps,
                pareto=False,
                note=note,
            )
        )

    for q, keys in (("slip_time", cfg["analytic"]), ("period", cfg["period_analytic"])):
        for key in keys:
            limit = cfg.get("max_order2_window", math.inf)
            if q == "period":
                limit = min(limit, cfg.get("max_period_order2_window", math.inf))
            if ANALYTIC[key][1] == 2 and edges[q][-1] > limit:
                say(
                    f"[{name}] {q:9s} {key:9s} skipped (second order on a window of "
                    f"{edges[q][-1]:g} is too slow for this mode)"
                )
                continue
            values, run, comp, note = run_analytic(model, key, q, edges[q])
            add(q, key, "analytic", l1(values, refd[q], edges[q]), run, comp, note=note)
            say(f"[{name}] {q:9s} {key:9s} L1 {rows[-1]['l1']:.4f}  {run:.3f} s")
    seed = 1
    for solver, dts in cfg["mc"].items():
        for dt in dts:
            for n in cfg["n_paths"]:
                errs, runs, steps = {q: [] for q in edges}, [], []
                # A first call of the configuration, not counted: it compiles, or loads the
                # compiled code and warms it (the first call's extra time beyond a compiled
                # run is its own column). Timing the first call as a run put exact stepping
                # at 2-3x its compiled time in the table before 2026-11-25 (public set,
                # dt = 0.8, 1e5 paths: 0.66 s against 0.25 s compiled).
                _, first_run, first_comp, _ = run_mc(model, solver, dt, n, 10**6 + seed, edges)
                for _ in range(cfg["repeats"]):
                    seed += 1
                    dens, run, _, n_steps = run_mc(model, solver, dt, n, seed, edges)
                    runs.append(run), steps.append(n_steps)
                    for q in edges:
                        errs[q].append(l1(dens[q], refd[q], edges[q]))
                for q in edges:
                    sd = float(np.std(errs[q], ddof=1)) if len(errs[q]) > 1 else 0.0
                    add(
                        q,
                        f"mc_{solver}",
                        "mc",
                        float(np.mean(errs[q])),
                        float(np.median(runs)),
                        max(0.0, first_run + first_comp - float(np.median(runs))),
                        solver,
                        dt,
                        n,
                        sd=sd,
                        repeats=len(runs),
                        steps=int(np.mean(steps)),
                    )
                say(
                    f"[{name}] mc {solver:5s} dt {dt:<6g} N {n:<7d} "
                    f"L1 {rows[-2]['l1']:.4f} / {rows[-1]['l1']:.4f}  "
                    f"{rows[-1]['run_seconds']:.3f} s"
                )
    return rows, edges


def label(row):
    if row["family"] == "analytic":
        return row["method"]
    solver = "EM" if row["solver"] == "euler" else "exact"
    return f"{solver} dt={row['dt']:g} N={row['n_paths']:.0e}".replace("e+0", "e")


def chart(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sets = list(dict.fromkeys(r["set"] for r in rows))
    outputs = ["slip_time", "period"]
    fig, axes = plt.subplots(2, len(sets), figsize=(4.6 * len(sets), 8.0), squeeze=False)
    markers = {"Fn1": "v", "Fn1_norm": "<", "Fg1": "^", "Fn2": "D", "Fn2_norm": "d", "Fg2": "s"}
    dts = sorted({r["dt"] for r in rows if r["family"] == "mc"})
    cmap = plt.get_cmap("viridis")
    colour = {dt: cmap(i / max(1, len(dts) - 1)) for i, dt in enumerate(dts)}
    for j, s in enumerate(sets):
        for i, q in enumerate(outputs):
            ax = axes[i, j]
            mine = [r for r in rows if r["set"] == s and r["output"] == q]
            for r in mine:
                x, y = max(r["run_seconds"], 1e-4), r["l1"]
                if r["family"] == "analytic":
                    ax.scatter(
                        x,
                        y,
                        marker=markers[r["method"]],
                        s=55,
                        c="crimson",
                        edgecolors="k",
                        zorder=3,
                    )
                    ax.annotate(
                        r["method"],
                        (x, y),
                        textcoords="offset points",
                        xytext=(5, 3),
                        fontsize=7,
                        color="crimson",
                    )
                else:
                    size = 12 + 14 * math.log10(r["n_paths"] / 1e3 + 1)
                    ax.scatter(
                        x,
                        y,
                        marker="o" if r["solver"] == "exact" else "^",
                        s=size,
                        color=colour[r["dt"]],
                        alpha=0.85,
                        zorder=2,
                    )
            front = sorted((r for r in mine if r["pareto"]), key=lambda r: r["run_seconds"])
            if front:
                xs = [max(r["run_seconds"], 1e-4) for r in front]
                ax.step(
                    xs,
                    [r["l1"] for r in front],
                    where="post",
                    color="k",
                    lw=1.2,
                    zorder=1,
                    label="Pareto front",
                )
            if mine:
                ax.axhline(
                    mine[0]["ref_floor"], color="grey", ls=":", lw=1, label="reference noise floor"
                )
            for tol in (0.05, 0.02):
                ax.axhline(tol, color="tab:orange", ls="--", lw=0.7)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"{s}: {q.replace('_', ' ')} density", fontsize=10)
            ax.set_xlabel("run time (s, compiled)")
            ax.set_ylabel("L1 error")
            ax.grid(True, which="both", alpha=0.2)
    handles = [
        plt.Line2D([], [], ls="", marker="o", color="grey", label="MC exact stepping"),
        plt.Line2D([], [], ls="", marker="^", color="grey", label="MC Euler-Maruyama"),
        plt.Line2D([], [], ls="", marker="s", color="crimson", label="level-crossing"),
        plt.Line2D([], [], color="k", label="Pareto front"),
        plt.Line2D([], [], color="grey", ls=":", label="reference noise floor"),
        plt.Line2D([], [], color="tab:orange", ls="--", label="L1 = 0.05, 0.02"),
    ] + [plt.Line2D([], [], ls="", marker="o", color=colour[d], label=f"dt = {d:g}") for d in dts]
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=8, frameon=False)
    fig.suptitle("Accuracy against cost (marker size: number of paths)", fontsize=11)
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def read_csv(path):
    """Rows of a table written by `write_csv`, with numbers as numbers."""
    floats = (
        "l1", "l1_sd", "ref_floor", "noise_constant", "run_seconds", "compile_seconds",
        "calibration_seconds",
    )  # fmt: skip
    ints = ("n_paths", "repeats", "path_steps")
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            for k in floats:
                r[k] = float(r[k]) if r.get(k, "") != "" else ""
            for k in ints:
                r[k] = int(float(r[k])) if r[k] != "" else ""
            r["dt"] = float(r["dt"]) if r["dt"] != "" else ""
            r["pareto"] = r["pareto"] == "True"
            rows.append(r)
    return rows


def write_csv(rows, path):
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def summary(rows, say):
    """The fastest method reaching each tolerance, per set and output."""
    for s in dict.fromkeys(r["set"] for r in rows):
        for q in ("slip_time", "period"):
            mine = [r for r in rows if r["set"] == s and r["output"] == q]
            for tol in (0.2, 0.1, 0.05, 0.02):
                ok = [r for r in mine if r["l1"] <= tol]
                best = min(ok, key=lambda r: r["run_seconds"]) if ok else None
                text = (
                    f"{label(best)} (L1 {best['l1']:.4f}, {best['run_seconds']:.3g} s)"
                    if best
                    else "none measured"
                )
                say(f"  {s:13s} {q:9s} L1 <= {tol:<5g}: {text}")
            paper = [
                r
                for r in mine
                if r["solver"] == "euler" and r["dt"] == 0.002 and r["n_paths"] == 100_000
            ]
            if paper:
                r = paper[0]
                say(
                    f"  {s:13s} {q:9s} paper's method (EM dt=0.002, 1e5 paths): "
                    f"L1 {r['l1']:.4f}, {r['run_seconds']:.3g} s"
                )


def main(argv=None):
    # timed runs are of compiled code (see _baselines.py)
    __import__("os").environ.setdefault("STICKSLIP_COMPILE", "eager")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=pathlib.Path, required=True, help="output directory")
    parser.add_argument("--quick", action="store_true", help="fewer runs, smaller reference")
    parser.add_argument("--sets", nargs="+", choices=list(SETS), default=list(SETS))
    parser.add_argument(
        "--package",
        action="store_true",
        help="also install the table as the package's measured data",
    )
    parser.add_argument(
        "--reuse",
        action="store_true",
        help="keep the packaged analytic rows; re-run the Monte Carlo ones",
    )
    args = parser.parse_args(argv)
    import stickslip as ss  # noqa: F401  (imported before timing anything)
    from stickslip.selection import calibration_seconds

    # This machine's speed, for `method: auto` to scale the costs to the machine it runs on.
    calibration = [calibration_seconds.__wrapped__()]

    start = time.perf_counter()
    cfg = QUICK if args.quick else FULL
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    if args.reuse:
        cfg = dict(cfg, analytic=[], period_analytic=[])
        rows = [
            r
            for r in read_csv(PACKAGE_TABLE)
            if r["set"] not in args.sets or r["family"] == "analytic"
        ]
    for name in args.sets:
        rows += measure(name, SETS[name], cfg, lambda text: print(text, flush=True))[0]
    pareto(rows)
    calibration.append(calibration_seconds.__wrapped__())
    print(f"calibration workload: {min(calibration) * 1e3:.2f} ms (best of start and end)")
    for r in rows:
        r["calibration_seconds"] = min(calibration)
    write_csv(rows, args.out / "accuracy_cost.csv")
    chart(rows, args.out / "accuracy_cost.png")
    summary(rows, print)
    if args.package:
        PACKAGE_TABLE.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(args.out / "accuracy_cost.csv", PACKAGE_TABLE)
        print(f"installed {PACKAGE_TABLE.relative_to(ROOT)}")
    print(
        f"wrote {args.out / 'accuracy_cost.csv'} and accuracy_cost.png "
        f"in {time.perf_counter() - start:.0f} s"
    )


if __name__ == "__main__":
    main()
