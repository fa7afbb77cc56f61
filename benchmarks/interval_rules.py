"""How a fit's interval rules compare on the same fits: each kept fit's design (its points,
both seeds' simulated cycles there: `fit_independent.py --keep DIR`) scored again, and the
estimate's covariance built by each rule from the same pieces:

- `sandwich + jackknife`: the sandwich (the first seed's polynomial, cubic terms along
  each axis, at its vertex as the bread) and the jackknife over the simulated cycles;
- `cubic bread + jackknife + difference`: that, plus the part of the two seeds' half
  difference the jackknife does not explain (what `fit` reported before the plain bread);
- `fit's rule`: the larger (`intervals.larger_covariance`) of that sandwich and the
  one with the plain bread (`intervals.with_plain_bread`: the curvature of a plain
  quadratic fitted to both seeds' mean values over the design), plus the seeds' noise as
  above: what `fit` reports;
- `plain bread + jackknife + difference`: the plain bread's sandwich alone, plus the
  seeds' noise (what `fit` reported before the larger of the two);
- `widened + half difference`: the sandwich widened by 1 + n/n_sim, plus the square of
  the two seeds' half difference (the rule before the jackknife);
- `Hessian + jackknife`: the Hessian's inverse instead of the sandwich;
- `quadratic bread + jackknife`: the plain bread and the jackknife, without the seeds'
  difference: along a weak direction the cubic terms, noisy, move the curvature at a
  vertex that lies steps away.

Per rule and parameter: the sd of (estimate - truth) / se over the fits with both
seeds' vertices (1 for honest intervals), and how many of them cover. Also the fit's rule
over all fits (a fit without an interval does not cover), and the mean square of the two
seeds' half difference over the jackknife's sd (about 1 where the jackknife holds the
simulation's noise).

    python benchmarks/interval_rules.py "kept/fixed-threshold-*.pkl"
    python benchmarks/interval_rules.py "kept/fixed-threshold-*.pkl" --time

`--ratio`: also the log-likelihood at the truth (one evaluation a fit, the fit's seed),
and whether the truth lies in the likelihood-ratio region the fit's surface calibrates
(`likelihood_ratio`).

`--profile` (a random threshold's kept fits): a lower bound on how often profile
intervals of the threshold's mean and sd would cover (`profile_bound`).

`--time`: what the jackknife costs a design point and seed against scoring the point
once (the first kept fit's centre; warmed, the median of 7 in this process).
"""

from __future__ import annotations

import glob
import math
import pickle
import sys

import numpy as np

from stickslip._inference import intervals as iv
from stickslip._inference.intervals import Z95
from stickslip._inference.likelihood import (
    cycle_log_likelihood,
    jackknife_values,
    scored_samples,
)
from stickslip._inference.surface import _Surface, polynomial_vertex, quadratic_design


