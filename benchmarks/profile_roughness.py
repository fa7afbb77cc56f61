"""What the profile's reference residuals are on a joint fit: noise, or the polynomial's
lack of fit. One set of `fit_joint_independent.py` (two springs, the random threshold,
`n_sim` 1000), fitted as there up to its profile intervals; then, per free parameter,
the others' design about the estimate at the fit's steps and at a half and a quarter of
them (the residual variance about the polynomial `profile_intervals` reads its noise
allowance from), and the values of the unit design's points against neighbours 1 % of a
step away, the polynomial's own difference between the two taken off (half their mean
squared difference: the surface's roughness at that scale). Last, the profile's own
values at five values of the parameter 0.05 standard errors apart about the estimate
(their sd is small: common random numbers keep nearby designs' values together, and the
noise that moves the statistic lives at the scale of the tries, a good part of a
standard error apart).

    python benchmarks/profile_roughness.py --set 40
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import fit_joint_independent as joint  # noqa: E402

NEIGHBOUR = 0.01  # the neighbours' distance, in steps
REPLICATE = 0.05  # the profile's values near the estimate, this many standard errors apart


def residual_variance(points, centre, value):
    """The values' variance about the profile's polynomial over `points`."""
    from stickslip._inference.surface import polynomial_terms

    y = np.array([value(u) for u in points], float)
    X = polynomial_terms(points - centre)
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    return float(np.sum((y - X @ coef) ** 2)) / (X.shape[0] - X.shape[1])


def roughness(points, centre, steps, value):
    """Half the mean squared difference between each point and a neighbour `NEIGHBOUR`
    steps away along every axis (signs alternating), less the polynomial's difference."""
    from stickslip._inference.surface import polynomial_terms

    n, m = points.shape
    sign = np.where((np.arange(n)[:, None] + np.arange(m)[None, :]) % 2 == 0, 1.0, -1.0)
    near = points + sign * NEIGHBOUR * steps
    at = np.array([value(u) for u in points], float)
    diff = np.array([value(u) for u in near], float) - at
    X = polynomial_terms(points - centre)
    coef = np.linalg.lstsq(X, at, rcond=None)[0]
    diff -= (polynomial_terms(near - centre) - X) @ coef
    return 0.5 * float(np.mean(diff**2))


def fitted_surface(i: int):
    """Set i fitted up to its profile intervals: the first seed's likelihood, the local
    surface and the box (what `profile_intervals` is given)."""
    import stickslip as ss
    from stickslip._inference import estimator

    caught = {}

    class Reached(Exception):
        pass

    def reach(loglik, surface, cov, mc, names, coords, lo, hi):
        caught.update(loglik=loglik, surface=surface, names=names, lo=lo, hi=hi)
        raise Reached

    runs, rig = joint.campaign("random", i)
    model, free, fixed, _ = joint.problem("random", rig)
    plain = estimator.profile_intervals
    estimator.profile_intervals = reach
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ss.fit(model, runs, free, fixed, n_sim=1000, seed=60_000 + i, intervals="profile")
    except Reached:
        pass
    finally:
        estimator.profile_intervals = plain
    return caught


def by_scale(i: int):
    from stickslip._inference import profile
    from stickslip._inference.surface import quadratic_design

    t0 = time.perf_counter()
    got = fitted_surface(i)
    print(f"set {i}: fitted to its profile in {time.perf_counter() - t0:.0f} s", flush=True)
    prof = profile._Profiler(got["loglik"], got["lo"], got["hi"])
    s = got["surface"]
    steps, centre = np.asarray(s.steps, float), np.asarray(s.centre, float)
    _, u1, _, _ = profile._smoothed_max(np.asarray(s.design, float), centre, steps, prof)
    H = np.asarray(s.hessian, float)
    se = np.sqrt(np.diag(np.linalg.inv(-0.5 * (H + H.T))))
    print("| parameter | residual var. x1 | x1/2 | x1/4 | neighbours' roughness | allowance's "
          "noise (x1) | the profile's values near the estimate: sd | noise from it |")
    print("|---|---|---|---|---|---|---|---|")
    for j, name in enumerate(got["names"]):
        others = [a for a in range(u1.size) if a != j]

        def value(row, others=others):
            u = u1.copy()
            u[others] = row
            return prof(u)

        residual = [residual_variance(quadratic_design(u1[others], steps[others] * f),
                                      u1[others], value)
                    for f in (1.0, 0.5, 0.25)]  # fmt: skip
        rough = roughness(quadratic_design(u1[others], steps[others]), u1[others],
                          steps[others], value)  # fmt: skip
        _, _, _, var_ref = prof.profiled(j, u1[j], u1.copy(), steps)
        # the profile's own values at psi 0-10 % of the curvature's standard error from the
        # estimate (its true change there under 0.005 units): their scatter is the noise a
        # value of the statistic carries
        near = [prof.profiled(j, u1[j] + k * REPLICATE * se[j], u1.copy(), steps)[0]
                for k in (-2, -1, 0, 1, 2)]  # fmt: skip
        sd = float(np.std(near, ddof=1))
        print(f"| {name} | {residual[0]:.3g} | {residual[1]:.3g} | {residual[2]:.3g} | "
              f"{rough:.3g} | {2 * math.sqrt(2 * var_ref):.2f} | {sd:.2f} | "
              f"{2 * math.sqrt(2) * sd:.2f} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", type=int, default=40)
    by_scale(parser.parse_args().set)


if __name__ == "__main__":
    main()
