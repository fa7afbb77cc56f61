"""Coverage of profile-likelihood intervals on a known surface with simulation-like noise.

    python benchmarks/profile_calibration.py [--free 4] [--sigma 1.5] [--tilt 0] [--step 1]
        [--sets 200] [--allowance 1] [--exact-covariance] [--warp 0]

The log-likelihood is a known quadratic, $-\\frac12 (u - m)^T C^{-1} (u - m)$, about a
maximum $m$ drawn from $N(0, C)$ (the data; the truth is 0), in `--free` parameters with
standard errors 1, 1.4, 1.7, 2 and correlations 0.5; to it every evaluated point adds its
own normal noise of sd `--sigma` log-likelihood units (the simulated likelihood's
roughness: through a measurement at `n_sim` 1000 a fit's profile moves by 3-6 units of the
statistic between values 3 % of a standard error apart) and each seed a random linear tilt
of sd `--tilt` a unit (its smooth part). Each set runs what a fit does: the local surface
about a start near $m$ (`surface.local_surface`, steps `--step` standard errors), the
sandwich covariance from its curvature $H$ and the true information, $H^{-1} C^{-1}
H^{-1}$ (`--exact-covariance`: $C$ itself), the vertex's simulation covariance measured
by 60 fresh draws of the noise on the same design (a fit measures it with a second seed
and a jackknife), and `profile_intervals`. Prints, per parameter, the share of sets whose
interval holds the truth (its sampling sd is about 0.015 at 200 sets), the intervals'
mean width over the data-only Wald width, and the estimates' spread over the intervals'
mean half-width / 1.96 (near 1 for calibrated intervals). `--allowance` scales the
profile's noise allowance (`profile.noisy_threshold`'s noise; 0: none), to see what it
does. `--warp W` makes the likelihood a quadratic in g(u) = u + W u^3 / sd^2 (each axis):
a true likelihood (its profile statistic at the truth still chi-square; the sandwich is
then the curvature's inverse) that the design's polynomial does not fit, so that its
residuals hold a lack of fit beside the noise.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import time
import warnings

import numpy as np


def correlation(p: int, rho: float = 0.5) -> np.ndarray:
    sd = np.sqrt(np.arange(1, p + 1, dtype=float))
    return (np.full((p, p), rho) + (1 - rho) * np.eye(p)) * np.outer(sd, sd)


class NoisyQuadratic:
    """The fit's `Likelihood` interface on the known surface: `(value, None)`; the noise
    at a point is a function of the point, the set and the seed (asked twice, the same).
    With `warp` the quadratic is in g(u) = u + warp u^3 / sd^2 (each axis; monotone), a
    likelihood that is not a polynomial in u, whose profile statistic at the truth is
    still chi-square: the design's polynomial then has a lack of fit."""

    def __init__(self, m, precision, sigma, tilts, salt, warp=0.0, sd=None):
        self.m, self.P, self.sigma, self.tilts, self.salt = m, precision, sigma, tilts, salt
        self.warp, self.sd = warp, sd

    def g(self, u):
        u = np.asarray(u, float)
        return u if not self.warp else u + self.warp * u**3 / self.sd**2

    def clean(self, u, tilt):
        d = self.g(u) - self.m
        return -0.5 * d @ self.P @ d + tilt @ np.asarray(u, float)

    def __call__(self, u, at_seed=0):
        u = np.asarray(u, float)
        key = u.tobytes() + self.salt.to_bytes(8, "little") + bytes([at_seed % 256])
        h = int.from_bytes(hashlib.blake2b(key, digest_size=8).digest(), "little")
        e = np.random.default_rng(h).standard_normal()
        return self.clean(u, self.tilts[at_seed % 2]) + self.sigma * e, None


@contextlib.contextmanager
def capped_inner_steps(k: float | None):
    """An experiment on `profile_intervals` (while the context lasts): the designs in the
    other parameters take steps of at most `k` of their curvature standard errors
    (`sqrt(diag(-H^-1))`, where finite) instead of the fit's; `None`: as built. Where the
    fit's steps span several standard errors the polynomial's lack of fit is read as the
    statistic's noise, and the steps cap it."""
    from stickslip._inference import estimator, profile

    if k is None:
        yield
        return
    built, plain = profile.profile_intervals, profile._Profiler.profiled

    def capped(loglik, surface, *args):
        H = np.asarray(surface.hessian, float)
        with np.errstate(invalid="ignore"):
            se = np.sqrt(np.diag(np.linalg.inv(-0.5 * (H + H.T))))
        steps = np.asarray(surface.steps, float)
        inner = np.where(np.isfinite(se) & (se > 0), np.minimum(steps, k * se), steps)
        profile._Profiler.profiled = lambda self, j, psi, start, _: plain(self, j, psi, start,
                                                                          inner)  # fmt: skip
        try:
            return built(loglik, surface, *args)
        finally:
            profile._Profiler.profiled = plain

    estimator.profile_intervals = profile.profile_intervals = capped
    try:
        yield
    finally:
        estimator.profile_intervals = profile.profile_intervals = built