def pieces(path):
    """A kept fit's estimate, truth and the rules' ingredients (fit coordinates)."""
    with open(path, "rb") as f:
        kept = pickle.load(f)
    r, truth = kept["fit"], kept["truth"]
    d = r.diagnostics
    design = d["design"]
    names = list(r.estimate)
    points = np.array(design["points"])
    centre, steps = np.array(design["centre"]), np.array(design["steps"])

    def seed(s):
        scores, values, blocks = [], [], []
        for sim in design["samples"][s]:
            args = (r.data, sim, d["bandwidth"], d["measurement"])
            t = None if sim is None else scored_samples(*args)
            scores.append(None if t is None else np.sum([t[k] for k in r.data], axis=0))
            values.append(-np.inf if t is None else float(sum(np.sum(v) for v in t.values())))
            blocks.append(jackknife_values(r.data, sim, d["bandwidth"], d["measurement"]))
        return scores, np.array(values), np.array(blocks)

    s1, v1, b1 = seed(0)
    s2, v2, b2 = seed(1)
    shift, H = polynomial_vertex(points - centre, v1, steps)
    shift2, H2 = polynomial_vertex(points - centre, v2, steps)
    surface = _Surface(centre=centre, steps=steps, nominal=quadratic_design(centre, steps),
                       design=points, values=list(v1), scores=s1, shift=shift, hessian=H,
                       clipped=design["clipped"])  # fmt: skip
    lag = iv.structural_lag(r.model)
    sandwich, _, _ = iv.sandwich_covariance(surface, names, s2, lag)
    big = np.full(len(names), 1e9)
    _, cubic, _ = iv.combine_seeds(surface, shift2, sandwich, [b1, b2], -big, big)
    plain = iv.with_plain_bread(surface, v2)
    fits = plain_fits = iv.sandwich_covariance(plain, names, s2, lag)[0]
    if plain is not surface:
        fits = iv.larger_covariance(plain_fits, sandwich)
    u_hat, cov, noise = iv.combine_seeds(surface, shift2, fits, [b1, b2], -big, big)
    scales = d["scales"]
    truth = np.array([math.log(truth[k]) if scales[k] == "log" else truth[k] for k in names])
    out = dict(names=names, truth=truth, u=u_hat, fits=cov, interval=noise["mc"] is not None
               and iv.concave(H), check=noise["check"], bread=plain.hessian,
               ratio=None)  # fmt: skip
    # what the fit's rule was built from, for a rule built otherwise (`ridge_checks.py`)
    out["parts"] = dict(surface=surface, plain=plain, scores2=s2, blocks=[b1, b2],
                        shift2=shift2, values=(v1, v2), lag=lag)  # fmt: skip
    if "--ratio" in sys.argv[2:]:  # 2 x the log-likelihood's fall from the estimate to the truth
        at_truth = cycle_log_likelihood(r, params=kept["truth"]).sum()
        out["ratio"] = 2.0 * (r.log_likelihood - float(at_truth))
    if shift is None or shift2 is None:
        return out
    jack = [iv._jackknife(surface, b) for b in (b1, b2)]
    if any(j is None for j in jack):
        return out
    mc = 0.25 * (jack[0] + jack[1])
    half = 0.5 * (shift - shift2)
    n = next(iter(r.data.values())).size
    out["rules"] = {
        "sandwich + jackknife": sandwich + mc,
        "cubic bread + jackknife + difference": cubic,
        "fit's rule": cov,
        "widened + half difference": sandwich * (1 + n / d["n_sim"]) + np.outer(half, half),
        "Hessian + jackknife": np.linalg.inv(-0.5 * (H + H2)) + mc,
    }
    if plain is not surface:
        out["rules"]["quadratic bread + jackknife"] = plain_fits + mc
        _, out["rules"]["plain bread + jackknife + difference"], _ = iv.combine_seeds(
            surface, shift2, plain_fits, [b1, b2], -big, big)  # fmt: skip
    return out


def timing(path) -> None:
    import time

    with open(path, "rb") as f:
        r = pickle.load(f)["fit"]
    d = r.diagnostics
    sim = d["design"]["samples"][0][0]
    args = (r.data, sim, d["bandwidth"], d["measurement"])
    calls = (("scored once", scored_samples), ("the 10 blocks' values", jackknife_values))
    for what, call in calls:
        call(*args)
        times = []
        for _ in range(7):
            t0 = time.perf_counter()
            call(*args)
            times.append(time.perf_counter() - t0)
        print(f"{what}: {np.median(times) * 1e3:.1f} ms a point and seed "
              f"({min(np.size(sim[k]) for k in r.data)} simulated cycles)")  # fmt: skip


def likelihood_ratio(found) -> None:
    """Whether the truth lies in the likelihood-ratio region the fit's own surface
    calibrates: 2 (l(estimate) - l(truth)) at the fit's seed against the 95 % point of
    sum_i lambda_i chi2_1, lambda the eigenvalues of the covariance times the bread's
    information (H^-1 J for a composite likelihood; the simulation's share included)."""
    rng = np.random.default_rng(0)
    covered, rows = 0, []
    with_interval = [f for f in found if f["interval"]]
    for f in with_interval:
        lam = np.linalg.eigvals(f["fits"] @ -f["bread"]).real
        q = np.quantile((rng.chisquare(1, (100_000, lam.size)) * lam).sum(axis=1), 0.95)
        covered += f["ratio"] <= q
        rows.append(f"{f['ratio']:.1f} (95 % {q:.1f})")
    others = [f"{f['ratio']:.1f}" for f in found if not f["interval"]]
    print(f"likelihood-ratio region: covers the truth in {covered} of {len(with_interval)} "
          f"fits with an interval; 2 dlogL (estimate - truth): {', '.join(rows)}; "
          f"without an interval: {', '.join(others) or 'none'}")  # fmt: skip


