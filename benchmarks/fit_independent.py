"""Coverage of `fit`'s intervals on force traces from a generator that shares no code with
the fit (`independent_slider.py`: its own exact-in-law integrator, OU friction noise started
at zero at each release, thresholds drawn by its own truncated normal, its own sensor:
white noise, spikes, a slow drift, a 50 Hz hum), fitted through the measurement as a user
fits a measured trace: `extract_cycles` on the force, then
`fit(model, cycles, free, fixed, scales=slider)`.

    python benchmarks/fit_independent.py --case random --sets 40 --jobs 2 --log random.jsonl
    python benchmarks/fit_independent.py --case fixed --sets 40 --jobs 2 --log fixed.jsonl
    python benchmarks/fit_independent.py --summary random.jsonl fixed.jsonl --out table.md
    python benchmarks/fit_independent.py --case random --release stick --data model ...

Cases (300 s traces at 2 kHz, the rig of `independent_slider.Rig`: an effective mass of
17.8 g on a 168 N/m spring driven at 42 um/s, like the measured paper slider's fit):

- `random`: a normal static threshold, F_s - F_k of mean 4.47 mN and sd 2.8 mN (~180
  cycles a trace), fitted by `random-threshold`: the natural frequency `omega0`, the
  friction-noise intensity `D`, the threshold's `mean` and `sd` free;
- `fixed`: the same rig with a fixed threshold (sd 0, ~230 cycles), fitted by `langevin`:
  `omega0`, `D`, `x0` free.

The truth in the model's units is the rig mapped through `stickslip.Slider` (its
`dimensionless()`), which also gives the fit its units (`scales`); the boxes are the
measured slider example's (`examples/slider_fit.py`), whose centres are not the truth. Known:
zeta, tau (the rig's) and v_b (the rig's; the extraction measures it within 0.1 % here).
Data seeds 30000 + i, fit seeds 40000 + i. Each set's result is one JSON line in `--log`
(sets already there are skipped: a run can be resumed or split over processes); `--summary`
reads them back: per parameter the sets covered, the share of estimates above the truth,
the sd of the estimates (fit coordinates) over the mean reported standard error, the mean
bias, and the scores' lag-1 autocorrelation with the intervals' widening for it.

`--data model` fits the model's own data instead, as a control: set i's cycles made by the
fit's forward model at the truth (`measured_cycles`, seed 90000 + i) through the
measurement read from generator trace i, as many as that trace gave. A lean that stays
there is the estimator's; one that goes is the generator's data (physics, sensor,
extraction) differing from the model's. `--own-cycles 4`: four times as many cycles a set
(a lean of the estimator's that shrinks with the data is a small-sample one).
`--likelihood pair` (an experiment, `_pair_likelihood.py`): each stick time scored given
the drop before it, in place of its marginal density.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import importlib.util
import json
import math
import pathlib
import sys
import time
import warnings

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("independent_slider", HERE / "independent_slider.py")
gen = importlib.util.module_from_spec(_spec)
sys.modules.setdefault(_spec.name, gen)
_spec.loader.exec_module(gen)

Z95 = 1.959963984540054
DURATION = 300.0
COLUMNS = ("slip_time", "stick_time", "slip_distance")
BOX = {
    "omega0": (0.5, 3.0),
    "D": (0.02, 3.0),
    "threshold": (0.3, 2.0),
    "sd": (0.0, 1.5),
    "cv": (0.0, 0.95),
}
CASES = {
    "random": dict(gap_sd=2.8e-3, model="random-threshold"),
    "fixed": dict(gap_sd=0.0, model="langevin"),
}


def rig_of(case: str) -> gen.Rig:
    return gen.Rig(gap_sd=CASES[case]["gap_sd"], hum=1.5e-4)


def truth_slider(rig):
    """The rig as a `stickslip.Slider` (SI), whose dimensionless form is the truth."""
    import stickslip as ss

    threshold = None
    static = None
    if rig.gap_sd > 0:
        law = {"mean": rig.kinetic_friction + rig.gap_mean, "sd": rig.gap_sd}
        threshold = ("normal", law)
    else:
        static = rig.kinetic_friction + rig.gap_mean
    return ss.Slider(
        mass=rig.mass, stiffness=rig.stiffness, v_b=rig.v_b, static_friction=static,
        kinetic_friction=rig.kinetic_friction, damping=rig.damping,
        noise=rig.noise_intensity, noise_time=rig.noise_time, threshold=threshold,
    )  # fmt: skip


def problem(case: str, release: str = "threshold", coords: str = "normal"):
    """(model name, free boxes, fixed values, truth of the free parameters) in model units;
    `release="stick"`: the random threshold fitted by `random-threshold-held` (a stick past
    its next threshold releases from where it is, as the generator's does)."""
    rig = rig_of(case)
    dim = truth_slider(rig).dimensionless()
    known = dict(zeta=dim["zeta"], v_b=dim["v_b"], tau=dim["tau"])
    shared = {"omega0": BOX["omega0"], "D": BOX["D"]}
    if case == "random":
        free = {**shared, "threshold_params.mean": BOX["threshold"],
                "threshold_params.sd": BOX["sd"]}  # fmt: skip
        truth = dict(omega0=dim["omega0"], D=dim["D"], **{
            "threshold_params.mean": dim["threshold_params"]["mean"],
            "threshold_params.sd": dim["threshold_params"]["sd"]})  # fmt: skip
        model = "random-threshold-held" if release == "stick" else "random-threshold"
        if coords == "moments":  # the truncated law's own mean and cv (an experiment)
            import truncated_moments as tm

            m, s = tm.moments(truth.pop("threshold_params.mean"),
                              truth.pop("threshold_params.sd"))  # fmt: skip
            truth.update({"threshold_params.mean": m, "threshold_params.cv": s / m})
            free.pop("threshold_params.sd")
            free["threshold_params.cv"] = BOX["cv"]
            return model, free, {**known, "threshold": "normal-moments"}, truth
        return model, free, {**known, "threshold": "normal"}, truth
    free = {**shared, "x0": BOX["threshold"]}
    return "langevin", free, known, dict(omega0=dim["omega0"], D=dim["D"], x0=dim["x0"])


def truth_model(case: str, release: str = "stick", noise: float = 1.0):
    """The fitted model at the truth (its noise intensity D times `noise`)."""
    import stickslip as ss

    dim = truth_slider(rig_of(case)).dimensionless()
    name = problem(case, release)[0]
    params = {k: dim[k] for k in ("omega0", "zeta", "D", "v_b", "tau")}
    params["D"] *= noise
    if case == "random":
        return ss.get_model(name)(**params, threshold="normal",
                                  threshold_params=dim["threshold_params"])  # fmt: skip
    return ss.get_model(name)(**params, x0=dim["x0"])


def model_data(data, case: str, release: str, slider, seed: int, factor: float = 1.0):
    """The model's own cycles at the truth through `data`'s measurement, `factor` times as
    many as `data` has, in SI (the `--data model` control)."""
    import stickslip as ss
    from stickslip._inference.measurement import Measurement, measured_cycles

    n = int(round(factor * len(data["slip_time"])))
    # each path's cut first and last cycles are dropped: simulate half as many again
    table = measured_cycles(
        truth_model(case, release), Measurement.from_cycles(data, scales=slider), int(1.5 * n), seed
    )
    s = slider.scales
    unit = {"slip_time": s.time, "stick_time": s.time, "slip_distance": s.length}
    return ss.Cycles({k: table[k][:n] * unit[k] for k in COLUMNS}, data.info)


def one_set(case: str, i: int, n_sim: int | None, release: str = "threshold",
            keep: pathlib.Path | None = None, coords: str = "normal",
            intervals: str = "wald", source: str = "generator",
            factor: float = 1.0, likelihood: str = "marginal") -> dict:  # fmt: skip
    """Make trace i, extract its cycles, fit them; the record of the set (`keep`: the
    cycles and the fit pickled there too, for a later look at the fit's surface).
    `source="model"`: fit the model's own cycles through that trace's measurement,
    `factor` times as many. `likelihood="pair"`: stick times scored given their drops
    (`_pair_likelihood`, an experiment)."""
    import stickslip as ss

    if likelihood == "pair":
        spec = importlib.util.spec_from_file_location("_pair_likelihood",
                                                      HERE / "_pair_likelihood.py")  # fmt: skip
        pair = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(pair)
        pair.install()
    from stickslip._inference.likelihood import cycle_log_likelihood

    rig = rig_of(case)
    slider = truth_slider(rig)
    model, free, fixed, truth = problem(case, release, coords)
    t0 = time.perf_counter()
    t, force, true = gen.make_trace(30_000 + i, DURATION, rig)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycles = ss.extract_cycles(t, force=force, stiffness=rig.stiffness, v_b=rig.v_b)
    data = ss.Cycles({k: cycles[k] for k in COLUMNS}, cycles.info)  # (period: slip + stick)
    if source == "model":
        data = model_data(data, case, release, slider, 90_000 + i, factor)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = ss.fit(model, data, free, fixed, scales=slider, n_sim=n_sim, seed=40_000 + i,
                   check=False, intervals=intervals)  # fmt: skip
    scales = r.diagnostics["scales"]
    d = r.diagnostics.get("dependence", {})
    mc = r.diagnostics.get("mc_noise", {})
    # the log-likelihood at the truth (the fit's seed and simulation): did the search find
    # a maximum above it?
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        at_truth = float(np.sum(cycle_log_likelihood(r, truth)))
    if keep is not None:
        import pickle

        keep.mkdir(parents=True, exist_ok=True)
        tag = ("" if coords == "normal" else f"-{coords}") + (
            "" if intervals == "wald" else f"-{intervals}"
        )
        with open(keep / f"{case}-{release}{tag}-{i}.pkl", "wb") as f:
            pickle.dump(dict(cycles=data, fit=r, truth=truth), f)
    x_unit = slider.scales.length
    gaps = np.asarray(true["threshold"]) - rig.kinetic_friction - rig.damping * rig.v_b
    return dict(
        case=case,
        release=release,
        coords=coords,
        intervals=intervals,
        data=source if factor == 1.0 else f"{source} x{factor:g}",
        likelihood=likelihood,
        set=i,
        n_cycles=len(data["slip_time"]),
        seconds=time.perf_counter() - t0,
        fit_seconds=r.diagnostics["seconds"],
        evaluations=r.diagnostics["evaluations"],
        estimate=r.estimate,
        ci=r.ci,
        wald_ci=(
            {k: v["wald"] for k, v in r.diagnostics.profile.items()}
            if r.diagnostics.profile
            else r.ci
        ),  # fmt: skip
        profile=r.diagnostics.profile,
        truth=truth,
        scales=scales,
        v_b_ratio=cycles.info["v_b_estimated"] / rig.v_b,
        window=cycles.info["window"],
        sample_threshold_mean=float(np.mean(gaps / (rig.stiffness * x_unit))),
        sample_threshold_sd=float(np.std(gaps / (rig.stiffness * x_unit), ddof=1)),
        dependence=dict(
            lag=d.get("lag"),
            acf={k: v[:2] for k, v in d.get("acf", {}).items()},
            se_ratio=d.get("se_ratio"),
        ),  # fmt: skip
        warnings=[str(w.message) for w in caught if str(w.message).startswith("fit:")],
        log_likelihood=r.log_likelihood,
        log_likelihood_at_truth=at_truth,
        mc_sd=mc.get("sd"),
        mc_ratio=mc.get("ratio"),
        covariance=r.diagnostics["covariance"],
        steps=r.diagnostics["design"]["steps"],
    )


def _to_fit(scale, x):
    return math.log(x) if scale == "log" else x


def _label(record: dict) -> str:
    """A record's case, and the release rule where it is not the registered model's."""
    release = record.get("release", "threshold")
    coords = record.get("coords", "normal")
    intervals = record.get("intervals", "wald")
    source = record.get("data", "generator")
    return (record["case"] + ("" if release == "threshold" else f" (release from the {release})")
            + ("" if coords == "normal" else f" ({coords})")
            + ("" if intervals == "wald" else f" ({intervals} intervals)")
            + ("" if source == "generator" else f" ({source}'s own data)")
            + ("" if record.get("likelihood", "marginal") == "marginal"
               else ", stick given drop"))  # fmt: skip


def _with_wald(records: list[dict], reread: bool = True) -> list[dict]:
    """The records, and for each fit with profile intervals its Wald intervals as a record
    of their own (the same estimates: the two rules compared on the same fits). With
    `reread` (single-run records), profile intervals are read again from each record's
    tries with this version's rule (`read_ends`), so that a log of an earlier version is
    summarised as this one reads it."""
    from stickslip._inference.params import from_fit_coords
    from stickslip._inference.profile import read_ends

    out = []
    for r in records:
        if r.get("intervals", "wald") != "profile" or not reread:
            out.append(r)
            if r.get("intervals", "wald") == "profile":
                out.append({**r, "ci": r["wald_ci"], "intervals": "profile's fits, Wald"})
            continue
        _, free, _, _ = problem(r["case"], r.get("release", "threshold"), r.get("coords", "normal"))
        ci = {}
        for k, v in r["profile"].items():
            lo, hi = (_to_fit(r["scales"][k], b) if b > 0 or r["scales"][k] != "log" else -math.inf
                      for b in free[k])  # fmt: skip
            ci[k] = tuple(from_fit_coords(r["scales"][k], e) for e in read_ends(v, lo, hi))
        out.append({**r, "ci": ci})
        out.append({**r, "ci": r["wald_ci"], "intervals": "profile's fits, Wald"})
    return out


def summary(records: list[dict]) -> list[dict]:
    rows = []
    for case in sorted({_label(r) for r in records}):
        sets = sorted((r for r in records if _label(r) == case), key=lambda r: r["set"])
        for k in sets[0]["estimate"]:
            scale = sets[0]["scales"][k]
            truth = sets[0]["truth"][k]
            est, se, cover, above, lag1, lag2, widen = [], [], 0, 0, [], [], []
            for r in sets:
                lo, hi = r["ci"][k]
                e = _to_fit(scale, r["estimate"][k])
                est.append(e)
                if math.isfinite(lo) and math.isfinite(hi) and (scale != "log" or lo > 0):
                    se.append((_to_fit(scale, hi) - _to_fit(scale, lo)) / (2 * Z95))
                    cover += lo <= truth <= hi
                above += r["estimate"][k] > truth
                acf = (r["dependence"].get("acf") or {}).get(k)
                if acf:
                    lag1.append(acf[0])
                    lag2.append(acf[1] if len(acf) > 1 else math.nan)
                ratio = (r["dependence"].get("se_ratio") or {}).get(k)
                if ratio:
                    widen.append(ratio)
            spread = float(np.std(est, ddof=1))
            mean_se = float(np.mean(se)) if se else math.nan
            rows.append(dict(
                case=case, parameter=k, sets=len(sets), covered=cover, above=above,
                spread=spread, se=mean_se, ratio=spread / mean_se,
                bias=float(np.mean(est) - _to_fit(scale, truth)),
                lag1=float(np.mean(lag1)) if lag1 else math.nan,
                lag2=float(np.nanmean(lag2)) if lag2 else math.nan,
                widen=float(np.mean(widen)) if widen else math.nan,
                seconds=float(np.mean([r["fit_seconds"] for r in sets])),
                cycles=float(np.mean([r["n_cycles"] for r in sets])),
            ))  # fmt: skip
    return rows


def table(rows) -> str:
    lines = [
        "| case | parameter | covered | above the truth | spread / mean SE | mean bias "
        "(fit coord.) | scores' autocorr. lag 1, lag 2 | SE widening for lag 1 | cycles "
        "| s a fit |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['parameter']} | {r['covered']}/{r['sets']} | "
            f"{r['above']}/{r['sets']} | {r['ratio']:.2f} | {r['bias']:+.3f} | "
            f"{r['lag1']:+.2f}, {r['lag2']:+.2f} | {r['widen']:.2f} | {r['cycles']:.0f} | "
            f"{r['seconds']:.0f} |"
        )
    return "\n".join(lines)


def variance_parts(records: list[dict]) -> str:
    """Where profile records keep their adjustment's parts (`variances`: the sandwich's,
    the simulation's in one seed's vertex, the curvature's own), per parameter the sd over
    sets of z = (estimate - truth) / sqrt(variance), the estimate the profiled seed's own:
    1 where that variance is the estimate's. Sets whose adjustment passes
    `profile.WIDE_ADJUSTMENT` (a nearly singular bread) are left out and counted."""
    from stickslip._inference.profile import WIDE_ADJUSTMENT

    kept = [r for r in records
            if str(r.get("intervals")).startswith("profile") and r.get("profile")]
    if not kept:
        return ""
    lines = ["| parameter | sets (wide c left out) | z sd: sandwich + simulation | sandwich "
             "| curvature | median c | median simulation / sandwich | tries' scatter / "
             "allowed (dof) |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for k in kept[0]["profile"]:
        z = {"total": [], "sandwich": [], "curvature": []}
        c, share, wide, scatter = [], [], 0, np.zeros(3)
        for r in kept:
            v = r["profile"][k]
            if not v["adjustment"] <= WIDE_ADJUSTMENT:
                wide += 1
                continue
            c.append(v["adjustment"])
            scatter += _tries_scatter(v)
            if "variances" not in v:  # (a log of an earlier version)
                continue
            err = v["estimate"] - _to_fit(r["scales"][k], r["truth"][k])
            parts = v["variances"]
            total = parts["sandwich"] + parts["simulation"]
            for name, var in (("total", total), ("sandwich", parts["sandwich"]),
                              ("curvature", parts["curvature"])):  # fmt: skip
                if var > 0:
                    z[name].append(err / math.sqrt(var))
            share.append(parts["simulation"] / parts["sandwich"])
        sd = {name: float(np.std(v, ddof=1)) if len(v) > 1 else math.nan for name, v in z.items()}
        lines.append(
            f"| {k} | {len(c)} ({wide}) | {sd['total']:.2f} | {sd['sandwich']:.2f} | "
            f"{sd['curvature']:.2f} | {np.median(c):.2f} | "
            f"{np.median(share) if share else math.nan:.2f} | "
            f"{scatter[0] / scatter[1]:.2f} ({scatter[2]:.0f}) |"
        )
    return "\n".join(lines)


def _tries_scatter(record) -> np.ndarray:
    """A profile's tries against its noise allowance: on each side with three tries or more
    that found the others' vertex, the residual sum of squares of their statistic about
    a + b (psi - estimate)^2, the same divided by the variance the allowance gives one
    try's statistic (`noise`^2 / 2:
    the reference's and a try's noise alike and independent), and the degrees of freedom;
    summed over the sides, the first over the second's sum is the tries' scatter as a
    share of what the allowance assumes (1: as assumed)."""
    psi, stat = np.asarray(record["psi"], float), np.asarray(record["statistic"], float)
    vertex = np.asarray(record["vertex"], bool)
    allowed = record["noise"] ** 2 / 2
    out = np.zeros(3)
    for sign in (-1.0, 1.0):
        on = (np.sign(psi - record["estimate"]) == sign) & vertex
        if on.sum() < 3 or not allowed > 0:
            continue
        X = np.c_[(psi[on] - record["estimate"]) ** 2, np.ones(on.sum())]
        rss = float(np.sum((stat[on] - X @ np.linalg.lstsq(X, stat[on], rcond=None)[0]) ** 2))
        dof = on.sum() - 2
        out += (rss, allowed * dof, dof)
    return out


def _read(paths) -> list[dict]:
    records = {}
    for path in paths:
        p = pathlib.Path(path)
        if p.exists():
            for line in p.read_text().splitlines():
                if line.strip():
                    r = json.loads(line)
                    records[_label(r), r["set"]] = r
    return list(records.values())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=list(CASES), default="random")
    parser.add_argument("--sets", type=int, default=40)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    parser.add_argument("--n-sim", type=int, default=None, help="fit's n_sim (its default)")
    parser.add_argument("--release", choices=("threshold", "stick"), default="threshold",
                        help="random case: a stick past its next threshold releases from the "
                        "threshold drawn (random-threshold, the paper's reset) or from where it "
                        "is (random-threshold-held)")  # fmt: skip
    parser.add_argument("--log", default=None, help="JSON lines, one a set (appended)")
    parser.add_argument("--coords", choices=("normal", "moments"), default="normal",
                        help="random case: the threshold's normal law by its untruncated mean "
                        "and sd (the plugin's) or by the truncated law's own mean and cv "
                        "(truncated_moments.py, an experiment)")  # fmt: skip
    parser.add_argument(
        "--intervals",
        choices=("wald", "profile"),
        default="wald",
        help="fit's intervals (profile: the Wald ones kept beside them)",
    )
    parser.add_argument("--keep", default=None, help="pickle each set's cycles and fit here")
    parser.add_argument("--summary", nargs="+", default=None, help="summarise these logs")
    parser.add_argument("--out", default=None, help="write the summary table here")
    parser.add_argument("--data", choices=("generator", "model"), default="generator",
                        help="fit the generator's traces, or (a control) the model's own "
                        "cycles through each trace's measurement")  # fmt: skip
    parser.add_argument(
        "--own-cycles",
        type=float,
        default=1.0,
        help="--data model: this many times the trace's cycles",
    )
    parser.add_argument("--likelihood", choices=("marginal", "pair"), default="marginal",
                        help="the fit's (marginal) or, an experiment, stick times scored "
                        "given their drops (_pair_likelihood.py)")  # fmt: skip
    args = parser.parse_args()
    if args.summary:
        records = _read(args.summary)
        text = table(summary(_with_wald(records)))
        parts = variance_parts(records)
        text += "\n\n" + parts if parts else ""
        print(text)
        print("bar: covered 88-99 %; under 70 % of estimates on one side of the truth")
        if args.out:
            pathlib.Path(args.out).write_text(text + "\n")
        return
    source = args.data if args.own_cycles == 1.0 else f"{args.data} x{args.own_cycles:g}"
    done = {r["set"] for r in _read([args.log]) if r["case"] == args.case
            and r.get("release", "threshold") == args.release
            and r.get("coords", "normal") == args.coords
            and r.get("intervals", "wald") == args.intervals
            and r.get("data", "generator") == source
            and r.get("likelihood", "marginal") == args.likelihood
            } if args.log else set()  # fmt: skip
    todo = [i for i in range(args.first, args.first + args.sets) if i not in done]
    with concurrent.futures.ProcessPoolExecutor(args.jobs) as pool:
        keep = None if args.keep is None else pathlib.Path(args.keep)
        futures = {pool.submit(one_set, args.case, i, args.n_sim, args.release, keep,
                               args.coords, args.intervals, args.data, args.own_cycles,
                               args.likelihood): i
                   for i in todo}  # fmt: skip
        for f in concurrent.futures.as_completed(futures):
            r = f.result()
            line = "; ".join(f"{k} {v:.4g} [{r['ci'][k][0]:.4g}, {r['ci'][k][1]:.4g}]"
                             for k, v in r["estimate"].items())  # fmt: skip
            print(f"{r['case']} set {r['set']}: {r['n_cycles']} cycles, {line}; "
                  f"{r['fit_seconds']:.0f} s", flush=True)  # fmt: skip
            if args.log:
                with open(args.log, "a") as fh:
                    fh.write(json.dumps(r, default=float) + "\n")


if __name__ == "__main__":
    main()
