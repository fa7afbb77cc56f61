"""Make the figures of docs/theory.md (fixed seeds; about a minute on two CPU cores).

    python docs/gen_theory_figures.py            # write docs/img/theory_*.png
    python docs/gen_theory_figures.py --quick    # fewer paths, for a trial run

- `theory_white_noise.png`: the white-noise degeneracy. The fraction of slips shorter than
  0.1 and the mean slip time against the step dt, for white friction noise (Euler-Maruyama
  with grid monitoring, as in the paper's simulations, and with the Brownian-bridge test)
  and for Ornstein-Uhlenbeck noise with tau = 0.1 and 0.01 (exact stepping).
- `theory_n1_sign.png`: the sign slip in eq. (12). The upcrossing density n1 with E[a^+]
  (Rice, exact for OU noise), the same with eq. (12) as printed (E[a^-]), and a histogram of
  simulated upcrossings, for the public OU set.

The numbers behind the figures are printed.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np
import scipy.linalg
import scipy.special
from scipy.stats import norm

IMG = pathlib.Path(__file__).resolve().parent / "img"
BASE = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
STEPS = (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)
DPI = 100


def white_noise_figure(plt, ss, n_paths):
    """Slips shorter than 0.1 and mean slip time against dt, white against OU noise."""
    Model = ss.get_model("langevin")
    cases = [
        ("white noise, Euler-Maruyama, grid monitoring", {}, dict(solver="euler", monitor="grid")),
        ("white noise, Brownian-bridge test", {}, dict(solver="euler")),
        (r"OU noise, $\tau = 0.01$, exact stepping", {"tau": 0.01}, {}),
        (r"OU noise, $\tau = 0.1$, exact stepping", {"tau": 0.1}, {}),
    ]
    styles = ["o-", "s--", "^-", "v-"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.6, 3.6))
    print(f"white-noise degeneracy, {n_paths} paths per point (seed 1)")
    print(f"{'case':48s} {'dt':>7s} {'P(T<0.1)':>9s} {'se':>7s} {'mean T':>7s} {'se':>6s}")
    for (label, extra, kw), style in zip(cases, styles, strict=True):
        model = Model(**BASE, **extra)
        early, early_se, mean, mean_se = [], [], [], []
        # tau = 0.1 has converged by dt = 0.001; its long slips make smaller steps slow
        steps = STEPS[:-1] if extra.get("tau") == 0.1 else STEPS
        for dt in steps:
            ens = ss.simulate(model, n_paths, dt, 40.0, seed=1, progress=False, **kw)
            p = float(np.mean(ens.slip_time < 0.1))
            m, se = ens.mean("slip_time")
            early.append(p)
            early_se.append(np.sqrt(p * (1 - p) / n_paths))
            mean.append(m)
            mean_se.append(se)
            print(f"{label:48s} {dt:7.4f} {p:9.4f} {early_se[-1]:7.4f} {m:7.3f} {se:6.3f}")
        a1.errorbar(steps, early, yerr=early_se, fmt=style, ms=4, label=label)
        a2.errorbar(steps, mean, yerr=mean_se, fmt=style, ms=4, label=label)
    for ax in (a1, a2):
        ax.set_xscale("log")
        ax.set_xlabel(r"time step $dt$ ($1/\omega_0$)")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    a1.set_ylabel(r"$P(T_{sl} < 0.1)$")
    a1.set_ylim(0, 1.05)
    a2.set_ylabel(r"mean slip time $E[T_{sl}]$")
    a2.set_ylim(bottom=0)
    a2.legend(fontsize=7, loc="center left")
    fig.suptitle(
        r"Langevin: $\omega_0=1, \zeta=0.1, D=0.4, v_b=1, x_0=1$; " f"{n_paths} paths per point",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(IMG / "theory_white_noise.png", dpi=DPI)
    plt.close(fig)


def velocity_moments(model, h, n):
    """Mean and covariance of the free slip state on t = 0, h, ..., n h (exact recursion
    with one-step propagators from Van Loan's block exponential at the small step h)."""
    lg = model.linear_gaussian()
    A, B, m0, P0 = (np.asarray(z, float) for z in (lg.A, lg.B, lg.m0, lg.P0))
    d = A.shape[0]
    M = np.zeros((2 * d, 2 * d))
    M[:d, :d], M[:d, d:], M[d:, d:] = -A, B @ B.T, A.T
    E = scipy.linalg.expm(M * h)
    Phi = E[d:, d:].T
    Q = Phi @ E[:d, d:]
    mu, S = np.empty((n + 1, d)), np.empty((n + 1, d, d))
    mu[0], S[0] = m0, P0
    for k in range(n):
        mu[k + 1] = Phi @ mu[k]
        S[k + 1] = Phi @ S[k] @ Phi.T + Q
    return mu, S


def upcrossing_figure(plt, ss, n_paths):
    """n1 with E[a^+], with eq. (12) as printed (E[a^-]), and simulated upcrossings."""
    p = dict(BASE, tau=0.1)
    model = ss.get_model("langevin")(**p)
    h, n = 0.001, 10_500
    t = h * np.arange(1, n + 1)
    mu, S = velocity_moments(model, h, n)
    mu, S = mu[1:], S[1:]
    # v = state[1], a = dv/dt = -omega0^2 x - zeta v + eta
    g = np.array([0.0, 1.0, 0.0])
    r = np.array([-(p["omega0"] ** 2), -p["zeta"], 1.0])
    mv, ma = mu @ g, mu @ r
    cvv = np.einsum("i,kij,j->k", g, S, g)
    cav = np.einsum("i,kij,j->k", r, S, g)
    caa = np.einsum("i,kij,j->k", r, S, r)
    pv = norm.pdf(p["v_b"], mv, np.sqrt(cvv))
    m = ma + cav / cvv * (p["v_b"] - mv)  # a | v = v_b ~ N(m, s^2)
    s = np.sqrt(caa - cav**2 / cvv)
    plus = s * norm.pdf(m / s) + m * norm.cdf(m / s)  # E[a^+]
    printed = np.sqrt(s**2 / (2 * np.pi)) * np.exp(-(m**2) / (2 * s**2)) - m / 2 * (
        scipy.special.erfc(m / (np.sqrt(2) * s))
    )  # eq. (12) as printed: E[a^-]
    n1, n1_printed = pv * plus, pv * printed
    est = ss.CrossingEstimator(model)
    check = float(np.max(np.abs(n1 - est.n1(t))))

    ens = ss.simulate(model, n_paths, 0.005, 10.5, seed=2, record_upcrossings=12, progress=False)
    up = ens.upcrossings
    times = up.times[~up.immediate].ravel()
    times = times[np.isfinite(times)]
    print(f"\nupcrossings: {up.n_paths} free paths (seed 2), {times.size} upcrossings by t = 10.5")
    print(f"n1 from the moments here against CrossingEstimator.n1: max difference {check:.1e}")
    print(f"integral over [0, 10]: n1 {np.trapezoid(n1[t <= 10], t[t <= 10]):.4f}, ", end="")
    print(f"printed {np.trapezoid(n1_printed[t <= 10], t[t <= 10]):.4f}, ", end="")
    print(f"simulated {np.sum(times <= 10) / up.n_paths:.4f}")
    i, j = np.argmax(n1), np.argmax(n1_printed)
    print(
        f"first peak: n1 {n1[i]:.3f} at t = {t[i]:.3f}; printed {n1_printed[j]:.3f} at {t[j]:.3f}"
    )

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.6, 3.6))
    for ax, width, t_end, logy in ((a1, 0.1, 10.0, True), (a2, 0.01, 0.5, False)):
        edges = np.arange(0.0, t_end + width / 2, width)
        centres = 0.5 * (edges[1:] + edges[:-1])
        counts = np.histogram(times, bins=edges)[0]
        dens, err = counts / up.n_paths / width, np.sqrt(counts) / up.n_paths / width
        # z-scores of the histogram against bin averages of each formula
        for name, curve in (("E[a+]", n1), ("printed", n1_printed)):
            mass = np.concatenate([[0.0], np.cumsum(curve) * h])
            cell = np.diff(np.interp(edges, np.concatenate([[0.0], t]), mass)) / width
            ok = counts >= 20
            chi2 = np.sum(((dens - cell)[ok] / err[ok]) ** 2)
            print(f"[0, {t_end}] bins of {width}: {name:8s} chi2 = {chi2:9.1f} on {ok.sum()} bins")
        keep = t <= t_end
        ax.plot(t[keep], n1[keep], color="C3", label=r"$n_1 = p_v\,E[a^+\mid v_b]$ (Rice, exact)")
        ax.plot(t[keep], n1_printed[keep], "--", color="C0", label=r"eq. (12) as printed: $E[a^-]$")
        ax.errorbar(
            centres, dens, yerr=err, fmt="x", ms=3, color="k", label="simulated upcrossings"
        )
        ax.set_xlabel(r"time $t$ ($1/\omega_0$)")
        if logy:
            ax.set_yscale("log")
            ax.set_ylim(1e-3, 10)
        else:
            ax.set_ylim(bottom=0)
    a1.set_ylabel(r"upcrossing density $n_1(t)$")
    a1.legend(fontsize=7, loc="lower right")
    a2.set_title(r"the first half time unit (bins of 0.01)", fontsize=9)
    fig.suptitle(
        r"OU noise: $\omega_0=1, \zeta=0.1, D=0.4, v_b=1, x_0=1, \tau=0.1$; "
        f"upcrossings of {up.n_paths} free paths",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(IMG / "theory_n1_sign.png", dpi=DPI)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer paths (a trial run)")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import stickslip as ss

    IMG.mkdir(exist_ok=True)
    white_noise_figure(plt, ss, 2_000 if args.quick else 20_000)
    upcrossing_figure(plt, ss, 2_000 if args.quick else 20_000)


if __name__ == "__main__":
    main()