def _fall(x, r, at, other) -> float:
    """Minus the fit's log-likelihood (its seed) at `at` with `other` = x."""
    v = cycle_log_likelihood(r, params={**at, other: x}).sum()
    return -v if np.isfinite(v) else 1e9


def profile_bound(paths, found) -> None:
    """A rough lower bound on how often profile-likelihood intervals would cover the random
    threshold's mean and sd: the truth's profile statistic 2 (l(estimate) - max l) with
    the parameter at the truth and only its partner (sd, or mean) maximised (bounded
    Brent, to 0.005), omega0 and D at the estimate (not maximising them can only raise
    the statistic; l(estimate) is the fit's seed's value at the two seeds' mean vertex,
    not that seed's maximum, which can lower it by the surface's noise), against 3.84 c,
    c the parameter's sandwich variance over the bread's inverse (a composite
    likelihood's scalar adjustment); ~15 evaluations a parameter."""
    from scipy.optimize import minimize_scalar

    pairs = (("threshold_params.mean", "threshold_params.sd", (0.1, 1.6)),
             ("threshold_params.sd", "threshold_params.mean", (0.2, 1.8)))  # fmt: skip
    covered = dict.fromkeys([p[0] for p in pairs], 0)
    for path, f in zip(paths, found, strict=True):
        with open(path, "rb") as fh:
            kept = pickle.load(fh)
        r, truth = kept["fit"], kept["truth"]
        naive = np.linalg.inv(-f["bread"])
        for target, other, bounds in pairs:
            i = f["names"].index(target)
            best = minimize_scalar(_fall, bounds=bounds, method="bounded",
                                   args=(r, {target: truth[target]}, other),
                                   options=dict(xatol=0.005))  # fmt: skip
            stat = 2.0 * (r.log_likelihood + best.fun)
            covered[target] += stat <= Z95**2 * f["fits"][i, i] / naive[i, i]
    print("profile intervals (a lower bound on their coverage): " + ", ".join(
        f"{k} {c}/{len(found)}" for k, c in covered.items()))  # fmt: skip


def main():
    paths = sorted(glob.glob(sys.argv[1]))
    if not paths:
        sys.exit(f"no kept fits match {sys.argv[1]}")
    if "--time" in sys.argv[2:]:
        timing(paths[0])
        return
    found = [pieces(p) for p in paths]
    names = found[0]["names"]
    both = [f for f in found if "rules" in f]
    print(f"{len(found)} fits, {len(both)} with both seeds' vertices and a jackknife")
    print("| rule | " + " | ".join(f"{k}: z sd, covered" for k in names) + " |")
    print("|---|" + "---|" * len(names))
    rules = list(dict.fromkeys(rule for f in both for rule in f["rules"]))
    for rule in rules:  # (a rule a fit could not make is left out of its row: n < all)
        has = [f for f in both if rule in f["rules"]]
        z = np.array([(f["u"] - f["truth"]) / np.sqrt(np.diag(f["rules"][rule])) for f in has])
        cells = [f"{z[:, i].std():.2f}, {int(np.sum(np.abs(z[:, i]) < iv.Z95))}/{len(has)}"
                 for i in range(len(names))]  # fmt: skip
        print(f"| {rule} | " + " | ".join(cells) + " |")
    covered = np.zeros(len(names), int)
    for f in found:
        if f["interval"]:
            se = np.sqrt(np.diag(f["fits"]))
            covered += np.abs(f["u"] - f["truth"]) <= iv.Z95 * se
    print("fit's rule over all fits: covered " + ", ".join(
        f"{k} {c}/{len(found)}" for k, c in zip(names, covered, strict=True))
        + f"; {sum(not f['interval'] for f in found)} without an interval")  # fmt: skip
    if "--ratio" in sys.argv[2:]:
        likelihood_ratio(found)
    if "--profile" in sys.argv[2:]:
        profile_bound(paths, found)
    checks = np.array([f["check"] for f in found if f["check"] is not None])
    if checks.size:
        print("seeds' half difference / jackknife sd, mean square: " + ", ".join(
            f"{k} {v:.2f}" for k, v in zip(names, (checks**2).mean(axis=0), strict=True))
            + f" ({len(checks)} fits)")  # fmt: skip


if __name__ == "__main__":
    main()