def one_set(rng, C, sigma, tilt, step, exact, warp=0.0):
    from scipy.optimize import brentq

    from stickslip._inference import profile
    from stickslip._inference.surface import local_surface, polynomial_vertex

    p = C.shape[0]
    P = np.linalg.inv(C)
    L = np.linalg.cholesky(C)
    m = L @ rng.standard_normal(p)
    tilts = [tilt * rng.standard_normal(p) for _ in range(2)]
    sd = np.sqrt(np.diag(C))
    lik = NoisyQuadratic(m, P, sigma, tilts, int(rng.integers(2**62)), warp, sd)
    lo, hi = np.full(p, -40.0), np.full(p, 40.0)
    names = [f"x{i}" for i in range(p)]
    # the maximum in u: g^-1(m) each axis (g monotone)
    top = np.array([brentq(lambda x, i=i: lik.g(np.full(p, x))[i] - m[i], -40.0, 40.0)
                    for i in range(p)])  # fmt: skip
    surf = local_surface(lik, top + 0.1 * L @ rng.standard_normal(p), lo, hi, {}, names,
                         step=step)  # fmt: skip
    design, centre = np.asarray(surf.design), np.asarray(surf.centre)
    shifts = []
    for _ in range(60):  # the vertex's simulation noise: fresh draws on the same design
        t = tilt * rng.standard_normal(p)
        values = np.array([lik.clean(u, t) for u in design])
        values = values + sigma * rng.standard_normal(len(design))
        shift, _ = polynomial_vertex(design - centre, values, np.asarray(surf.steps))
        if shift is not None:
            shifts.append(shift)
    mc = np.cov(np.array(shifts).T) / 2.0  # (of two seeds' mean, as a fit reports it)
    H = np.asarray(surf.hessian)
    h_inv = np.linalg.inv(-0.5 * (H + H.T))
    cov = C if exact else h_inv @ P @ h_inv
    if warp:  # a true likelihood, not quadratic: no composite adjustment (c = 1 but for mc)
        cov = h_inv
    ci, records, _ = profile.profile_intervals(lik, surf, cov, mc, names,
                                               {k: "linear" for k in names}, lo, hi)  # fmt: skip
    return [(ci[k], records[k]) for k in names]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--free", type=int, default=4)
    parser.add_argument("--sigma", type=float, default=1.5)
    parser.add_argument("--tilt", type=float, default=0.0)
    parser.add_argument("--step", type=float, default=1.0)
    parser.add_argument("--sets", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--allowance", type=float, default=1.0)
    parser.add_argument("--exact-covariance", action="store_true")
    parser.add_argument("--inner-se", type=float, default=None,
                        help="an experiment: the profile's designs in the other parameters "
                        "at most this many of their standard errors a step")  # fmt: skip
    parser.add_argument("--warp", type=float, default=0.0,
                        help="the quadratic in u + warp u^3 / sd^2: a lack of fit (the "
                        "sandwich then the curvature's inverse: a true likelihood)")
    args = parser.parse_args(argv)

    from stickslip._inference import profile

    plain = profile.noisy_threshold
    profile.noisy_threshold = lambda c, noise, level=0.95: plain(c, args.allowance * noise, level)
    C = correlation(args.free)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    rows = []
    with warnings.catch_warnings(), capped_inner_steps(args.inner_se):
        warnings.simplefilter("ignore")
        for _ in range(args.sets):
            rows.append(one_set(rng, C, args.sigma, args.tilt, args.step, args.exact_covariance,
                                args.warp))  # fmt: skip
    sd = np.sqrt(np.diag(C))
    print(f"{args.free} free, sigma {args.sigma}, tilt {args.tilt}, step {args.step}, "
          f"warp {args.warp}, inner steps at most {args.inner_se} SE, "
          f"allowance x{args.allowance}, {args.sets} sets, "
          f"{'exact' if args.exact_covariance else 'sandwich'} covariance "
          f"({time.perf_counter() - t0:.0f} s)")  # fmt: skip
    print("| parameter | covered | width / Wald | spread / SE | threshold (median) | c | noise |")
    print("|---|---|---|---|---|---|---|")
    for i in range(args.free):
        ends = np.array([r[i][0] for r in rows])
        rec = [r[i][1] for r in rows]
        est = np.array([x["estimate"] for x in rec])
        covered = np.mean((ends[:, 0] <= 0) & (0 <= ends[:, 1]))
        half = np.mean(ends[:, 1] - ends[:, 0]) / 2
        print(f"| x{i} | {covered:.3f} | {half / (1.959964 * sd[i]):.2f} | "
              f"{np.std(est) / (half / 1.959964):.2f} | "
              f"{np.median([x['threshold'] for x in rec]):.2f} | "
              f"{np.median([x['adjustment'] for x in rec]):.2f} | "
              f"{np.median([x['noise'] for x in rec]):.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
