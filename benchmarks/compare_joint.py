"""`compare_fits` on fits of one slider to several runs: a fixed against a random static
threshold, on two force traces of the independent generator (`independent_slider.py`,
which shares no code with the library) on springs of 168 and 400 N/m.

    python benchmarks/compare_joint.py --gap-sd 0.0028 [--seed 500] [--n-sim 1000]
    python benchmarks/compare_joint.py --gap-sd 0          # the fixed threshold true
    python benchmarks/compare_joint.py --gap-sd 0 --again  # the fits' kept cycles' saving

Each trace is 200 s at 2 kHz with the generator's sensor noise, spikes, drift and a mains
hum, read by `extract_cycles`; both laws are fitted jointly to the two runs (`langevin`:
mass, noise and static friction free; `random-threshold-held`: mass, noise and the
threshold's mean and sd free; the kinetic friction, damping and noise time fixed at the
generator's; boxes not centred on the truth), then `compare_fits` chooses. Prints the
fits' estimates and times and the comparison's table.

The model-choice study over many sets reuses the fits of `fit_joint_independent.py
--keep DIR` (each set's runs and its fit of the law that made them, pickled): each set's
other law is fitted to the same runs with the same seed and boxes, the simpler law's
replicates drawn (`draw_replicates`), and `compare_fits` chooses; one JSON line a set:

    python benchmarks/compare_joint.py --kept DIR --log choice.jsonl [--jobs 2]
    python benchmarks/compare_joint.py --summary choice.jsonl
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


def chosen_on_kept(path: str) -> dict:
    """One set of the study: the kept runs and fit of the law that made them
    (`fit_joint_independent.py --keep`), the other law fitted with that script's boxes and
    seed, the comparison; its record."""
    import pickle

    import stickslip as ss

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import fit_joint_independent as study

    case, i = pathlib.Path(path).stem.rsplit("-", 1)
    with open(path, "rb") as f:
        kept = pickle.load(f)
    other = "random" if case == "fixed" else "fixed"
    model, free, fixed, _ = study.problem(other, kept["rig"])
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fits = {case: kept["fit"],
                other: ss.fit(model, kept["runs"], free, fixed, n_sim=kept["fit"].diagnostics[
                    "n_sim"], seed=60_000 + int(i))}  # fmt: skip
        fit_seconds = time.perf_counter() - t0
        fits = {k: fits[k] for k in ("fixed", "random")}  # (the simpler first)
        reps = ss.draw_replicates(fits["fixed"], seed=70_000 + int(i))
        c = ss.compare_fits(fits, replicates=[reps])
    (test,) = c.tests
    return dict(case=case, set=int(i), chosen=c.chosen_name, right=c.chosen_name == case,
                statistic=test["statistic"], p_values=test["p_values"],
                log_likelihood={k: float(r.log_likelihood) for k, r in fits.items()},
                fit_seconds=fit_seconds, seconds=time.perf_counter() - t0,
                warnings=c.warnings)  # fmt: skip


def study_main(args) -> None:
    """`--kept`: the study over every kept set (those in `--log` skipped); `--summary`."""
    import concurrent.futures
    import json

    if args.summary:
        rows = [json.loads(x) for f in args.summary for x in open(f) if x.strip()]
        for case in sorted({r["case"] for r in rows}):
            mine = [r for r in rows if r["case"] == case]
            right = sum(r["right"] for r in mine)
            p = sorted(max(r["p_values"]) for r in mine)
            print(f"{case} threshold true: the right law chosen in {right} of {len(mine)} "
                  f"sets; p-values (the larger of the two seeds') {p[0]:.3g} to {p[-1]:.3g}; "
                  f"{sum(r['seconds'] for r in mine) / len(mine):.0f} s a set")  # fmt: skip
        return
    done = set()
    if args.log and pathlib.Path(args.log).exists():
        done = {(r["case"], r["set"]) for r in (json.loads(x) for x in open(args.log)
                                                if x.strip())}  # fmt: skip
    paths = []  # the cases in turn, set by set (a study cut short has both)
    for p in sorted(pathlib.Path(args.kept).glob("*.pkl"),
                    key=lambda p: (int(p.stem.rsplit("-", 1)[1]), p.stem)):  # fmt: skip
        case, i = p.stem.rsplit("-", 1)
        if (case, int(i)) not in done and case in args.cases:
            paths.append(str(p))
    with concurrent.futures.ProcessPoolExecutor(args.jobs) as pool:
        for record in pool.map(chosen_on_kept, paths):
            line = json.dumps(record, default=float)
            if args.log:
                with open(args.log, "a") as f:
                    f.write(line + "\n")
            print(f"{record['case']} set {record['set']}: chose {record['chosen']}, 2 dlogL "
                  f"{record['statistic']}, p {record['p_values']}, {record['seconds']:.0f} s",
                  flush=True)  # fmt: skip


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gap-sd", type=float, default=None, help="the threshold's sd, N")
    parser.add_argument("--kept", default=None, help="the study over these kept sets")
    parser.add_argument("--log", default=None, help="the study's JSON lines (appended)")
    parser.add_argument("--jobs", type=int, default=1, help="the study's sets at once")
    parser.add_argument("--cases", nargs="+", default=["fixed", "random"],
                        help="the study's cases: the law that made the data")  # fmt: skip
    parser.add_argument("--summary", nargs="+", default=None, help="summarise study logs")
    parser.add_argument("--seed", type=int, default=500)
    parser.add_argument("--n-sim", type=int, default=1000)
    parser.add_argument("--again", action="store_true", help="time the comparison from the "
                        "fits' kept design cycles against the same simulated again")  # fmt: skip
    args = parser.parse_args(argv)
    if args.kept or args.summary:
        return study_main(args)
    if args.gap_sd is None:
        parser.error("--gap-sd is needed (or --kept / --summary for the study)")

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
    if args.again:
        again_main(ss, fits, comparison)


def again_main(ss, fits, comparison) -> None:
    """The comparison once more from the fits' kept design cycles and once with them
    simulated again (the same cycles: a function of the point, the run and the seed), both
    after the first comparison has compiled and warmed everything; the same statistics."""
    seconds = {}
    for how in ("simulated again", "kept"):
        designs = [r.diagnostics.design for r in fits.values()]
        kept = [d.samples for d in designs]
        if how == "simulated again":
            for d in designs:
                object.__setattr__(d, "samples", None)
        t0 = time.perf_counter()
        other = ss.compare_fits(fits, seed=11)
        seconds[how] = time.perf_counter() - t0
        for d, k in zip(designs, kept, strict=True):
            object.__setattr__(d, "samples", k)
        same = [t["statistic"] for t in other.tests] == [t["statistic"] for t in comparison.tests]
        print(f"compared from the design cycles {how}: {seconds[how]:.1f} s "
              f"({'the same' if same else 'OTHER'} statistics)")  # fmt: skip
    print(f"kept / simulated again: {seconds['kept'] / seconds['simulated again']:.3f}")


if __name__ == "__main__":
    main()
