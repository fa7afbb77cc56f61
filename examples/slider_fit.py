"""The measured slider trace end to end: cycles -> candidate models -> the simplest model
the data do not reject -> its parameters in SI units -> a predictive check and a plain
verdict. The data (a 30.7 g paper slider pulled over paper at 42 um/s through a 168 N/m
spring, force at 2 kHz) are by N. Pustelnik and V. Vidal, CeCILL-B: credit and licence in
examples/data/slider_paper_on_paper/README.md.

    python examples/slider_fit.py --out results-slider-fit

1. `extract_cycles` on the force trace (as examples/slider_trace.py): 252 cycles;
2. a reference slider (`stickslip.Slider`): the rig's mass, stiffness and loading speed,
   and, for the units only, a static and kinetic friction from the data's median peak
   force and drop; the model is fitted in its units, through the data's measurement
   (`fit(..., cycles, scales=slider)`: the model's trace sampled at 2 kHz with the data's
   noise, spikes and mains line, then `extract_cycles` with the data's settings);
3. two candidates, both with an effective natural frequency (`omega0`, in units of
   sqrt(k/m)) and a friction-noise intensity `D` free: a fixed static threshold `x0`,
   and a normal random one (`threshold_params.mean`, `.sd`); their fits run side by
   side, one process each;
4. `compare_fits` chooses the simpler unless the data reject it (scoring its replicates,
   drawn by `draw_replicates` as soon as the simpler fit ends, against the cycles the
   fits simulated at their designs); each candidate's goodness of fit
   (`goodness_of_fit`, 100 replicates through the measurement) and its cycles for the
   predictive check run in its worker process, submitted as soon as its fit ends;
5. its parameters in SI with 95 % intervals, a predictive check (`slider_fit.png`: data
   against both fitted models, stick time, slip time, force drop), and the verdict,
   printed and written to `slider_fit.md` (and `slider_fit.json`).

What is assumed, not fitted: the spring (168 N/m), the loading speed (the sticks'
measured slope, 7 % above the nominal 42 um/s), a negligible viscous damping (zeta =
1e-3), the noise's correlation time (0.1 / omega0 = 1.35 ms), independent cycles (the
drift of the absolute force level over the run is outside the model: `peak_force` is not
fitted). The rig's 30.7 g only sets the units: an effective mass is fitted (omega0).

`--out DIR`, then copy slider_fit.png to docs/img to refresh docs/slider_fit.md. About
4.7 minutes of CPU, 2.5 minutes on 2 quiet cores (docs/slider_fit.md, "Cost"): a point of a fit
through this measurement is 4000 model cycles (`fit`'s default) as a 2 kHz trace, ~0.4 s;
`--n-sim 1000` is four times cheaper, and its random threshold's fit has no interval.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
import math
import multiprocessing
import os
import pathlib
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from slider_trace import MASS, STIFFNESS, extract, load  # noqa: E402

COLUMNS = ("slip_time", "stick_time", "slip_distance")  # a force trace's d is its drop / k
ZETA = 1e-3  # viscous damping c / (m omega0): negligible (no velocity-dependent friction)
TAU = 0.1  # the friction noise's correlation time, in units of 1/omega0 (1.35 ms)
BOX = {  # model units of the reference slider (time 1/omega0, length x0); wide enough that
    # the polynomial's design (+-2 steps of 0.3 about the estimate, log for a positive end)
    # stays inside it
    "omega0": (0.5, 3.0),  # an effective natural frequency of 37 to 222 rad/s
    "D": (0.02, 3.0),
    "threshold": (0.3, 2.0),  # x0, or the random threshold's mean
    "sd": (0.0, 1.5),  # the random threshold's sd
}
ALPHA = 0.01  # the verdict's level, as fit's and compare_fits'
# fit's warnings that its intervals are not to be used (no vertex, or not concave)
UNUSABLE = ("the polynomial fitted to the surface has no maximum",
            "the log-likelihood is not concave")  # fmt: skip


def reference_slider(cycles):
    """The rig in SI (`Slider.from_cycles`), which sets the model's units: mass, the
    extraction's stiffness and the sticks' measured loading speed, and, for the units only,
    F_s = the median peak force and F_k = F_s - (median drop) / 2 (a drop is 2 (F_s - F_k)
    without damping)."""
    import stickslip as ss

    return ss.Slider.from_cycles(cycles, MASS, stiffness=STIFFNESS, zeta=ZETA)


CANDIDATES = ("fixed threshold", "random threshold")


def candidates(slider):
    """{name: (model, free, fixed)} of `CANDIDATES`: the fixed and the random static
    threshold."""
    known = dict(zeta=ZETA, v_b=slider.dimensionless()["v_b"], tau=TAU)
    shared = {"omega0": BOX["omega0"], "D": BOX["D"]}
    law = {"threshold_params.mean": BOX["threshold"], "threshold_params.sd": BOX["sd"]}
    fixed = ("langevin", {**shared, "x0": BOX["threshold"]}, known)
    random = ("random-threshold", {**shared, **law}, {**known, "threshold": "normal"})
    return dict(zip(CANDIDATES, (fixed, random), strict=True))


def fitted(data, slider, spec, n_sim, seed):
    """One candidate's fit (no goodness check: only the chosen model's is needed), its
    warnings returned rather than printed; picklable, for a worker process."""
    import stickslip as ss

    model, free, fixed = spec
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = ss.fit(model, data, free, fixed, n_sim=n_sim, seed=seed, scales=slider,
                   check=False)  # fmt: skip
    return r, _ours(caught)


def _ours(caught) -> list[str]:
    """The messages of stickslip's own warnings (fit, compare_fits, goodness_of_fit) among
    those caught; the libraries' (a subprocess left running, ...) are not the verdict's."""
    prefixes = ("fit:", "compare_fits:", "goodness_of_fit:")
    return [str(w.message) for w in caught if str(w.message).startswith(prefixes)]


def si_parameters(r, slider):
    """[(quantity, unit, estimate, low, high)] of a fit, in SI (`Slider.si_table`)."""
    # where the fit's surface had no usable curvature its intervals are not intervals (the
    # fit says so in its warnings): reported as nan
    said = getattr(r, "diagnostics", {}).get("warnings", [])
    usable = not any(w.startswith(UNUSABLE) for w in said)
    return [(row["quantity"], row["unit"], row["estimate"],
             row["low"] if usable else math.nan, row["high"] if usable else math.nan)
            for row in slider.si_table(r)]  # fmt: skip


def to_si(columns, slider):
    """Cycles in the model's units (a fit's `data`, its `simulated()`) in SI: times in s,
    the slip distance as the force drop in N."""
    s = slider.scales
    return {
        "stick_time": np.asarray(columns["stick_time"]) * s.time,
        "slip_time": np.asarray(columns["slip_time"]) * s.time,
        "force_drop": np.asarray(columns["slip_distance"]) * s.force,
    }


PANELS = (("stick_time", "stick time (s)", 1.0), ("slip_time", "slip time (ms)", 1e3),
          ("force_drop", "force drop (mN)", 1e3))  # fmt: skip


def _plotting():
    """matplotlib's pyplot, on the file backend (imported once: ~1 s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_check(data_si, models_si, p_values, chosen, path):
    """Data against each fitted model: histograms (density) and distribution functions."""
    plt = _plotting()
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.4))
    styles = {"fixed threshold": ("tab:orange", "--"), "random threshold": ("tab:green", "-")}
    for j, (name, label, scale) in enumerate(PANELS):
        x = data_si[name] * scale
        edges = np.histogram_bin_edges(x, bins=30)
        axes[0, j].hist(x, edges, density=True, color="0.7", label=f"data ({x.size} cycles)")
        axes[1, j].step(np.sort(x), np.arange(1, x.size + 1) / x.size, where="post",
                        color="k", lw=1.5, label="data")  # fmt: skip
        for model, sim in models_si.items():
            y = sim[name] * scale
            colour, ls = styles.get(model, ("tab:blue", "-"))
            tag = f"{model}{' (chosen)' if model == chosen else ''}"
            axes[0, j].hist(y, edges, density=True, histtype="step", color=colour, ls=ls,
                            lw=1.5, label=tag)  # fmt: skip
            axes[1, j].step(np.sort(y), np.arange(1, y.size + 1) / y.size, where="post",
                            color=colour, ls=ls, lw=1.2, label=tag)  # fmt: skip
        fitted_name = "slip_distance" if name == "force_drop" else name
        p = p_values.get(fitted_name)
        title = label if p is None else f"{label}: chosen model's p = {p:.3g}"
        axes[0, j].set_title(title, fontsize=9)
        axes[1, j].set_xlabel(label)
    axes[0, 0].set_ylabel("density")
    axes[1, 0].set_ylabel("fraction of cycles below")
    axes[0, 0].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7, loc="lower right")
    fig.suptitle("k168Nm_v42 (Pustelnik & Vidal, CeCILL-B): data against the fitted models, "
                 "simulated through the data's measurement", fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def verdict(chosen_name, chosen, comparison, p_values, data_si, sims_si, others=None):
    """The plain statement: which model, whether it reproduces each observable, and where
    it does not (the quantiles of data and model side by side)."""
    lines = []
    rejected_by = [r for r in comparison.table if r["verdict"].startswith("rejected")]
    lines.append(f"**Chosen model: {chosen_name}** ({comparison.table[0]['verdict']}).")
    for r in rejected_by:
        lines.append(f"The {r['name']} model is rejected against a richer one "
                     f"(2 dlogL = {r['statistic']:.1f}, p = {r['p_value']:.3g}).")  # fmt: skip
    low = {k: p for k, p in p_values.items() if p < ALPHA}
    names = {"slip_time": "slip time", "stick_time": "stick time",
             "slip_distance": "force drop", "joint": "all three at once"}  # fmt: skip
    shown = ", ".join(f"{names.get(k, k)} p = {p:.3g}" for k, p in p_values.items())
    if low:
        lines.append(f"**It does not reproduce the measurement**: its goodness of fit rejects "
                     f"it ({shown}; below {ALPHA} in "
                     f"{', '.join(names.get(k, k) for k in low)}).")  # fmt: skip
    else:
        n = next(iter(data_si.values())).size
        lines.append(f"**It reproduces the measurement** within what {n} cycles can tell: "
                     f"no goodness-of-fit p-value is below {ALPHA} ({shown}).")  # fmt: skip
    for name, ps in (others or {}).items():
        shown_other = ", ".join(f"{names.get(k, k)} p = {p:.3g}" for k, p in ps.items())
        lines.append(f"The {name} model's own goodness of fit: {shown_other}.")
    said = chosen.diagnostics["warnings"]
    if any(w.startswith(UNUSABLE) for w in said):
        lines.append(
            "Its fit's surface has no usable curvature (its warnings): the estimates stand, "
            "but its intervals are not available and its goodness-of-fit p-values are rough "
            "(docs/goodness.md). The noise and the threshold's spread trade off along a "
            "plateau of the surface, where the simulation's noise makes spikes of a few "
            "units; more model cycles a point (--n-sim) shrink them (docs/slider_fit.md)."
        )
    sim = sims_si[chosen_name]
    for name, label, scale in PANELS:
        q = np.percentile(data_si[name], [10, 50, 90]) * scale
        m = np.percentile(sim[name], [10, 50, 90]) * scale
        unit = label.split("(")[1].rstrip(")")
        lines.append(
            f"- {label.split(' (')[0]}: data 10/50/90 % {q[0]:.3g} / {q[1]:.3g} / {q[2]:.3g} "
            f"{unit}, model {m[0]:.3g} / {m[1]:.3g} / {m[2]:.3g} {unit}"
        )
    return lines


# glibc's allocator for the worker processes: keep freed memory for reuse rather than
# returning it to the system. A point's trace is millions of samples, and the extraction's
# arrays of that size, each fresh from the system, page-faulted on every point: a point of
# a fit took 0.90 s with these settings against 1.05 s without (8 points, one process),
# the same numbers. Set for the workers only (read when a process starts), not for this one;
# other C libraries ignore them.
ALLOCATOR = {
    "MALLOC_MMAP_THRESHOLD_": str(32 * 2**20),  # arrays up to 32 MB from the heap...
    "MALLOC_TRIM_THRESHOLD_": str(2 * 2**30),  # ...kept there when freed...
    "MALLOC_TOP_PAD_": str(512 * 2**20),  # ...and the heap grown in large steps
}


def run_all(data, slider, n_sim, seed, workers):
    """Everything in worker processes (`ALLOCATOR`'s settings), one candidate's work in one
    process (up to `workers`; candidate i in process i mod `workers`): its fit, then, for
    the simplest candidate, the comparison's replicates (`draw_replicates`: most of the
    comparison's cost, drawn beside the richer fit), and its goodness of fit and
    predictive cycles (`checked`), each submitted as soon as the fit ends; the comparison,
    once every fit has ended, in the simplest candidate's process (a job on a process
    that has not run its model first loads the model's compiled simulation, ~2 s a model
    here). Returns `(fits, said, comparison, caught, checks, fits_done)`, the last the
    `time.perf_counter()` at which the last fit ended. The numbers do not depend on
    `workers` or on the order the fits end in."""
    specs = candidates(slider)
    simplest = min(specs, key=lambda name: len(specs[name][1]))  # the comparison's null
    fits, said, checking = {}, {}, {}
    context = multiprocessing.get_context("spawn")  # a fresh JAX in each worker
    saved = {k: os.environ.get(k) for k in ALLOCATOR}
    os.environ.update(ALLOCATOR)
    pools = [concurrent.futures.ProcessPoolExecutor(1, mp_context=context)
             for _ in range(max(1, min(workers, len(specs))))]  # fmt: skip
    home = {name: pools[i % len(pools)] for i, name in enumerate(specs)}
    try:
        jobs = {home[name].submit(fitted, data, slider, spec, n_sim, seed): name
                for name, spec in specs.items()}  # fmt: skip
        _plotting()  # (here, while the workers fit: not after them)
        for job in concurrent.futures.as_completed(jobs):
            name = jobs[job]
            fits[name], said[name] = job.result()
            if name == simplest:
                drawing = home[name].submit(drawn, fits[name], seed)
            checking[name] = home[name].submit(checked, fits[name], seed, n_sim, slider)
            print(f"\n{name}:\n{fits[name].summary()}", flush=True)
        fits_done = time.perf_counter()
        fits = {name: fits[name] for name in specs}  # the candidates' own order
        comparison, caught = home[simplest].submit(compared, fits, drawing.result()).result()
        print("\n" + comparison.summary(), flush=True)
        checks = {name: checking[name].result() for name in specs}
    finally:
        for pool in pools:
            pool.shutdown()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return fits, said, comparison, caught, checks, fits_done


def drawn(fit, seed):
    """The comparison's replicates of `fit` (the simpler candidate), with a seed of their
    own; for a worker process."""
    import stickslip as ss

    return ss.draw_replicates(fit, seed=seed + 100)


def compared(fits, replicates):
    """`compare_fits` with the simpler candidate's `replicates`, and its warnings (returned
    rather than printed); for a worker."""
    import stickslip as ss

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        comparison = ss.compare_fits(fits, replicates=[replicates])
    return comparison, _ours(caught)


def checked(fit, seed, n_sim, slider):
    """A candidate's goodness of fit (its warnings returned rather than printed) and its
    cycles simulated through the measurement with a seed of its own (not the draws its
    estimate was tuned on), in SI; picklable, for a worker process."""
    import stickslip as ss

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        goodness = ss.goodness_of_fit(fit, n_rep=100, seed=seed + 200)
    return goodness, _ours(caught), to_si(fit.simulated(4 * n_sim, seed=seed + 300), slider)


def conclude(fits, said, comparison, caught, checks, slider, out, n_sim, seed):
    """The chosen candidate with its goodness of fit, the predictive check, the SI
    parameters and the verdict, written to `out`: returns the JSON record."""
    table = next(iter(fits.values())).data  # the cycles in the model's units, as fitted
    chosen_name = comparison.chosen_name
    goodness, said_goodness, _ = checks[chosen_name]
    chosen = dataclasses.replace(comparison.chosen, goodness=goodness)
    p_values = chosen.p_values
    others = {name: dataclasses.replace(fits[name], goodness=g).p_values
              for name, (g, _, _) in checks.items() if name != chosen_name}  # fmt: skip

    data_si = to_si(table, slider)
    sims_si = {name: sim for name, (_, _, sim) in checks.items()}
    plot_check(data_si, sims_si, p_values, chosen_name, out / "slider_fit.png")
    rows = si_parameters(chosen, slider)
    lines = verdict(chosen_name, chosen, comparison, p_values, data_si, sims_si, others)
    warned = [f"{k}: {w}" for k, ws in said.items() for w in ws]
    warned += caught + said_goodness
    record = write_report(out, chosen_name, comparison, rows, lines, warned, p_values, fits,
                          slider, n_sim, seed)  # fmt: skip
    record["goodness_of_the_others"] = others
    return record


def main(argv=None):
    import resource

    import stickslip as ss

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results-slider-fit", help="folder for the outputs")
    parser.add_argument(
        "--n-sim", type=int, default=4000, help="model cycles per point (fit's own default)"
    )
    parser.add_argument("--seed", type=int, default=1, help="the fits' simulation seed")
    parser.add_argument("--workers", type=int, default=2,
                        help="processes, up to one per candidate: its fit, then its goodness "
                        "check (the simpler's: the comparison's replicates too)")  # fmt: skip
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    wall0 = time.perf_counter()

    t, force = load("k168Nm_v42.mat")
    cycles, _ = extract(t, force)
    slider = reference_slider(cycles)
    data = ss.Cycles({k: cycles[k] for k in COLUMNS}, cycles.info)  # (period: slip + stick)
    print(f"{len(cycles)} cycles; reference slider: omega0 = {slider.scales.omega0:.4g} rad/s, "
          f"x0 = {slider.scales.length:.4g} m, force unit k x0 = {slider.scales.force:.4g} N, "
          f"v_b = {slider.v_b:.4g} m/s (the sticks' slope)", flush=True)  # fmt: skip
    fits, said, comparison, caught, checks, fits_done = run_all(
        data, slider, args.n_sim, args.seed, args.workers
    )
    fit_seconds = fits_done - wall0
    record = conclude(fits, said, comparison, caught, checks, slider, out, args.n_sim,
                      args.seed)  # fmt: skip
    wall = time.perf_counter() - wall0
    usage = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    cpu = sum(u.ru_utime + u.ru_stime for u in usage)
    record.update(seconds=wall, fit_seconds=fit_seconds, cpu_seconds=cpu, workers=args.workers)
    (out / "slider_fit.json").write_text(json.dumps(record, indent=1, default=_plain) + "\n")
    timing = (f"{wall:.0f} s end to end ({fit_seconds:.0f} s the candidates' fits, "
              f"{args.workers} at a time); {cpu:.0f} s of CPU in all processes")  # fmt: skip
    with open(out / "slider_fit.md", "a") as f:
        f.write(f"\n{timing}.\n")
    print((out / "slider_fit.md").read_text())
    print(f"written: slider_fit.md, slider_fit.json, slider_fit.png in {out}; {timing}")


def write_report(out, chosen_name, comparison, rows, lines, warned, p_values, fits, slider,
                 n_sim, seed):  # fmt: skip
    """slider_fit.md (the verdict, the SI parameters, the comparison, the warnings) and
    slider_fit.json (the same as numbers); returns the JSON record."""
    table = ["| quantity | estimate | 95 % interval |", "|---|---:|---|"]
    for label, unit, value, lo, hi in rows:
        ci = f"[{lo:.4g}, {hi:.4g}]" if math.isfinite(lo) else "none (see the warnings)"
        table.append(f"| {label} ({unit}) | {value:.4g} | {ci} |")
    text = "\n".join([
        "# The measured slider, fitted", "",
        *lines, "",
        f"## The chosen model's parameters ({chosen_name}), in SI", "",
        *table, "",
        "## Model choice", "", "```", comparison.summary(), "```", "",
        "## Warnings", "",
        *([f"- {w}" for w in warned] or ["none"]), "",
        f"{n_sim} model cycles per point, seed {seed}.",
    ])  # fmt: skip
    (out / "slider_fit.md").write_text(text + "\n")
    record = dict(
        chosen=chosen_name,
        p_values=p_values,
        rejected=bool(any(p < ALPHA for p in p_values.values())),
        candidates={name: dict(estimate=r.estimate, ci={k: list(v) for k, v in r.ci.items()},
                               log_likelihood=r.log_likelihood,
                               warnings=r.diagnostics["warnings"])
                    for name, r in fits.items()},  # fmt: skip
        table=comparison.table,
        si={label: dict(unit=unit, estimate=v, ci=[lo, hi]) for label, unit, v, lo, hi in rows},
        reference_slider=slider.si_dict(),
        n_sim=n_sim, seed=seed,
    )  # fmt: skip
    (out / "slider_fit.json").write_text(json.dumps(record, indent=1, default=_plain) + "\n")
    return record


def _plain(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, (tuple, np.ndarray)):
        return list(value)
    return str(value)


if __name__ == "__main__":
    main()
