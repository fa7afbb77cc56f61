"""Coverage of `fit`'s 95 % intervals over many simulated data sets (the bar:
each parameter's interval covers the truth in 88-99 % of >= 40 sets, and the spread of the
estimates matches the mean reported standard error within 20 %).

    python benchmarks/fit_coverage.py --case measured sticks joint [--sets 40] [--out cov.md]

(`--first 20 --sets 20` runs sets 20-39 alone: a run split over processes gives the same
per-set lines, whose summary `--from-logs` prints.)

Cases (the Langevin model at the public set, D = 0.4, tau = 0.1; boxes not centred on the
truth; data seeds 10000 + i, fit seeds 20000 + i, never the same):

- `measured`: cycles extracted (`extract_cycles`) from noisy sampled position traces
  (sampling interval 0.1, noise sd 1e-3, 4 paths of 600 time units, ~320 cycles), made
  here independently of the fit's forward model (a step ten times finer, each stick in
  closed form); D free (tau known), the measurement in the model;
- `measured2`: the same data, D and tau free;
- `sticks`: 1500 per-cycle stick times, their zero-length sticks in (~38 %), D free;
- `joint`: 1500 per-cycle slip and stick times of the same cycles, D and tau free.

Per parameter: how many intervals cover the truth, the sd of the estimates (log scale: the
intervals are Wald's in log coordinates) over the mean reported standard error (from the
interval's width), and the wall and CPU time. Each set's line is printed as it is done.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import re
import time
import warnings

import numpy as np

import stickslip as ss
from stickslip._inference.forward import simulate_values
from stickslip.extract import Cycles

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
TRUTH = dict(D=0.4, tau=0.1)
Z95 = 1.959963984540054
H, NOISE = 0.1, 1e-3  # the measured case's sampling interval and position noise


def _load_example(name):
    """A module of examples/ (the trace-sampling of `fit_trace.py`, shared, not copied)."""
    import importlib.util

    path = pathlib.Path(__file__).resolve().parents[1] / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# One path's position on a grid of spacing h: slips interpolated, sticks in closed form.
_sampled = _load_example("fit_trace").sampled_trace


def measured_data(seed, n_paths=4, t_max=600.0) -> Cycles:
    model = ss.get_model("langevin")(**BASE, **TRUTH)
    series = ss.simulate_cycles(model, n_paths, 0.01, t_max, seed=seed)
    rng = np.random.default_rng([seed, 1])
    found = []
    for p in range(n_paths):
        t, x = _sampled(series, p, t_max, H, BASE["v_b"])
        found.append(ss.extract_cycles(t, x + rng.normal(0.0, NOISE, x.size), v_b=1.0))
    table = {k: np.concatenate([c.table[k] for c in found]) for k in found[0].table}
    return Cycles(table, found[0].info)


def per_cycle(seed, n=1500) -> dict[str, np.ndarray]:
    """`n` per-cycle values (slips of positive length that ended; zero sticks kept)."""
    model = ss.get_model("langevin")(**BASE, **TRUTH)
    sim = simulate_values(model, int(n * 1.3) + 100, 0.2, 200.0, seed)
    return {k: v[:n] for k, v in sim.items()}


D_BOX = {"D": (0.1, 2.0)}  # log-centre 0.45
BOTH = {"D": (0.1, 2.0), "tau": (0.02, 0.8)}  # log-centres 0.45, 0.13
CASES = {
    "measured": (lambda s: measured_data(s), D_BOX),
    "measured2": (lambda s: measured_data(s), BOTH),
    "sticks": (lambda s: {"stick_time": per_cycle(s)["stick_time"]}, D_BOX),
    "joint": (lambda s: {k: per_cycle(s)[k] for k in ("slip_time", "stick_time")}, BOTH),
}


def run_case(case: str, sets: int, n_sim: int | None, first: int = 0) -> dict:
    make, free = CASES[case]
    fixed = {**BASE, **{k: v for k, v in TRUTH.items() if k not in free}}
    est = {k: [] for k in free}
    ses = {k: [] for k in free}
    cover = {k: 0 for k in free}
    warned = 0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for i in range(first, first + sets):
        data = make(10_000 + i)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = ss.fit("langevin", data, free, fixed, seed=20_000 + i, n_sim=n_sim, check=False)
        warned += bool(r.diagnostics["warnings"])
        line = []
        for k in free:
            lo, hi = r.ci[k]
            cover[k] += lo <= TRUTH[k] <= hi
            est[k].append(math.log(r.estimate[k]))
            ses[k].append(math.log(hi / lo) / (2 * Z95))
            line.append(f"{k} {r.estimate[k]:.4g} [{lo:.4g}, {hi:.4g}]")
        n = next(iter(r.diagnostics["n_data"].values()))
        print(f"{case} set {i}: {n} cycles, {'; '.join(line)}; {r.diagnostics['evaluations']} "
              f"points, {r.diagnostics['seconds']:.0f} s"
              + (f"; warned: {r.diagnostics['warnings']}" if r.diagnostics["warnings"] else ""),
              flush=True)  # fmt: skip
    out = dict(case=case, sets=sets, wall=time.perf_counter() - wall0,
               cpu=time.process_time() - cpu0, warned=warned, params={})  # fmt: skip
    for k in free:
        spread = float(np.std(est[k], ddof=1))
        mean_se = float(np.mean(ses[k]))
        bias = float(np.mean(est[k]) - math.log(TRUTH[k]))
        out["params"][k] = dict(cover=cover[k], spread=spread, se=mean_se,
                                ratio=spread / mean_se, bias=bias)  # fmt: skip
    return out


LINE = re.compile(r"(\w+) set (\d+): (\d+) cycles, (.*?); (\d+) points, (\d+) s(; warned)?")
PARAM = re.compile(r"(\w+) ([\d.e+-]+) \[([\d.e+-]+), ([\d.e+-]+)\]")


def from_logs(paths) -> list[dict]:
    """The summary of per-set lines printed by earlier runs (a run split over processes;
    a set found twice counts once); wall time: the fits' own seconds added up."""
    sets: dict = {}
    for path in paths:
        for line in pathlib.Path(path).read_text().splitlines():
            m = LINE.match(line)
            if m:
                params = {k: tuple(map(float, v)) for k, *v in PARAM.findall(m.group(4))}
                sets.setdefault(m.group(1), {})[int(m.group(2))] = (
                    params, float(m.group(6)), bool(m.group(7)),
                )  # fmt: skip
    results = []
    for case, rows in sets.items():
        rows = [rows[i] for i in sorted(rows)]
        out = dict(case=case, sets=len(rows), wall=sum(r[1] for r in rows), cpu=float("nan"),
                   warned=sum(r[2] for r in rows), params={})  # fmt: skip
        for k in rows[0][0]:
            est = np.log([r[0][k][0] for r in rows])
            ses = [math.log(r[0][k][2] / r[0][k][1]) / (2 * Z95) for r in rows]
            cover = sum(r[0][k][1] <= TRUTH[k] <= r[0][k][2] for r in rows)
            spread, mean_se = float(np.std(est, ddof=1)), float(np.mean(ses))
            out["params"][k] = dict(cover=cover, spread=spread, se=mean_se,
                                    ratio=spread / mean_se,
                                    bias=float(np.mean(est) - math.log(TRUTH[k])))  # fmt: skip
        results.append(out)
    return results


