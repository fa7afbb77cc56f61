"""The forward measurement with its sticks cut against the whole trace: the same cycles?
And at what cost?

    python benchmarks/forward_measurement.py [--chunks 10] [--cycles 1000] [--json out.json]

The measured slider's measurement (`examples/data/slider_paper_on_paper/k168Nm_v42.mat`
through `extract_cycles`, as `examples/slider_fit.py` reads it: 2 kHz, its noise, spikes,
mains line and window) on the Langevin model near that example's estimate (omega0 1.24, D
0.37, x0 1 in the reference slider's units). For each of `--chunks` seeds, `--cycles`
successive model cycles are measured twice with the same simulated paths and the same
keyed sensor noise: `measured_trace(..., sticks="whole")` then `extract_cycles` on every
sample (the reference), and `sticks="cut"`, only the stretches about the slips
synthesised and extracted (`measured_cycles`' default).

Reported:

- **decisions**: the cycles each finds, matched by their release (within a window of the
  force rate); the share of the whole trace's cycles the cut one finds too, and of the
  cut one's that the whole one finds;
- **per cycle**: the differences cut - whole of the release, slip time, stick time and
  drop, as quantiles of |difference| over the extraction's own error (the robust sd,
  1.4826 MAD, of the whole trace's values less the model's own, over the cycles matched
  to the simulation's truth; robust: where the measurement joins two model cycles, a
  stick time is the sum of two): "the same cycles to within the extraction's timing
  error";
- **cost**: seconds per 1000 model cycles of each path (warm: the first chunk of each is
  run once before timing), simulation included, and their ratio.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))

COLUMNS = ("release_time", "slip_time", "stick_time", "force_drop")


def setting():
    """(model, measurement) of the measured slider near its fitted estimate."""
    from slider_fit import TAU, ZETA, reference_slider  # noqa: E402
    from slider_trace import extract, load  # noqa: E402

    import stickslip as ss

    t, force = load("k168Nm_v42.mat")
    cycles, _ = extract(t, force)
    slider = reference_slider(cycles)
    measurement = ss.Measurement.from_cycles(cycles, scales=slider)
    model = ss.get_model("langevin")(omega0=1.24, zeta=ZETA, v_b=slider.dimensionless()["v_b"],
                                     tau=TAU, D=0.37, x0=1.0)  # fmt: skip
    return model, measurement


def measure(model, measurement, n, seed, sticks):
    """The measured trace's cycles per path (full tables, release times included), the
    simulation's truth, and the seconds it took."""
    from stickslip._inference.measurement import extracted, measured_trace

    t0 = time.perf_counter()
    trace = measured_trace(model, measurement, n, seed, sticks=sticks)
    tables = [extracted(signals, measurement, float(model.v_b)) for signals in trace.traces]
    return tables, trace.truth, time.perf_counter() - t0


def match(a, b, tol):
    """Indices (i, j) pairing each release in `a` with the nearest in `b` within `tol`,
    one to one (both sorted)."""
    if a.size == 0 or b.size == 0:
        return np.zeros(0, int), np.zeros(0, int)
    j = np.clip(np.searchsorted(b, a), 1, b.size - 1)
    j = np.where(np.abs(b[j - 1] - a) <= np.abs(b[j] - a), j - 1, j)
    ok = np.abs(b[j] - a) <= tol
    i, j = np.flatnonzero(ok), j[ok]
    first = np.r_[True, j[1:] != j[:-1]]
    return i[first], j[first]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--chunks", type=int, default=10)
    parser.add_argument("--cycles", type=int, default=1000)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    model, measurement = setting()
    h = measurement.sampling_interval
    tol = measurement.window * h
    for sticks in ("whole", "cut"):  # warm both paths alike
        measure(model, measurement, args.cycles, 0, sticks)
    seconds = {"whole": 0.0, "cut": 0.0}
    diffs = {k: [] for k in COLUMNS}
    errors = {k: [] for k in COLUMNS}
    n_whole = n_cut = both = model_cycles = 0
    for seed in range(1, args.chunks + 1):
        out = {}
        for sticks in ("whole", "cut"):
            tables, truth, sec = measure(model, measurement, args.cycles, seed, sticks)
            out[sticks] = (tables, truth)
            seconds[sticks] += sec
        model_cycles += out["whole"][1]["release_time"].size
        truth = out["whole"][1]
        for p, (w, c) in enumerate(zip(out["whole"][0], out["cut"][0], strict=True)):
            n_whole += w["release_time"].size
            n_cut += c["release_time"].size
            i, j = match(w["release_time"], c["release_time"], tol)
            both += i.size
            for k in COLUMNS:
                diffs[k].append(c[k][j] - w[k][i])
            # the extraction's own error: whole-trace values against the model's
            rows = truth["path"] == p
            own = {"release_time": truth["release_time"][rows],
                   "slip_time": truth["slip_time"][rows],
                   "stick_time": truth["stick_time"][rows]}  # fmt: skip
            own["force_drop"] = truth["slip_distance"][rows]  # k = 1: the drop is x_0 - x_stick
            a, b = match(w["release_time"], own["release_time"], tol)
            for k in COLUMNS:
                errors[k].append(w[k][a] - own[k][b])
    report = dict(
        model_cycles=int(model_cycles), whole_cycles=n_whole, cut_cycles=n_cut, matched=both,
        whole_found_by_cut=both / n_whole, cut_found_by_whole=both / n_cut,
        seconds_per_1000=dict((k, 1000 * v / model_cycles) for k, v in seconds.items()),
        speedup=seconds["whole"] / seconds["cut"], per_cycle={},
    )
    for k in COLUMNS:
        d = np.abs(np.concatenate(diffs[k]))
        e = np.concatenate(errors[k])
        e = e[np.isfinite(e)]
        own = float(1.4826 * np.median(np.abs(e - np.median(e))))
        q = np.percentile(d, [50, 90, 99, 99.5, 100]) / own
        names = ("p50", "p90", "p99", "p99.5", "max")
        report["per_cycle"][k] = dict(own_rms_error=own,
                                      over_own_error=dict(zip(names, q.tolist(), strict=True)),
                                      within_own_error=float(np.mean(d <= own)))  # fmt: skip
    print(f"{model_cycles} model cycles; the whole trace found {n_whole}, the cut one "
          f"{n_cut}, {both} matched: {100 * both / n_whole:.2f} % of the whole trace's "
          f"found by the cut one, {100 * both / n_cut:.2f} % of the cut one's by the whole "
          "one")  # fmt: skip
    print(f"seconds per 1000 model cycles: whole {report['seconds_per_1000']['whole']:.3f}, "
          f"cut {report['seconds_per_1000']['cut']:.3f}: {report['speedup']:.2f}x")  # fmt: skip
    print(f"{'column':14s} {'own error':>10s}   |cut - whole| / own error: p50 p90 p99 "
          "p99.5 max; share within it")
    for k, r in report["per_cycle"].items():
        q = r["over_own_error"]
        print(f"{k:14s} {r['own_rms_error']:10.4g}   " + " ".join(f"{v:.3f}" for v in
              q.values()) + f"; {100 * r['within_own_error']:.2f} %")  # fmt: skip
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
