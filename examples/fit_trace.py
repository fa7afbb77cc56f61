"""From a measured trace to friction-noise parameters: trace -> cycles -> fit -> figure.

    python examples/fit_trace.py --out results-fit [--paths 8] [--t-max 800] [--noise 1e-3]

A stand-in for a measurement: the Langevin model with OU friction noise (the public set:
omega0 = 1, zeta = 0.1, x0 = 1, v_b = 1, D = 0.4, tau = 0.1) run through successive cycles
(`simulate_cycles`, several independent traces), its position sampled every 0.1 time units
(a tenth of the slip time scale) with Gaussian measurement noise of sd `--noise`. Then, as a
user with a real trace would:

1. `trace.csv` (columns t, x, trace) -> `extract_cycles` per trace -> `cycles.csv`, written
   by `Cycles.to_csv` with the extraction's settings in its `# stickslip cycles` header (the
   command line does the same: `stickslip cycles trace.csv --v-b 1 --out cycles.csv` for a
   single trace);
2. a study with a fit block (`fit_study.yaml`: D and tau free, the other parameters known)
   run by `run_fit`, which is what `stickslip fit fit_study.yaml --out fit` does: the
   cycles file carries its measurement, so the model is simulated as a trace, sampled,
   made noisy and extracted alike (`fit/fit.json`, `fit/fit.png`, `fit/summary.md`, with
   the goodness-of-fit p-values and whether the data reject the model);
3. the estimates printed beside the truth.

At the defaults: about 1000 cycles, a few minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np

PARAMS = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
SAMPLE = 0.1  # sampling interval of the "measurement"


def sampled_trace(series, path, t_max, h, v_b):
    """Position of one simulated path on a grid of spacing `h` (slips interpolated between
    the simulator's samples, sticks in closed form: x grows at v_b from the stick)."""
    t, states, slipping = series.trajectory(path)
    rows = series.cycles["path"] == path
    cyc = {k: series.cycles[k][rows] for k in ("release_time", "slip_time", "period")}
    grid = np.arange(0.0, t_max, h)
    x = np.full(grid.size, np.nan)
    ends = np.nonzero(~slipping)[0]
    starts = np.concatenate([[0], ends[:-1] + 1])
    for c, (s, e) in enumerate(zip(starts, ends, strict=False)):
        t0, t_sl, period = cyc["release_time"][c], cyc["slip_time"][c], cyc["period"][c]
        slip = (grid >= t0) & (grid < t0 + t_sl)
        x[slip] = np.interp(grid[slip], t[s : e + 1], states[s : e + 1, 0])
        stick = (grid >= t0 + t_sl) & (grid < t0 + period)
        x[stick] = states[e, 0] + v_b * (grid[stick] - (t0 + t_sl))
    ok = np.isfinite(x)
    return grid[ok], x[ok]


def main(argv=None):
    import yaml

    import stickslip as ss
    from stickslip.study import run_fit

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results-fit")
    parser.add_argument("--paths", type=int, default=8)
    parser.add_argument("--t-max", type=float, default=800.0)
    parser.add_argument("--noise", type=float, default=1e-3)
    parser.add_argument("--n-sim", type=int, default=None, help="default: fit's (4000)")
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    wall = time.perf_counter()

    # the "measurement"
    model = ss.get_model("langevin")(**PARAMS)
    series = ss.simulate_cycles(model, args.paths, 0.01, args.t_max, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    traces = []
    for p in range(args.paths):
        t, x = sampled_trace(series, p, args.t_max, SAMPLE, PARAMS["v_b"])
        traces.append((t, x + rng.normal(0.0, args.noise, x.size)))
    np.savetxt(
        out / "trace.csv",
        np.concatenate([np.column_stack([t, x, np.full(t.size, p)]) for p, (t, x) in
                        enumerate(traces)]),
        delimiter=",", header="t,x,trace", comments="", fmt="%.10g",
    )  # fmt: skip

    # 1. trace -> cycles (one table; the settings of the first trace's extraction, which
    # the others share: the same sampling, noise level and rules)
    found = [ss.extract_cycles(t, x, v_b=PARAMS["v_b"]) for t, x in traces]
    table = {k: np.concatenate([c.table[k] for c in found]) for k in found[0].table}
    ss.Cycles(table, found[0].info).to_csv(out / "cycles.csv")
    print(f"{table['slip_time'].size} cycles from {args.paths} traces of {args.t_max:g}")

    # 2. cycles -> fit (a study file, as `stickslip fit` runs it)
    known = {k: v for k, v in PARAMS.items() if k not in ("D", "tau")}
    study = {
        "title": "Friction noise from a measured trace",
        "description": "D and tau of the OU friction noise from slip times extracted from a "
        "sampled, noisy position trace.",
        "model": {"name": "langevin", "params": PARAMS},
        "simulation": None,
        "analytic": [{"method": "decoupling", "order": 1}],
        "fit": {
            "data": "cycles.csv", "columns": ["slip_time", "stick_time"],
            "free": {"D": [0.05, 2.0], "tau": [0.01, 1.0]}, "seed": 0,
        },
    }  # fmt: skip
    if args.n_sim is not None:
        study["fit"]["n_sim"] = args.n_sim
    (out / "fit_study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    result = run_fit(out / "fit_study.yaml", out / "fit", force=True)

    # 3. against the truth
    print(result.summary())
    for k in ("D", "tau"):
        lo, hi = result.ci[k]
        inside = "inside" if lo <= PARAMS[k] <= hi else "OUTSIDE"
        print(f"  truth {k} = {PARAMS[k]}: {inside} the interval")
    print(f"known: {known}; {time.perf_counter() - wall:.0f} s; figure {out / 'fit' / 'fit.png'}")
    return result


if __name__ == "__main__":
    main()
