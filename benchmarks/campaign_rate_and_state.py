"""The rate-and-state law fitted to stick-slip runs of the public grid at once, and compared
with the campaign's viscous kinetic friction on the same runs.

    python benchmarks/campaign_rate_and_state.py [--runs k1002Nm_v42.mat k168Nm_v1100.mat]
        [--n-sim 1000] [--grid 10] [--compare [--n-boot 19] [--alpha 0.1]] [--log FILE]

The runs are `examples/campaign.py`'s (its grid file; N. Pustelnik and V. Vidal,
CeCILL-B: credit and licence in `examples/data/slider_paper_on_paper/README.md`), each
through its own measurement, spring and speed; by default k = 1002 N/m at 42 um/s and
k = 168 N/m at 1100 um/s. The third stick-slip run (k = 168 N/m, 42 um/s) is left out for
cost: the law's noise-free drop there (44 mN at the orientation values) takes some 6 s of
loading, four times the run's sticks, and with it a point took about 6 minutes (seven
points in 42 minutes, the three runs; `--runs` with all three names fits it).
The law: `rate-and-state` with the plugin's orientation values for paper on paper (the
slider's 30.7 g, N 0.301 N, a 0.01, b 0.015, v_ref 1 um/s) and its Ornstein-Uhlenbeck
friction noise (tau 2 ms, D of 0.3 N a over M), the critical slip distance `d_c` free
over a box of 0.25-8 um (the orientation value 1 um is not its centre). One parameter:
each point is 1000 model cycles of each run through its measurement, and a fit of two
or more costs hours. The friction noise runs on a grid of tau / `--grid` (the plugin's
default is tau / 40; tau / 10, the default here, is 2-3 times cheaper a point and shifts
the model's measured drop by about 3 standard errors of 3000 cycles: docs/rate_and_state.md,
"Why tau/40").

Against it, the campaign's viscous kinetic friction (`langevin` with the damping free, its
fixed values about the grid's first run as in the example) fitted to the same runs; each
fit's log-likelihood of the data's values in SI is printed (the two are in different
units: `compare_fits` sets them side by side the same way). `--compare` runs
`compare_fits` too: the rate-and-state law, with fewer free parameters, is the simpler
candidate, so the bootstrap draws its replicates from it (`--n-boot` sets of the runs,
each at the run's number of cycles through its measurement; 33 minutes at 19 on the
default runs beside three other jobs, most of it those replicates); `--alpha` sets the
level (the smallest p-value `--n-boot` allows is 1 / (n_boot + 1)). Prints both fits,
their per-run KS p-values and the seconds each took; `--log` appends one JSON line.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import time
import warnings

HERE = pathlib.Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("campaign_example",
                                               HERE.parent / "examples" / "campaign.py")
campaign_example = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(campaign_example)

MASS, NORMAL_FORCE, A, TAU = 0.0307, 0.301, 0.01, 2e-3
ORIENTATION = dict(mass=MASS, normal_force=NORMAL_FORCE, mu0=0.3, a=A, b=0.015, v_ref=1e-6,
                   tau=TAU, D=(0.3 * NORMAL_FORCE * A / MASS) ** 2 * TAU)  # fmt: skip
D_C_BOX = (0.25e-6, 8e-6)  # m: the orientation value 1 um lies off its geometric centre
# The runs fitted by default: on the soft spring at 42 um/s the law's sticks load some 6 s
# (four times the run's), and with that run a point took ~6 minutes (the three runs).
RUNS = ("k1002Nm_v42.mat", "k168Nm_v1100.mat")


def si_log_likelihood(result) -> float:
    """A fit's log-likelihood of its data's values in SI (as `compare_fits` turns fits in
    other units: each value a density scores adds minus the log of its unit)."""
    from stickslip._inference import compare

    columns = [d for d, _, _ in compare._runs_of(result)]
    return result.log_likelihood + float(compare.si_shift(columns, compare._units_of(result))[0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-sim", type=int, default=1000)
    parser.add_argument("--grid", type=int, default=10, help="noise grid tau / GRID")
    parser.add_argument("--compare", action="store_true", help="compare_fits too (its "
                        "replicates are the rate-and-state law's: about half an hour)")
    parser.add_argument("--n-boot", type=int, default=19)
    parser.add_argument("--alpha", type=float, default=0.1)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--runs", nargs="+", default=list(RUNS), help="the stick-slip runs "
                        "fitted, by file name")  # fmt: skip
    parser.add_argument("--log", default=None)
    args = parser.parse_args(argv)

    import stickslip as ss

    campaign = ss.Campaign.from_yaml(campaign_example.GRID)
    every = [r for r in campaign.runs if r.regime == "stick-slip"]
    stick = [r for r in every if r.settings["name"] in args.runs]
    # the viscous law's fixed values as in the example: about the grid's first run
    reference = ss.Slider.from_cycles(every[0].cycles, mass=every[0].settings["mass"])
    fits, seconds = {}, {}
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fits["rate and state"] = ss.fit(
            "rate-and-state", stick, {"d_c": D_C_BOX}, ORIENTATION, n_sim=args.n_sim,
            seed=args.seed, dt=TAU / args.grid,
        )  # fmt: skip
    seconds["rate and state"] = time.perf_counter() - t0
    said = [str(w.message) for w in caught if str(w.message).startswith("fit:")]
    print(f"rate and state: {seconds['rate and state']:.0f} s, "
          f"{fits['rate and state'].diagnostics.evaluations} points", flush=True)  # fmt: skip
    print(fits["rate and state"].summary(), flush=True)
    t0 = time.perf_counter()
    law = campaign_example.candidates(reference)["viscous friction"]
    fits["viscous friction"], _ = campaign_example.joint_fit(law, stick, args.n_sim, args.seed)
    seconds["viscous friction"] = time.perf_counter() - t0
    print(f"viscous friction: {seconds['viscous friction']:.0f} s", flush=True)
    print(fits["viscous friction"].summary(), flush=True)
    si = {name: si_log_likelihood(r) for name, r in fits.items()}
    print("log-likelihood of the values in SI: "
          + ", ".join(f"{name} {v:.1f}" for name, v in si.items()))  # fmt: skip
    comparison = None
    if args.compare:
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            comparison = ss.compare_fits(fits, alpha=args.alpha, n_boot=args.n_boot,
                                         seed=args.seed + 100)  # fmt: skip
        seconds["compare_fits"] = time.perf_counter() - t0
        print(f"compare_fits: {seconds['compare_fits']:.0f} s")
        print(comparison.summary())
    if args.log:
        record = dict(
            runs=args.runs, n_sim=args.n_sim, grid=args.grid, n_boot=args.n_boot, alpha=args.alpha,
            seconds=seconds, warnings=said, si_log_likelihood=si,
            chosen=None if comparison is None else comparison.chosen_name,
            fits={name: dict(
                estimate=r.estimate, ci={k: list(v) for k, v in r.ci.items()},
                log_likelihood=r.log_likelihood, evaluations=r.diagnostics.evaluations,
                runs=[dict(name=row["name"], p_values=row["p_values"])
                      for row in r.diagnostics["runs"]],
            ) for name, r in fits.items()},
            comparison=None if comparison is None else comparison.summary(),
            tests=None if comparison is None else comparison.tests,
        )  # fmt: skip
        with open(args.log, "a") as fh:
            fh.write(json.dumps(record, default=float) + "\n")


if __name__ == "__main__":
    main()
