"""Make the figures and numbers of docs/rate_and_state.md (noise-free runs; a few minutes
on two CPU cores).

    python docs/gen_rate_and_state.py            # write docs/img/rate_and_state_*.png
    python docs/gen_rate_and_state.py --quick    # a coarser regime map, for a trial run

- `rate_and_state_slip.png`: the plugin's noise-free cycle at the rig's softest spring and
  slowest drive (k = 168 N/m, V = 42 um/s) beside slips of the measured trace
  `examples/data/slider_paper_on_paper/k168Nm_v42.mat`, each aligned at its force peak and
  scaled by its own drop.
- `rate_and_state_regimes.png`: the regime the plugin predicts over the (k, V) plane (the
  critical stiffness of the linear analysis; stick-slip or oscillation below it from the
  noise-free limit cycle) with the measured regimes of the source's grid of runs.

The numbers behind the figures are printed.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

DOCS = pathlib.Path(__file__).resolve().parent
IMG = DOCS / "img"
TRACE = DOCS.parent / "examples" / "data" / "slider_paper_on_paper" / "k168Nm_v42.mat"
MASS, G = 0.0307, 9.81
# Orientation values for paper on paper (the order of those of Heslot et al. 1994), not
# fitted: N is the slider's weight.
PARAMS = dict(mass=MASS, normal_force=MASS * G, mu0=0.3, a=0.01, b=0.015, d_c=1e-6, v_ref=1e-6)
# The source's grid of runs and the regimes its traces show (k in N/m, V in m/s).
RUNS = [
    (168.0, 42e-6, "stick-slip"),
    (1002.0, 42e-6, "stick-slip"),
    (168.0, 1100e-6, "stick-slip"),
    (168.0, 4300e-6, "oscillation"),
    (1002.0, 4300e-6, "oscillation"),
    (2254.0, 4300e-6, "oscillation"),
]
COLORS = {"stick-slip": "tab:red", "oscillation": "tab:orange", "steady sliding": "tab:blue"}
DPI = 100


def measured_slips(ss, count=12):
    """Force around the first `count` slips of the measured trace: (t - t_peak, F) each."""
    from scipy.io import loadmat

    d = loadmat(TRACE)
    t = np.ravel(d["t"]) - np.ravel(d["t"])[0]
    F = np.ravel(d["Fnorm"]) * MASS * G
    cycles = ss.extract_cycles(t, force=F, stiffness=168.0, v_b=42e-6)
    out = []
    for t0, T in zip(cycles["release_time"][:count], cycles["slip_time"][:count], strict=True):
        w = (t > t0 - 0.1) & (t < t0 + T + 0.1)
        out.append((t[w] - t0, F[w]))  # (t0: the fitted start of the slip)
    print(f"measured: {len(cycles)} cycles; median slip {np.median(cycles['slip_time']):.4f} s, "
          f"drop {1e3 * np.median(cycles['force_drop']):.2f} mN, stick "
          f"{np.median(cycles['stick_time']):.3f} s")  # fmt: skip
    return out, cycles


def model_slip(ss, k=168.0, t_max=40.0):
    """The noise-free cycle at k, V = 42 um/s, on the limit cycle."""
    m = ss.get_model("rate-and-state")(stiffness=k, v_b=42e-6, **PARAMS)
    c = ss.simulate_cycles(m, 1, 2e-4, t_max, seed=0, record=True)
    t, ys, _ = c.trajectory(0)
    table = c.cycles
    i = np.nonzero(np.isfinite(table["period"]))[0][-1]
    t0, T = table["release_time"][i], table["slip_time"][i]
    w = (t > t0 - 0.1) & (t < t0 + T + 0.1)
    F = m.normal_force * m.a * ys[w, 0]
    print(f"model at k = {k:g} N/m: cycle {i}: slip {T:.4f} s, "
          f"drop {1e3 * table['force_drop'][i]:.2f} mN, "
          f"stick {table['stick_time'][i]:.3f} s, period {table['period'][i]:.3f} s, "
          f"peak {1e3 * table['peak_force'][i]:.2f} mN")  # fmt: skip
    return t[w] - t0, F, table, i


def _half_drop(t, F, lo, hi):
    """The time the force first falls through half its drop (linear interpolation, on the
    force's running median of 15 samples: a spike is no crossing)."""
    from scipy.ndimage import median_filter

    y = (median_filter(F, size=15, mode="nearest") - lo) / (hi - lo) - 0.5
    i = np.nonzero((y[:-1] > 0) & (y[1:] <= 0))[0][0]
    return t[i] + (t[i + 1] - t[i]) * y[i] / (y[i] - y[i + 1])


def slip_figure(plt, ss):
    slips, cycles = measured_slips(ss)
    model_slip(ss, 1002.0, 8.0)  # (its numbers, for the page's table)
    tm, Fm, table, i = model_slip(ss)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), dpi=DPI)
    for tt, F in slips:
        lo = np.median(F[tt > tt.max() - 0.05])
        hi = np.median(F[(tt > -0.06) & (tt < -0.02)])
        t_half = _half_drop(tt, F, lo, hi)
        axes[0].plot(1e3 * (tt - t_half), (F - lo) / (hi - lo), color="0.6", lw=0.6)
    lo, hi = Fm.min(), Fm[tm <= 0].max()
    t_half = _half_drop(tm, Fm, lo, hi)
    axes[0].plot(1e3 * (tm - t_half), (Fm - lo) / (hi - lo), color="tab:red", lw=2,
                 label="rate-and-state (noise-free)")  # fmt: skip
    axes[0].plot([], [], color="0.6", label="measured slips (k168Nm_v42)")
    axes[0].set(xlim=(-70, 70), xlabel="time from the half-drop (ms)",
                ylabel="(force - trough) / drop", title="slips scaled by their drops")  # fmt: skip
    axes[0].legend(fontsize=8)
    axes[1].plot(tm, 1e3 * Fm, color="tab:red")
    axes[1].set(xlabel="time from the force's peak (s)", ylabel="spring force (mN)",
                title="the model's slip, unscaled")  # fmt: skip
    fig.tight_layout()
    fig.savefig(IMG / "rate_and_state_slip.png")
    plt.close(fig)


