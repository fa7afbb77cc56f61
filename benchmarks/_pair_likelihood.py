"""An experiment, not the library's likelihood: a row's stick time scored given the slip's
drop, in place of its marginal (`fit_independent.py --likelihood pair`).

The fit's likelihood is composite: each column's marginal density (`likelihood`). Within a
row of a force trace's cycles the drop and the stick that follows share the release
force: with a fixed threshold the stick is the drop over the loading rate, with a random
one the next threshold's draw spreads it. Scoring the stick time given the drop tells the
threshold's spread from the friction noise by that pair, not by the marginals' shapes.

A positive stick time contributes $\\log(1 - p_0) + \\log f(y \\mid d, y > 0)$, a zero one
$\\log p_0$ as before ($y$ the stick time on its log scale, $d$ the drop, $p_0$ the
simulated fraction of zero sticks); each a (conditional) log-density, so their sum is a
composite likelihood whose estimating equations stay unbiased. The conditional density is
the smoothed log of a binned product-kernel estimate of the simulated pairs (the fit's
own two bandwidths) less that of the drops', data smoothed by the same kernels, with the
defensive mixture and floor of the marginal terms, as the library does for one column.

`install()` puts it in the estimator of the process that calls it (the Wald intervals'
simulation-noise check, `jackknife_values`, keeps the marginal terms: the estimate is the
experiment here).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

BINS = 256  # per axis: about six bins a bandwidth at n_sim 1000
TRUNCATE = 6.0  # the kernel's reach, in bandwidths (the library's binned kernel's)


def _smoothed_log(counts, n, cell, sigma, floor_area, broad):
    """The kernel estimate of `n` values binned in `counts` (cells of size `cell`; the
    kernel's sd in bins `sigma`), mixed with the broad normal `broad` at weight 1/n and
    floored at one value's peak density (`floor_area`: the kernel's normalisation), its
    log smoothed by the same kernel."""
    f = ndimage.gaussian_filter(counts, sigma, mode="constant", truncate=TRUNCATE) / (n * cell)
    density = np.maximum((1 - 1.0 / n) * f + broad / n, 1.0 / (n * floor_area))
    return ndimage.gaussian_filter(np.log(density), sigma, mode="nearest", truncate=TRUNCATE)


def _normal(x, centre, sd):
    return np.exp(-0.5 * ((x - centre) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))


def conditional(drop, stick, sim_drop, sim_stick, h_drop, h_stick):
    """Per positive data stick, the smoothed log-density of its stick time (per unit stick
    time) given its drop, from the simulated pairs; `(terms, positive)`, `None` where
    fewer than 10 simulated pairs have a positive stick."""
    from stickslip._inference.data import to_fit_scale

    ok = np.isfinite(sim_drop) & np.isfinite(sim_stick) & (sim_stick > 0)
    n = int(ok.sum())
    if n < 10:
        return None
    positive = stick > 0
    y, d = to_fit_scale("stick_time", stick[positive]), drop[positive]
    ys, ds = to_fit_scale("stick_time", sim_stick[ok]), sim_drop[ok]
    span = [[d.min() - 8 * h_drop, d.max() + 8 * h_drop], [y.min() - 8 * h_stick,
                                                          y.max() + 8 * h_stick]]  # fmt: skip
    counts, ex, ey = np.histogram2d(ds, ys, BINS, range=span)
    dx, dy = ex[1] - ex[0], ey[1] - ey[0]
    cx, cy = 0.5 * (ex[1:] + ex[:-1]), 0.5 * (ey[1:] + ey[:-1])
    bx = _normal(cx, d.mean(), 3 * max(d.std(), h_drop))
    by = _normal(cy, y.mean(), 3 * max(y.std(), h_stick))
    sigma = (h_drop / dx, h_stick / dy)
    joint = _smoothed_log(counts, n, dx * dy, sigma, 2 * math.pi * h_drop * h_stick,
                          bx[:, None] * by[None, :])  # fmt: skip
    marginal = _smoothed_log(counts.sum(axis=1), n, dx, sigma[0],
                             math.sqrt(2 * math.pi) * h_drop, bx)  # fmt: skip
    at = ndimage.map_coordinates(joint, [(d - cx[0]) / dx, (y - cy[0]) / dy], order=1,
                                 mode="nearest")  # fmt: skip
    out = np.full(stick.size, np.nan)
    out[positive] = at - np.interp(d, cx, marginal) - y  # (per unit stick time)
    return out, positive


def install():
    """Score stick times given their drops in this process's fits."""
    from stickslip._inference import estimator, likelihood

    marginal_terms = likelihood.scored_samples

    def scored(data, sim, bandwidth, measurement):
        terms = marginal_terms(data, sim, bandwidth, measurement)
        if terms is None or not {"slip_distance", "stick_time"} <= set(data):
            return terms
        stick = np.asarray(data["stick_time"], float)
        sim_stick = np.asarray(sim["stick_time"], float)
        got = conditional(np.asarray(data["slip_distance"], float), stick,
                          np.asarray(sim["slip_distance"], float), sim_stick,
                          bandwidth["slip_distance"], bandwidth["stick_time"])  # fmt: skip
        if got is None:
            return terms
        cond, positive = got
        finite = sim_stick[np.isfinite(sim_stick)]
        p0 = likelihood._zero_fraction(int(np.count_nonzero(finite == 0)), finite.size)
        new = terms["stick_time"].copy()  # zero sticks keep log p0
        new[positive] = math.log1p(-p0) + cond[positive]
        return {**terms, "stick_time": new}

    estimator.scored_samples = scored
