"""The public paper-on-paper grid end to end: every run read in its regime, friction laws
fitted jointly to the stick-slip runs, and each stick-slip run predicted from a fit to the
others.

    python examples/campaign.py --out campaign-out [--n-sim 1000]

The six runs (N. Pustelnik and V. Vidal, CeCILL-B: credit and licence in
data/slider_paper_on_paper/README.md) span springs of 168, 1002 and 2254 N/m and driving
speeds of 42, 1100 and 4300 um/s. What it does:

1. `Campaign.from_yaml(campaigns/public_grid.yaml)`: each run's regime, the table of runs
   and the regime map (`DIR/campaign/`);
2. three laws fitted to the three stick-slip runs at once (`fit(model, [run, ...])`), one
   set of SI parameters for all three, each run through its own measurement, spring and
   speed: a normal random static threshold whose stick, past the next threshold, releases
   from where it is (`random-threshold-held`), a fixed threshold with a viscous kinetic
   friction, F_k + c times the slider's speed (`langevin`, the damping c free), and both
   at once; free in each: the effective mass, the friction-noise intensity and the static
   threshold (its mean and sd), and c where the law has it; fixed: the kinetic friction
   (the cycles see only the gap above it), the noise's correlation time, and a negligible
   c where the law has none (`--with-fixed`: the fixed threshold alone too);
3. `compare_fits` on the joint fits: the simplest law the data do not reject (a
   parametric bootstrap of sets of three runs, each through its own measurement; of two
   laws with as many free parameters, the likelier); the chosen law fitted again with
   profile-likelihood intervals (`--no-profile`: its Wald intervals, often none here)
   and saved as `DIR/campaign_fit.json` (`stickslip.load_fit`);
4. leave one out: each stick-slip run predicted (`FitResult.predict(run)`, through the
   run's own measurement) from the chosen law fitted to the two others: medians of stick
   time, slip time and force drop against the run's, KS p-values;
5. the regime the chosen fit predicts for each oscillating run (`predict(stiffness=,
   v_b=)`).

Writes `DIR/fits.md`, `DIR/leave_one_out.csv` and `.md`, and `DIR/summary.md`; prints
the summary. About 14 minutes on 2 quiet cores at `--n-sim 1000` (10 with
`--no-profile`), the fits in worker processes (`--workers`, 2 by default; docs/runs.md).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import csv
import math
import multiprocessing
import pathlib
import time
import warnings

HERE = pathlib.Path(__file__).resolve().parent
GRID = HERE / "campaigns" / "public_grid.yaml"
ZETA = 1e-3  # the damping c / (m omega0) at the first run's spring: negligible
TAU = 0.1  # the noise's correlation time in units of the first run's 1/omega0 (1.35 ms)
# The viscous kinetic friction's c (N s/m: F_k + c times the slip's speed over the track),
# from negligible to past critical damping at the softer spring (c / (m omega0) about 2
# for 30 g at 168 N/m).
DAMPING = (1e-4, 5.0)
OBSERVABLES = ("stick_time", "slip_time", "force_drop")


def candidates(reference, with_fixed=False):
    """{law: (model, free, fixed)} in SI, about the first run's reference slider: a random
    threshold, a viscous kinetic friction, both (and a fixed threshold, `with_fixed`)."""
    kinetic = reference.kinetic_friction
    omega0 = reference.scales.omega0
    fixed = dict(kinetic_friction=kinetic, noise_time=TAU / omega0)
    negligible = dict(damping=ZETA * reference.mass * omega0)
    shared = {"mass": (0.003, 0.1), "noise": (1e-10, 1e-6)}
    gap = (kinetic + 1e-3, kinetic + 0.03)  # F_s - F_k from 1 to 30 mN
    random = {"threshold.mean": gap, "threshold.sd": (1e-4, 0.02)}
    viscous = {"damping": DAMPING}
    laws = {
        "random threshold": ("random-threshold-held", shared | random, fixed | negligible),
        "viscous friction": ("langevin", shared | {"static_friction": gap} | viscous, fixed),
        "random threshold, viscous friction": (
            "random-threshold-held", shared | random | viscous, fixed),
    }  # fmt: skip
    if with_fixed:
        laws = {"fixed threshold": ("langevin", shared | {"static_friction": gap},
                                    fixed | negligible)} | laws  # fmt: skip
    return laws


def joint_fit(law, runs, n_sim, seed, intervals="wald"):
    import stickslip as ss

    model, free, fixed = law
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = ss.fit(model, runs, free, fixed, n_sim=n_sim, seed=seed, intervals=intervals)
    said = [str(w.message) for w in caught if str(w.message).startswith("fit:")]
    return r, said


def _g(x, digits=4):
    return f"{x:.{digits}g}" if x is not None and math.isfinite(x) else "-"


def fits_markdown(fits) -> str:
    lines = ["| law | parameter | estimate | 95 % interval |", "|---|---|---|---|"]
    for name, (r, _) in fits.items():
        for k, v in r.estimate.items():
            lo, hi = r.ci[k]
            lines.append(f"| {name} | {k} | {_g(v)} | [{_g(lo)}, {_g(hi)}] |")
    lines += ["", "| law | log-likelihood | free | per run: KS p (slip time, stick time, "
              "slip distance) |", "|---|---|---|---|"]  # fmt: skip
    for name, (r, _) in fits.items():
        runs = "; ".join(
            f"{row['name']}: " + ", ".join(_g(p, 2) for p in row["p_values"].values())
            for row in r.diagnostics["runs"]
        )
        lines.append(f"| {name} | {r.log_likelihood:.1f} | {len(r.estimate)} | {runs} |")
    return "\n".join(lines)


def left_out(law, stick, i, n_sim, seed):
    """Run i predicted from `law` fitted to the other stick-slip runs: its row (for a
    worker process)."""
    run = stick[i]
    others = [r for j, r in enumerate(stick) if j != i]
    r, said = joint_fit(law, others, n_sim, seed)
    p = r.predict(run.cycles)
    row = dict(run=run.settings["name"], stiffness=run.settings["stiffness"],
               v_b=run.settings["v_b"], fitted_to=" + ".join(
                   o.settings["name"] for o in others), regime=p.regime,
               evidence=p.evidence)  # fmt: skip
    for k, (model, data) in p.medians().items():
        row[f"{k}_predicted"] = model
        row[f"{k}_run"] = data
        row[f"{k}_ratio"] = data / model if model and data else math.nan
        row[f"{k}_p"] = p.p_values[k]
    row["warnings"] = len(said)
    return row


def compared(fits, seed):
    """`compare_fits` of the joint fits, its warnings left out (its summary lists them);
    for a worker process."""
    import stickslip as ss

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ss.compare_fits(fits, seed=seed)


def loo_markdown(rows) -> str:
    lines = [
        "| run | fitted to | regime | stick time: predicted, run (s) | slip time (ms) "
        "| force drop (mN) | KS p (stick, slip, drop) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['run']} | {r['fitted_to']} | {r['regime']} | "
            f"{_g(r['stick_time_predicted'], 3)}, {_g(r['stick_time_run'], 3)} | "
            f"{_g(1e3 * r['slip_time_predicted'], 3)}, {_g(1e3 * r['slip_time_run'], 3)} | "
            f"{_g(1e3 * r['force_drop_predicted'], 3)}, {_g(1e3 * r['force_drop_run'], 3)} | "
            + ", ".join(_g(r[f"{k}_p"], 2) for k in OBSERVABLES) + " |"
        )  # fmt: skip
    # a run the left-out fit does not predict to stick-slip: why (no medians to compare)
    lines += [f"\n{r['run']}, predicted {r['regime']}: {r['evidence']}" for r in rows
              if r["regime"] != "stick-slip"]  # fmt: skip
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="results folder (made; must not hold "
                        "other files)")  # fmt: skip
    parser.add_argument("--n-sim", type=int, default=1000, help="model cycles a point a run")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--force", action="store_true", help="replace an earlier result")
    parser.add_argument("--workers", type=int, default=2, help="processes at once: the "
                        "laws' fits, then the leave-one-out fits")  # fmt: skip
    parser.add_argument("--with-fixed", action="store_true", help="a fixed static "
                        "threshold too (the simplest law; the comparison then takes three "
                        "times the replicates)")  # fmt: skip
    parser.add_argument("--no-profile", action="store_true", help="keep the chosen law's "
                        "Wald intervals (its refit with profile-likelihood intervals, beside the "
                        "left-out fits, takes about 4 minutes more)")  # fmt: skip
    parser.add_argument("--check-only", action="store_true", help="read the runs and check "
                        "each law's box on them, fit nothing (seconds)")  # fmt: skip
    args = parser.parse_args(argv)

    import stickslip as ss

    t0 = time.perf_counter()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    campaign = ss.Campaign.from_yaml(GRID)
    campaign.write(out / "campaign", force=args.force)
    stick = [r for r in campaign.runs if r.regime == "stick-slip"]
    moving = [r for r in campaign.runs if r.regime != "stick-slip"]
    print(f"{len(campaign.runs)} runs read in {time.perf_counter() - t0:.1f} s:")
    for run in campaign.runs:
        print(f"  {run!r}: {run.evidence}")

    reference = ss.Slider.from_cycles(stick[0].cycles, mass=stick[0].settings["mass"])
    laws = candidates(reference, args.with_fixed)
    if args.check_only:  # each law's model on each run at its box's centre and corners
        for name, (model, free, fixed) in laws.items():
            for run in stick:
                slider = ss.Slider.from_cycles(run.cycles, mass=run.settings["mass"])
                for corner in (0, 1, None):
                    at = {k: (lo * hi) ** 0.5 if corner is None else (lo, hi)[corner]
                          for k, (lo, hi) in free.items()}  # fmt: skip
                    ss.get_model(model)(**slider.model_parameters({**fixed, **at}))
            print(f"{name}: {model}, {', '.join(free)} free: every run's model builds")
        return
    # The fits in worker processes (`--workers` at a time, a fresh JAX in each): the
    # laws side by side, then the comparison, then the leave-one-out fits of the chosen
    # law. The numbers do not depend on the workers or on the order the fits end in.
    fits = {}
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        t1 = time.perf_counter()
        # (the law with the most free parameters, the longest fit, first)
        jobs = {pool.submit(joint_fit, law, stick, args.n_sim, args.seed): name
                for name, law in sorted(laws.items(), key=lambda x: -len(x[1][1]))}  # fmt: skip
        for job in concurrent.futures.as_completed(jobs):
            name = jobs[job]
            fits[name] = job.result()
            print(f"{name}: fitted to {len(stick)} runs, done after "
                  f"{time.perf_counter() - t1:.0f} s")  # fmt: skip
            print("  " + fits[name][0].summary().replace("\n", "\n  "))
        fits = {name: fits[name] for name in laws}  # the laws' own order
        t1 = time.perf_counter()
        comparison = pool.submit(
            compared, {k: r for k, (r, _) in fits.items()}, args.seed + 100
        ).result()
        print(f"compared in {time.perf_counter() - t1:.0f} s")
        print("  " + comparison.summary().replace("\n", "\n  "))
        chosen = comparison.chosen_name
        best, said = fits[chosen]
        t1 = time.perf_counter()
        # the chosen law again with profile-likelihood intervals (the same estimate: the
        # intervals follow the likelihood where the surface's quadratic gives none),
        # beside the leave-one-out fits
        profiled = None if args.no_profile else pool.submit(
            joint_fit, laws[chosen], stick, args.n_sim, args.seed, "profile")
        loo = list(pool.map(left_out, [laws[chosen]] * len(stick), [stick] * len(stick),
                            range(len(stick)), [args.n_sim] * len(stick),
                            [args.seed] * len(stick)))  # fmt: skip
        print(f"leave one out: {time.perf_counter() - t1:.0f} s")
        if profiled is not None:
            best, said = profiled.result()
            print(f"{chosen}, profile intervals: {time.perf_counter() - t1:.0f} s")
            print("  " + best.summary().replace("\n", "\n  "))
        best.save(out / "campaign_fit.json")
    with open(out / "leave_one_out.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(loo[0]))
        writer.writeheader()
        writer.writerows(loo)
    regimes = []
    for run in moving:
        s = run.settings
        p = best.predict(stiffness=s["stiffness"], v_b=s["v_b"], seed=args.seed + 7)
        regimes.append(f"| {s['name']} | {run.regime} | {p.regime} ({p.evidence}) |")

    fits_md = fits_markdown(fits)
    loo_md = loo_markdown(loo)
    (out / "fits.md").write_text(fits_md + "\n")
    (out / "leave_one_out.md").write_text(loo_md + "\n")
    summary = "\n".join([
        f"# The public grid, {len(stick)} stick-slip runs fitted jointly",
        "", f"Chosen: **{chosen}** (`{laws[chosen][0]}`), saved as campaign_fit.json.", "",
        fits_md, "", "## The choice", "", "```", comparison.summary(), "```", "",
        f"## {chosen}: {'Wald' if args.no_profile else 'profile-likelihood'} intervals", "",
        fits_markdown({chosen: (best, said)}).split("\n\n")[0], "",
        *[f"- {w}" for w in said if "interval" in w], "",
        "## Each stick-slip run from a fit to the others", "", loo_md, "",
        "## The other runs: measured regime, predicted regime", "",
        "| run | measured | predicted |", "|---|---|---|", *regimes, "",
        f"{time.perf_counter() - t0:.0f} s in all, n_sim {args.n_sim}.",
    ])  # fmt: skip
    (out / "summary.md").write_text(summary + "\n")
    print(summary)


if __name__ == "__main__":
    main()
