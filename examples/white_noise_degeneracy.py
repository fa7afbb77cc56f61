"""White friction noise makes the paper's slip phase degenerate: a table as dt shrinks.

    python examples/white_noise_degeneracy.py [--n-paths 20000]

For the paper's eq. (8) with white noise (omega0 = 1, zeta = 0.1, D = 0.4, v_b = 1, x0 = 1),
prints, at several dt, the fraction of slips shorter than 0.1 and the fraction that end in
the first step, with grid monitoring (the paper's Euler-Maruyama simulations) and with
the Brownian-bridge test (continuous monitoring); then the same for Ornstein-Uhlenbeck noise
(tau = 0.1), which is well posed.
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-paths", type=int, default=20_000)
    args = parser.parse_args(argv)
    import stickslip as ss

    Model = ss.get_model("langevin")
    params = dict(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0)
    n = args.n_paths
    se = np.sqrt(0.25 / n)
    print(f"{n} paths per cell; standard error of a fraction <= {se:.4f}")
    print(
        f"{'noise':6s} {'monitoring':22s} {'dt':>8s} {'P(T_sl < 0.1)':>14s} {'P(first step)':>14s}"
    )
    cases = [
        ("white", dict(solver="euler", monitor="grid"), "grid (Euler-Maruyama)", {}),
        ("white", dict(solver="euler"), "Brownian bridge", {}),
        ("OU", dict(), "continuous (exact)", {"tau": 0.1}),
    ]
    for noise, kw, label, extra in cases:
        for dt in (0.02, 0.005, 0.00125):
            e = ss.simulate(Model(**params, **extra), n, dt, 10.0, seed=1, **kw)
            early = np.mean(e.slip_time < 0.1)
            first = np.mean(e.slip_time <= dt)
            print(f"{noise:6s} {label:22s} {dt:8.5f} {early:14.4f} {first:14.4f}")
    return 0


if __name__ == "__main__":
    main()