def regime_figure(plt, ss, quick):
    RS = ss.get_model("rate-and-state")
    speeds = np.logspace(-5.5, -2, 5 if quick else 8)
    stiff = np.logspace(1.5, 4.7, 5 if quick else 8)
    V = np.logspace(-6, -1.7, 200)
    kc = [RS(stiffness=1.0, v_b=v, **PARAMS).critical_stiffness() for v in V]
    fig, ax = plt.subplots(figsize=(6.5, 4.8), dpi=DPI)
    ax.fill_between(1e6 * V, kc, 1e6, color=COLORS["steady sliding"], alpha=0.15)
    ax.plot(1e6 * V, kc, color=COLORS["steady sliding"], label="$k_c(V)$: steady sliding above")
    found = {}
    for v in speeds:
        for k in stiff:
            m = RS(stiffness=float(k), v_b=float(v), **PARAMS)
            if k >= m.critical_stiffness():
                continue
            r = ss.stability_report(m)
            found[(k, v)] = r
            ax.scatter(1e6 * v, k, s=60, marker="s", color=COLORS[r.regime], alpha=0.35, lw=0)
            print(f"k {k:9.1f} N/m  V {1e6 * v:9.2f} um/s  {r.regime:12s} {r.evidence}")
    for k, v, regime in RUNS:
        ax.scatter(1e6 * v, k, s=90, marker="o", color=COLORS[regime], edgecolor="k", zorder=5)
        m = RS(stiffness=k, v_b=v, **PARAMS)
        r = ss.stability_report(m)
        print(f"run k {k:6.0f} V {1e6 * v:6.0f}: measured {regime}; predicted {r.regime} "
              f"(k_c {m.critical_stiffness():.0f} N/m): {r.evidence}")  # fmt: skip
    for name, color in COLORS.items():
        ax.scatter([], [], marker="s", color=color, alpha=0.35, label=f"predicted {name}")
    ax.scatter([], [], marker="o", color="w", edgecolor="k", label="measured run (its regime)")
    ax.set(xscale="log", yscale="log", xlim=(1, 2e4), ylim=(20, 1e5),
           xlabel="driving speed V (um/s)", ylabel="spring stiffness k (N/m)",
           title="rate-and-state (orientation parameters) over the rig's grid")  # fmt: skip
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(IMG / "rate_and_state_regimes.png")
    plt.close(fig)
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a coarser regime map")
    parser.add_argument("--only", choices=("slip", "regimes"), help="make one figure")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import stickslip as ss

    IMG.mkdir(exist_ok=True)
    if args.only != "regimes":
        slip_figure(plt, ss)
    if args.only != "slip":
        regime_figure(plt, ss, args.quick)
    RS = ss.get_model("rate-and-state")
    m, fast = RS(stiffness=168.0, v_b=42e-6, **PARAMS), RS(stiffness=1.0, v_b=1100e-6, **PARAMS)
    print(f"k_c at 42 um/s: {m.critical_stiffness():.0f} N/m; quasi-static "
          f"N (b - a) / d_c = {m.normal_force * (m.b - m.a) / m.d_c:.0f} N/m; at 1100 um/s: "
          f"{fast.critical_stiffness():.0f}")  # fmt: skip


if __name__ == "__main__":
    main()
