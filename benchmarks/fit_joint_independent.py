"""Coverage of joint fits (`fit(model, [run, ...])`) on campaigns of an independent
generator: one slider (`independent_slider.Rig`: 17.8 g, its OU friction noise, its
thresholds) on several springs, each run a force trace through its own sensor, extracted
and fitted as a user fits measured runs.

    python benchmarks/fit_joint_independent.py --case fixed --sets 40 --log joint.jsonl
    python benchmarks/fit_joint_independent.py --summary joint.jsonl --out table.md

Cases (runs of 200 s at 2 kHz, springs of 168 and 400 N/m at 42 um/s, ~150 and ~330
cycles):

- `fixed`: a fixed threshold, fitted by `langevin`: the mass, the noise intensity and the
  static friction free (boxes not centred on the truth), the kinetic friction, damping
  and noise time fixed at the truth;
- `random`: a normal threshold of sd 2.8 mN, fitted by `random-threshold-held`: the mass,
  the noise, the threshold's mean and sd free.

Each run's reference slider is `Slider.from_cycles(cycles, mass=0.03)` (30 g: not the
truth). Data seeds 50000 + 10 i + run, fit seeds 60000 + i. The summary is
`fit_independent.py`'s: per parameter the sets covered, the share above the truth, the
spread of the estimates over the mean standard error.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import pathlib
import pickle
import sys
import time
import warnings

HERE = pathlib.Path(__file__).resolve().parent


def _load(name):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)
    spec.loader.exec_module(module)
    return module


gen = _load("independent_slider")
single = _load("fit_independent")
calibration = _load("profile_calibration")

DURATION = 200.0
SPRINGS = (168.0, 400.0)
COLUMNS = ("slip_time", "stick_time", "slip_distance")
REFERENCE_MASS = 0.03
CASES = {"fixed": dict(gap_sd=0.0, model="langevin"),
         "random": dict(gap_sd=2.8e-3, model="random-threshold-held")}  # fmt: skip


def problem(case: str, rig):
    """(model, free, fixed, truth) in SI."""
    fixed = {"kinetic_friction": rig.kinetic_friction, "damping": rig.damping,
             "noise_time": rig.noise_time}  # fmt: skip
    free = {"mass": (0.005, 0.05), "noise": (3e-9, 3e-7)}
    truth = {"mass": rig.mass, "noise": rig.noise_intensity}
    static = rig.kinetic_friction + rig.gap_mean
    if case == "fixed":
        free["static_friction"] = (0.093, 0.099)
        truth["static_friction"] = static
    else:
        free["threshold.mean"] = (0.093, 0.099)
        free["threshold.sd"] = (5e-4, 1e-2)
        truth["threshold.mean"] = static
        truth["threshold.sd"] = rig.gap_sd
    return CASES[case]["model"], free, fixed, truth


def campaign(case: str, i: int):
    """Set i's runs, each `(Cycles, reference Slider)`, and the generator's rig (the last
    spring's)."""
    import stickslip as ss

    runs, rig = [], None
    for j, k in enumerate(SPRINGS):
        rig = dataclasses.replace(gen.Rig(gap_sd=CASES[case]["gap_sd"], hum=1.5e-4),
                                  stiffness=k)  # fmt: skip
        t, force, _ = gen.make_trace(50_000 + 10 * i + j, DURATION, rig)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cycles = ss.extract_cycles(t, force=force, stiffness=k, v_b=rig.v_b)
        ref = ss.Slider.from_cycles(cycles, mass=REFERENCE_MASS)
        runs.append((ss.Cycles({c: cycles[c] for c in COLUMNS}, cycles.info), ref))
    return runs, rig


def _intervals_label(intervals: str, inner_se: float | None) -> str:
    """The intervals a record was made with (a resumed study skips the sets it has)."""
    return intervals if inner_se is None else f"{intervals}, inner {inner_se:g} SE"


def one_set(case: str, i: int, n_sim: int | None, keep: pathlib.Path | None = None,
            intervals: str = "wald", inner_se: float | None = None) -> dict:  # fmt: skip
    import stickslip as ss

    t0 = time.perf_counter()
    runs, rig = campaign(case, i)
    model, free, fixed, truth = problem(case, rig)
    with warnings.catch_warnings(record=True) as caught, \
            calibration.capped_inner_steps(inner_se):  # fmt: skip
        warnings.simplefilter("always")
        r = ss.fit(model, runs, free, fixed, n_sim=n_sim, seed=60_000 + i, intervals=intervals)
    d = r.diagnostics
    if keep is not None:  # the runs and the fit, for compare_joint.py's study (they pickle)
        keep.mkdir(parents=True, exist_ok=True)
        with open(keep / f"{case}-{i}.pkl", "wb") as f:
            pickle.dump(dict(runs=runs, fit=r, rig=rig), f)
    return dict(
        case=case, set=i, n_cycles=[row["cycles"] for row in d["runs"]],
        seconds=time.perf_counter() - t0, fit_seconds=d["seconds"],
        evaluations=d["evaluations"], estimate=r.estimate, ci=r.ci, truth=truth,
        intervals=_intervals_label(intervals, inner_se),
        profile=d["profile"],
        wald_ci=({k: v["wald"] for k, v in d["profile"].items()} if d["profile"] else r.ci),
        scales=d["scales"], p_values=[row["p_values"] for row in d["runs"]],
        dependence=dict(lag=d["dependence"].get("lag"), acf={}, se_ratio=None),
        warnings=[str(w.message) for w in caught if str(w.message).startswith("fit:")],
    )  # fmt: skip


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=list(CASES), default="fixed")
    parser.add_argument("--sets", type=int, default=40)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--n-sim", type=int, default=1000, help="fit's n_sim a run")
    parser.add_argument("--intervals", choices=("wald", "profile"), default="wald",
                        help="fit's intervals (profile: the Wald ones kept beside them)")
    parser.add_argument("--inner-se", type=float, default=None,
                        help="an experiment (profile_calibration.capped_inner_steps): the "
                        "profile's designs at most this many standard errors a step")  # fmt: skip
    parser.add_argument("--log", default=None, help="JSON lines, one a set (appended)")
    parser.add_argument("--keep", default=None,
                        help="a folder: each set's runs and fit pickled (CASE-SET.pkl)")
    parser.add_argument("--summary", nargs="+", default=None, help="summarise these logs")
    parser.add_argument("--out", default=None, help="write the summary table here")
    args = parser.parse_args()
    if args.summary:
        records = single._read(args.summary)
        text = single.table(single.summary(single._with_wald(records, reread=False)))
        parts = single.variance_parts(records)
        text += "\n\n" + parts if parts else ""
        print(text)
        if args.out:
            pathlib.Path(args.out).write_text(text + "\n")
        return
    label = _intervals_label(args.intervals, args.inner_se)
    done = {r["set"] for r in single._read([args.log]) if r["case"] == args.case
            and r.get("intervals", "wald") == label} if args.log else set()
    for i in range(args.first, args.first + args.sets):
        if i in done:
            continue
        record = one_set(args.case, i, args.n_sim,
                         None if args.keep is None else pathlib.Path(args.keep), args.intervals,
                         args.inner_se)  # fmt: skip
        line = json.dumps(record, default=float)
        if args.log:
            with open(args.log, "a") as f:
                f.write(line + "\n")
        shown = "; ".join(f"{k} {record['estimate'][k]:.4g} [{record['ci'][k][0]:.4g}, "
                          f"{record['ci'][k][1]:.4g}] (truth {record['truth'][k]:.4g})"
                          for k in record["estimate"])  # fmt: skip
        print(f"{args.case} set {i}: {shown}; {record['seconds']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
