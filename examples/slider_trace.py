"""A measured stick-slip trace, cycle by cycle: a 30.7 g paper slider pulled over paper at
42 um/s through a 168 N/m spring, its force recorded at 2 kHz for 375 s (data, credit and
licence: examples/data/slider_paper_on_paper/README.md).

    python examples/slider_trace.py --out results-slider [--no-sensitivity]

1. load the force (`Fnorm`, in units of the slider's weight m g) and turn it into newtons;
2. `extract_cycles(t, force=F, stiffness=168, v_b=42e-6)`: one row per cycle, in s, m, N;
3. write `slider_window.png` (a stretch of the trace, the slips marked, one slip close up
   with its fitted release and stick) and `slider_histograms.png` (stick time, slip time,
   force drop);
4. the threshold sensitivity: every threshold of the extraction halved and doubled in turn
   (and the rate filter's window), the cycle count and the medians each time, printed and
   written to `slider_sensitivity.md`;
5. the 4300 um/s run, which slides without sticking, refused in one line.

`--out DIR` then copy slider_*.png to docs/img to refresh docs/measured_trace.md. About 15 s
on 2 cores, most of it the 12 extra extractions of the sensitivity table.
"""

from __future__ import annotations

import argparse
import pathlib
import time
import warnings

import numpy as np

DATA = pathlib.Path(__file__).resolve().parent / "data" / "slider_paper_on_paper"
MASS = 0.0307  # kg, the slider
GRAVITY = 9.81  # m/s^2, as the source normalises the force
STIFFNESS = 168.0  # N/m
V_B = 42e-6  # m/s, the nominal driving speed
WINDOW = (200.0, 215.0)  # s, the stretch of trace shown
COLUMNS = ("stick_time", "slip_time", "force_drop")
MATCH = 0.02  # s: releases this close are the same slip (two thirds of the median slip)


def load(name):
    """(t in s, force in N) from one of the source's .mat files."""
    from scipy.io import loadmat

    raw = loadmat(DATA / name)
    return raw["t"].ravel(), raw["Fnorm"].ravel() * MASS * GRAVITY


def extract(t, force, **kw):
    """`extract_cycles` on the force trace; the v_b warning returned, not printed."""
    import stickslip as ss

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cycles = ss.extract_cycles(t, force=force, stiffness=STIFFNESS, v_b=V_B, **kw)
    return cycles, [str(w.message) for w in caught]


def sensitivity(t, force, base):
    """Rows (setting, value, cycles, change %, median stick, slip, drop) for the defaults
    and each threshold (and the window) halved and doubled, the others at their defaults."""

    def row(label, value, cycles):
        med = [float(np.median(cycles[c])) for c in COLUMNS]
        # the events found by one run and not the other (no release within MATCH)
        gap = np.abs(cycles["release_time"][:, None] - base["release_time"][None])
        changed = np.concatenate([cycles["force_drop"][gap.min(axis=1) > MATCH],
                                  base["force_drop"][gap.min(axis=0) > MATCH]])  # fmt: skip
        largest = float(changed.max()) if changed.size else 0.0
        return (label, value, len(cycles), 100.0 * (len(cycles) / len(base) - 1.0), *med,
                changed.size, largest)  # fmt: skip

    rows = [row("defaults", "", base)]
    for key, value in base.info["thresholds"].items():
        for factor in (0.5, 2.0):
            found, _ = extract(t, force, thresholds={key: factor * value})
            rows.append(row(key, f"{factor * value:g} (x{factor:g})", found))
    w = base.info["window"]
    for factor in (0.5, 2.0):
        found, _ = extract(t, force, window=max(5, int(round(factor * w))))
        rows.append(row("window", f"{found.info['window']} samples (x{factor:g})", found))
    return rows


