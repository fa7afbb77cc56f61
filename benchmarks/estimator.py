"""Speed and accuracy of the crossing-statistics estimator on the public reference set.

    python benchmarks/estimator.py [--json out.json]

Times (after compilation, reported apart) n1 on 3000 times, n2 on a 1000 x 1000 grid, each
first-passage approximation on [0, 7] and the slip-distance and period densities; and the
L1 distance of every approximation to the reference Monte Carlo histogram of slip times over
t in [0, 7] (bins of 0.1; bin averages of the density).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time
import warnings

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
PUBLIC = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
METHODS = [("truncation", 1, False), ("truncation", 1, True), ("decoupling", 1, False),
           ("truncation", 2, False), ("truncation", 2, True), ("decoupling", 2, False)]  # fmt: skip


def _timed(fn, repeat=3):
    out = fn()  # compile
    best = min(_once(fn) for _ in range(repeat))
    return out, best


def _once(fn):
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def l1_to_reference(est, method, order, normalized, ref):
    hist = ref["T_counts"] / ref["T_counts"].sum() / 0.1
    fine = np.linspace(0.0, 7.0, 7001)
    F = est.first_passage(fine, method, order, normalized=normalized)
    cells = np.array(
        [
            np.trapezoid(F[i * 100 : (i + 1) * 100 + 1], fine[i * 100 : (i + 1) * 100 + 1])
            for i in range(70)
        ]
    )  # noqa: E501
    return float(np.sum(np.abs(cells / 0.1 - hist[:70])) * 0.1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=pathlib.Path)
    parser.add_argument("--quick", action="store_true", help="smaller grids (a smoke test)")
    args = parser.parse_args(argv)
    import stickslip as ss

    warnings.simplefilter("ignore", ss.ApproximationWarning)
    ref = dict(np.load(ROOT / "tests" / "data" / "langevin_ou_public.npz"))
    model = ss.get_model("langevin")(**PUBLIC)
    rows = {}
    est = ss.CrossingEstimator(model)
    t3000 = np.linspace(0.01, 30.0, 300 if args.quick else 3000)
    start = time.perf_counter()
    est.n1(t3000)
    rows["n1, 3000 times: compile"] = time.perf_counter() - start
    rows["n1, 3000 times"] = _timed(lambda: est.n1(t3000))[1]
    t1000 = np.linspace(0.01, 10.0, 100 if args.quick else 1000)
    start = time.perf_counter()
    est.n2(t1000, t1000)
    rows["n2, 1000 x 1000 grid: compile + run"] = time.perf_counter() - start
    rows["n2, 1000 x 1000 grid"] = _timed(lambda: est.n2(t1000, t1000), repeat=2)[1]
    L1 = {}
    for method, order, normalized in METHODS[:3] if args.quick else METHODS:
        fresh = ss.CrossingEstimator(model)
        fresh.first_passage([1.0], method, order, normalized=normalized)  # compile kernels
        fresh = ss.CrossingEstimator(model)  # no cached grids
        start = time.perf_counter()
        L1[(method, order, normalized)] = l1_to_reference(fresh, method, order, normalized, ref)
        name = f"{'normalised ' if normalized else ''}{method} {order} on [0, 7], dt 0.01"
        rows[name] = time.perf_counter() - start
    dens = ss.CrossingEstimator(model, horizon=30.0)
    d = np.arange(-3.0, 9.0, 0.05) + 0.025
    T = np.arange(0.0, 60.0, 0.1) + 0.05
    for order in (1,) if args.quick else (1, 2):
        start = time.perf_counter()
        dens.slip_distance_density(d, "decoupling", order)
        dens.period_density(T, "decoupling", order)
        rows[f"p(d) and p(T), decoupling {order}, horizon 30 (incl. compile)"] = (
            time.perf_counter() - start
        )
    print("Crossing-statistics estimator, public reference set")
    for name, seconds in rows.items():
        print(f"  {name:62s} {seconds * 1e3:10.1f} ms")
    print("L1 distance to the reference Monte Carlo histogram, t in [0, 7], bins of 0.1:")
    for (method, order, normalized), value in L1.items():
        label = f"{'normalised ' if normalized else ''}{method} order {order}"
        print(f"  {label:40s} {value:.4f}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {"seconds": rows, "L1": {" ".join(map(str, k)): v for k, v in L1.items()}}, indent=2
            )
        )  # noqa: E501
    return rows, L1


if __name__ == "__main__":
    main()