def table(results) -> str:
    lines = [
        "| case | parameter | covered | spread / mean SE | sd of log estimate | mean SE "
        "| mean log bias | fits that warned | wall (CPU) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        for k, p in r["params"].items():
            lines.append(
                f"| {r['case']} | {k} | {p['cover']}/{r['sets']} | {p['ratio']:.2f} | "
                f"{p['spread']:.4f} | {p['se']:.4f} | {p['bias']:+.4f} | {r['warned']} | "
                f"{r['wall']:.0f} s ({r['cpu']:.0f} s) |"
            )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--sets", type=int, default=40)
    parser.add_argument("--n-sim", type=int, default=None, help="fit's n_sim (its default)")
    parser.add_argument("--first", type=int, default=0, help="first set (to split a run)")
    parser.add_argument("--out", default=None, help="write the table as markdown here")
    parser.add_argument(
        "--from-logs", nargs="+", default=None, help="summarise earlier runs' per-set lines"
    )
    args = parser.parse_args()
    if args.from_logs:
        results = from_logs(args.from_logs)
    else:
        results = [run_case(c, args.sets, args.n_sim, args.first) for c in args.case]
    text = table(results)
    print(text)
    print("bar: covered 88-99 % of sets; spread / mean SE within 0.8-1.2")
    if args.out:
        pathlib.Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