def table_markdown(rows):
    lines = [
        "| setting | value | cycles | change | median stick (s) | median slip (ms) | "
        "median drop (mN) | slips found or lost | largest of their drops (mN) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, value, n, change, stick, slip, drop, n_changed, largest in rows:
        lines.append(f"| {label} | {value} | {n} | {change:+.1f}% | {stick:.3f} | "
                     f"{1e3 * slip:.1f} | {1e3 * drop:.2f} | {n_changed} | "
                     f"{1e3 * largest:.2f} |")  # fmt: skip
    return "\n".join(lines)


def plot_window(t, force, cycles, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    release = cycles["release_time"]
    stuck = release + cycles["slip_time"]
    fig, (ax, zoom) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw=dict(width_ratios=(3, 1)))
    sel = (t >= WINDOW[0]) & (t <= WINDOW[1])
    ax.plot(t[sel], force[sel], lw=0.3, color="0.45", label="force (raw samples)")
    shown = (release >= WINDOW[0]) & (stuck <= WINDOW[1])
    for a, b in zip(release[shown], stuck[shown], strict=True):
        ax.axvspan(a, b, color="tab:red", alpha=0.35, lw=0)
    ax.plot(release[shown], cycles["peak_force"][shown], "v", color="tab:red", ms=5,
            label="release (fitted)")  # fmt: skip
    ax.set_xlim(*WINDOW)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("spring force F (N)")
    ax.set_title(f"{shown.sum()} slips in {WINDOW[1] - WINDOW[0]:g} s (shaded: slip)", fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    # one slip close up: the largest drop in the window
    j = np.flatnonzero(shown)[np.argmax(cycles["force_drop"][shown])]
    near = (t >= release[j] - 0.06) & (t <= stuck[j] + 0.06)
    zoom.plot(t[near], force[near], ".", ms=2, color="0.35")
    zoom.axvline(release[j], color="tab:red", lw=1, label="release")
    zoom.axvline(stuck[j], color="tab:green", lw=1, label="stick")
    zoom.set_xlabel("t (s)")
    zoom.set_title(f"slip time {1e3 * cycles['slip_time'][j]:.1f} ms", fontsize=9)
    zoom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_histograms(cycles, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2))
    labels = ("stick time $T_{st}$ (s)", "slip time $T_{sl}$ (s)", "force drop (N)")
    for ax, name, label in zip(axes, COLUMNS, labels, strict=True):
        values = cycles[name]
        ax.hist(values, bins=30, color="tab:blue", alpha=0.8)
        ax.axvline(np.median(values), color="k", lw=1, ls="--", label="median")
        ax.set_xlabel(label)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))
    axes[0].set_ylabel("cycles")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{len(cycles)} cycles, k168Nm_v42", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    import stickslip as ss

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results-slider", help="folder for figures, table")
    parser.add_argument("--no-sensitivity", action="store_true", help="skip the table")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    t, force = load("k168Nm_v42.mat")
    start = time.perf_counter()
    cycles, caught = extract(t, force)
    took = time.perf_counter() - start
    info = cycles.info
    print(f"k168Nm_v42: {t.size} samples over {t[-1] - t[0]:.1f} s; {len(cycles)} cycles "
          f"in {took:.2f} s")  # fmt: skip
    for message in caught:
        print(f"  warning: {message}")
    print(f"  noise sd {info['noise_sd']:.3g} N ({info['n_spikes']} spikes replaced); force "
          f"rate noise {info['rate_noise_ratio']:.2f} x white noise's (window "
          f"{info['window']} samples)")  # fmt: skip
    print(f"  v_b from the sticks' loading slope {info['v_b_estimated']:.4g} m/s (nominal "
          f"{V_B:g})")  # fmt: skip
    for name, unit, scale in (("stick_time", "s", 1), ("slip_time", "ms", 1e3),
                              ("force_drop", "mN", 1e3), ("peak_force", "N", 1)):  # fmt: skip
        q = np.percentile(cycles[name], [10, 50, 90]) * scale
        print(f"  {name:11s} median {q[1]:.4g} {unit} (10-90%: {q[0]:.3g} - {q[2]:.3g})")
    print(f"  fitted timing: release sd {1e3 * info['release_sd_median']:.2f} ms, stick sd "
          f"{1e3 * info['stick_sd_median']:.2f} ms (medians; white-noise errors)")  # fmt: skip
    cycles.to_csv(out / "slider_cycles.csv")
    plot_window(t, force, cycles, out / "slider_window.png")
    plot_histograms(cycles, out / "slider_histograms.png")

    if not args.no_sensitivity:
        table = table_markdown(sensitivity(t, force, cycles))
        (out / "slider_sensitivity.md").write_text(table + "\n")
        print(table)

    t2, force2 = load("k168Nm_v4300.mat")
    try:
        ss.extract_cycles(t2, force=force2, stiffness=STIFFNESS, v_b=4300e-6)
        print("k168Nm_v4300: cycles found (not expected: this run slides)")
    except ss.StickSlipError as err:
        print(f"k168Nm_v4300: refused: {err}")
    print(f"written: {', '.join(sorted(p.name for p in out.glob('slider_*')))} in {out}")


if __name__ == "__main__":
    main()
