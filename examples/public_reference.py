"""Monte Carlo of the public reference set against an independent implementation.

    python examples/public_reference.py --out results [--n-paths 100000]

Simulates one slip-stick cycle for each of `--n-paths` paths of the Langevin model with
Ornstein-Uhlenbeck friction noise (omega0 = 1, zeta = 0.1, D = 0.4, v_b = 1, x0 = 1,
tau = 0.1), and a few paths through many cycles, then writes to `--out`:

- `ensemble.npz`: slip times, slip distances, stick times and periods of every path;
- `slip_time.png`, `slip_distance.png`: histograms against the reference histograms
  (2e5 paths from an independent NumPy implementation, `tests/data/`);
- `time_series.png`: stick-slip motion of one path (the paper's fig. 2) and its phase
  portrait (fig. 7);
- `summary.md`: means, chi-square homogeneity tests and timings.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
DATA = HERE.parent / "tests" / "data"
PARAMS = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)


def chi2_homogeneity(a, b, min_expected=5.0):
    """Chi-square homogeneity test of two histograms on the same bins (sparse bins merged)."""
    from scipy import stats

    na, nb = a.sum(), b.sum()
    rows, acc = [], np.zeros(2)
    for x, y in zip(a, b, strict=True):
        acc += (x, y)
        if acc.sum() * min(na, nb) / (na + nb) >= min_expected:
            rows.append(acc.copy())
            acc[:] = 0
    if acc.sum() and rows:
        rows[-1] += acc
    stat, p, dof, _ = stats.chi2_contingency(np.array(rows).T, correction=False)
    return stat, dof, p


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=pathlib.Path, required=True, help="output directory")
    parser.add_argument("--n-paths", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import stickslip as ss

    ref = np.load(DATA / "langevin_ou_public.npz")
    meta = json.loads((DATA / "langevin_ou_public.json").read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    model = ss.get_model("langevin")(**PARAMS)

    t0 = time.perf_counter()
    ens = ss.simulate(model, args.n_paths, 0.005, 30.0, seed=args.seed, progress=True)
    t_sim = time.perf_counter() - t0
    grid = ss.simulate(model, args.n_paths, 0.005, 30.0, seed=args.seed, monitor="grid")
    t0 = time.perf_counter()
    series = ss.simulate_cycles(model, 1, 0.005, 40.0, seed=args.seed)
    t_series = time.perf_counter() - t0

    np.savez_compressed(
        args.out / "ensemble.npz",
        slip_time=ens.slip_time,
        slip_distance=ens.slip_distance,
        stick_time=ens.stick_time,
        period=ens.period,
        immediate=ens.immediate,
    )

    lines = [
        "# Public reference set: Monte Carlo against an independent implementation",
        "",
        f"Model: langevin {PARAMS}; {args.n_paths} paths, exact stepping, dt = 0.005.",
        f"Reference: {meta['mc']['n_paths']} paths, {meta['mc']['stepping']}.",
        "",
        "| quantity | continuous monitoring | grid monitoring | reference |",
        "|---|---|---|---|",
    ]
    for name, key in (("mean slip time", "mean_T"), ("mean slip distance", "mean_d")):
        attr = "slip_time" if key == "mean_T" else "slip_distance"
        (m1, s1), (m2, s2) = ens.mean(attr), grid.mean(attr)
        lines.append(f"| {name} | {m1:.4f} ± {s1:.4f} | {m2:.4f} ± {s2:.4f} | {meta[key]:.4f} |")
    for label, attr, edges, counts in (
        ("slip time", "slip_time", ref["T_edges"], ref["T_counts"]),
        ("slip distance", "slip_distance", ref["d_edges"], ref["d_counts"]),
    ):
        res = []
        for e in (ens, grid):
            c, _ = np.histogram(getattr(e, attr)[e.stuck], bins=edges)
            stat, dof, p = chi2_homogeneity(c, counts)
            res.append(f"chi2 = {stat:.1f} (dof {dof}), p = {p:.3g}")
        lines.append(f"| histogram of {label} | {res[0]} | {res[1]} | |")
    lines += [
        "",
        f"Simulation: {t_sim:.2f} s wall ({ens.stats['compile_seconds']:.2f} s compiling), "
        f"{ens.stats['path_steps']:.3g} path-steps; time series: {t_series:.2f} s.",
        "",
        "Grid monitoring is the reference's own convention (first grid point with "
        "v >= v_b, linear interpolation); it matches both reference histograms. Continuous "
        "monitoring (the default) also finds sticks inside a step and places them on the exact "
        "bridge mean; its slip-distance histogram differs from the reference near d = 0, where "
        "the grid convention puts every path that crosses within the first step at exactly "
        "T_sl = 0, d = 0 (linear interpolation from v(0) = v_b), while the paths in fact dip "
        "below v_b first.",
    ]
    (args.out / "summary.md").write_text("\n".join(lines) + "\n")

    time_label = r"slip time $T_{sl}$ ($1/\omega_0$)"
    distance_label = r"slip distance $d$ ($v_b/\omega_0$)"
    for attr, edges, counts, xlabel, fname in (
        ("slip_time", ref["T_edges"], ref["T_counts"], time_label, "slip_time.png"),
        ("slip_distance", ref["d_edges"], ref["d_counts"], distance_label, "slip_distance.png"),
    ):
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        width = np.diff(edges)
        centres = 0.5 * (edges[1:] + edges[:-1])
        ref_density = counts / counts.sum() / width
        ax.step(
            centres,
            ref_density,
            where="mid",
            color="0.3",
            lw=1.2,
            label="reference (2e5 paths, NumPy)",
        )
        values, errors, _ = ens.histogram(attr, edges)
        ax.errorbar(
            centres,
            values,
            yerr=errors,
            fmt="x",
            ms=3,
            color="C3",
            label=f"stickslip ({args.n_paths} paths)",
        )
        ax.set_xlabel(xlabel)
        ax.set_ylabel("probability density")
        if attr == "slip_time":
            ax.set_xlim(0, 15)
            ax.set_yscale("log")
        ax.legend()
        ax.set_title(
            r"Langevin, OU noise: $\omega_0=1, \zeta=0.1, D=0.4, v_b=1, x_0=1, \tau=0.1$",
            fontsize=9,
        )
        fig.tight_layout()
        fig.savefig(args.out / fname, dpi=120)
        plt.close(fig)

    t, X, slipping = series.trajectory(0)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8), gridspec_kw={"width_ratios": [2, 1]})
    a1.plot(t, X[:, 0], color="C0", lw=0.9, label="position $x$")
    a1.plot(t, X[:, 1], color="C1", lw=0.9, label="velocity $v$")
    a1.axhline(PARAMS["v_b"], color="0.5", ls=":", lw=0.8, label="$v_b$")
    a1.set_xlabel(r"time $t$ ($1/\omega_0$)")
    a1.set_ylabel("$x$, $v$")
    a1.legend(loc="lower left", fontsize=8)
    a1.set_title("stick-slip motion (flat segments of $v$: sticks)", fontsize=9)
    for start, stop in _slips(slipping)[:6]:
        a2.plot(X[start:stop, 0], X[start:stop, 1], lw=0.8)
    a2.set_xlabel("position $x$")
    a2.set_ylabel("velocity $v$")
    a2.set_title("phase portrait of six slips", fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out / "time_series.png", dpi=120)
    plt.close(fig)
    print((args.out / "summary.md").read_text())
    return 0


def _slips(slipping):
    """(start, stop) index ranges of the slips in a trajectory (stop includes the stick)."""
    ends = np.nonzero(~slipping)[0]
    starts = np.r_[0, ends[:-1] + 1]
    return list(zip(starts, ends + 1, strict=True))


if __name__ == "__main__":
    sys.exit(main())
