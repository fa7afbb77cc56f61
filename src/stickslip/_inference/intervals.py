r"""The estimate's uncertainty: 95 % Wald intervals in fit coordinates (so asymmetric in the
parameter) with the sandwich covariance $H^{-1} J H^{-1}$ (`sandwich_covariance`: per-cycle scores
summed over the columns, `_score_matrix`; the smoothed likelihood is not a likelihood, and
the columns of one cycle are dependent; with $H$ the first seed's polynomial at its vertex
and again with the curvature of a plain quadratic through both seeds' values,
`with_plain_bread`, the larger of the two, `larger_covariance`), plus the simulation's own
noise in the estimate (`combine_seeds`): the surface's design evaluated again with a
second seed, the estimate the mean of the two vertices, its Monte Carlo covariance a
jackknife over the cycles simulated at the design points (`_jackknife`), which the two
seeds' half difference checks (`mc_noise_report` says what it found). The two seeds'
per-cycle scores also give $J$ free of the simulation's noise (their cross product,
`sandwich_covariance`).

Successive cycles are not independent where one draw reaches two rows: a row is a slip
and the stick that follows it, and a random static threshold ends that stick and starts
the next row's slip (`structural_lag`). $J$ then holds the scores' lagged cross products
up to that lag, $J = \Gamma_0 + \sum_{l=1}^{L} (\Gamma_l + \Gamma_l^T)$ (`_meat`), and the
lags the scores themselves show beyond it (`_dependence`: an autocorrelation past
`ACF_BAND` of its sampling sd) are added too. A model with memory makes its cycles a
chain: Bartlett's weights over Newey and West's number of lags (`newey_west_lag`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .params import from_fit_coords
from .surface import polynomial_vertex, quadratic_hessian

Z95 = 1.959963984540054
# The Monte Carlo noise check: a warning when the estimate's Monte Carlo sd (from two seeds)
# passes this fraction of its standard error (its variance then a quarter of the data's: the
# interval, which includes it, 12 % wider from the simulation alone); the n_sim advised
# brings it to MC_RATIO_GOAL (under 5 % wider).
MC_RATIO_WARN = 0.5
MC_RATIO_GOAL = 0.3
# The jackknife's replicates (`_jackknife`): at least this share of them with a vertex, or
# the simulation's noise decides the maximum and there is no interval. The two seeds' half
# difference against the jackknife's sd: past MC_CHECK (a two-sided 0.1 % each) in any
# parameter the fit says so (the difference is in the interval either way).
JACK_LEAST = 0.8
MC_CHECK = 3.29
# Dependent cycles (`_dependence`): the scores' autocorrelations are looked at up to
# MAX_LAG; one beyond the structural lag counts when it passes ACF_BAND times its sampling
# sd 1/sqrt(n) (with 3 free parameters and 5 lags, 15 looks: a false alarm in ~4 % of fits,
# which costs only a slightly noisier J).
MAX_LAG = 5
ACF_BAND = 3.0


def concave(hessian) -> bool:
    """Whether a log-likelihood surface of this Hessian is concave (a maximum with usable
    curvature: intervals, and the goodness check's simulation noise, depend on it)."""
    H = np.asarray(hessian, float)
    return bool(np.all(np.linalg.eigvalsh(-0.5 * (H + H.T)) > 0))


def with_plain_bread(surface, values2):
    """The surface with, as its Hessian, the curvature of a plain quadratic fitted to both
    seeds' mean values over the design (`quadratic_hessian`), where that is concave: a
    second bread for the sandwich (`fit` reports the larger covariance of the two,
    `larger_covariance`). The first seed's polynomial at its vertex (a cubic term along each
    axis) keeps the vertex unbiased, but along a weak direction the vertex lies steps from
    the design's centre and the cubic terms, noisy, move the curvature there: on an
    independent generator's random thresholds (28 fits at n_sim 4000) the noise's
    intervals spread 1.34 times their standard errors under that bread and 0.94 under this
    one (covered 22 and 27 of 28); on 40 fixed-threshold fits the two agree (z's sd 1.23,
    1.13, 0.97 against 1.24, 1.09, 0.97). Unchanged where either is not concave (the
    surface then gives no interval: `sandwich_covariance` says why)."""
    values = 0.5 * (np.asarray(surface.values, float) + np.asarray(values2, float))
    H = quadratic_hessian(surface.design - surface.centre, values)
    if H is None or not concave(H) or not concave(surface.hessian):
        return surface
    return dataclasses.replace(surface, hessian=H)


def larger_covariance(a, b) -> np.ndarray:
    """A covariance at least as large as both `a` and `b` in every direction: `a` plus
    the positive part of `b - a` (so `b` plus that of `a - b`; either where the other is
    the smaller). `fit` builds the sandwich with both of its curvatures, the first seed's
    polynomial at the vertex and the plain quadratic through both seeds
    (`with_plain_bread`), and reports this: each estimate has its failure (the cubic
    terms' noise where the vertex lies steps away; a surface that is not quadratic over
    the design's span), and where the two disagree the curvature is that uncertain. On
    the same kept fits (`benchmarks/interval_rules.py`) it kept the plain bread's mending
    of an independent generator's random thresholds (D covered 27 of 28, z sd 0.94;
    the cubic bread's 22, 1.34) and the cubic bread's fixed-threshold static friction
    (39 of 40, 0.93; the plain bread's 37, 0.97)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    w, v = np.linalg.eigh(0.5 * ((b - a) + (b - a).T))
    return a + (v * np.maximum(w, 0.0)) @ v.T


def sandwich_covariance(surface, names, scores2=None, lag=0) -> tuple[np.ndarray, list[str], dict]:
    r"""The sandwich covariance $H^{-1} J H^{-1}$ from the surface's Hessian and per-cycle
    scores (the Hessian's inverse alone if a design point failed), with its warnings and
    what was found of the rows' dependence (`_dependence`).

    With `scores2`, the per-cycle terms of the same design under a second, independent
    seed, $J$ is the symmetrised cross product of the two seeds' scores,
    $(G_1^T G_2 + G_2^T G_1)/2$: each seed's scores are the data's own plus the
    simulation's noise, independent between seeds, so the cross product holds the data's
    $G^T G$ without the noise's $\sum_i \operatorname{var}$, which one seed's $G^T G$ adds
    (through a measurement, where a simulated cycle near a sparse datum comes and goes
    with the sampling's joins, one seed's $J$ made a standard error up to 20 % larger:
    0.084 against 0.069 on one set). Where the cross product is not positive definite (the
    noise dominates), one seed's $J$ is kept.

    `lag`: the rows' structural dependence (`structural_lag`; `None`: unknown, from the
    scores alone); $J$ adds the lagged cross products up to it and up to any lag the
    scores show (`_meat`)."""
    said = []
    info = -surface.hessian
    dependence: dict = dict(lag=0, structural=lag, acf={}, band=None, bartlett=False)
    if not concave(surface.hessian):
        said.append(
            "the log-likelihood is not concave around the estimate (the data do not pin the "
            "free parameters down, the simulation noise hides the curvature, or the box holds "
            "no maximum): no intervals (nan); a larger n_sim or fewer free parameters"
        )
        info = info + np.eye(len(names)) * max(1e-9, -np.min(np.linalg.eigvalsh(info)) + 1e-9)
    bread = cov = np.linalg.inv(info)
    if all(s is not None for s in surface.scores):
        G = _score_matrix(surface.nominal, surface.design, surface.centre, surface.scores)
        G2 = None
        if scores2 is not None and all(s is not None for s in scores2):
            G2 = _score_matrix(surface.nominal, surface.design, surface.centre, scores2)
        dependence = _dependence(G, G2, names, lag)
        J = None
        chain = dependence["bartlett"]
        if G2 is not None:
            J = _meat(G, G2, dependence["lag"], chain)
            if not np.all(np.linalg.eigvalsh(J) > 0):
                J = None
        if J is None:
            J = _meat(G, G, dependence["lag"], chain)
        cov = bread @ J @ bread
        if dependence["lag"] > 0:  # what treating the rows as independent would have said
            J0 = None if G2 is None else _meat(G, G2, 0)
            if J0 is None or not np.all(np.linalg.eigvalsh(J0) > 0):
                J0 = _meat(G, G, 0)
            cov_independent = bread @ J0 @ bread
            dependence["se_ratio"] = {
                k: float(math.sqrt(max(cov[i, i], 0.0) / cov_independent[i, i]))
                if cov_independent[i, i] > 0 else math.nan
                for i, k in enumerate(names)
            }  # fmt: skip
    else:
        said.append("a design point failed: intervals from the Hessian alone")
    return cov, said, dependence


def structural_lag(model) -> int | None:
    """How many following rows a cycle's own random draws reach, from the model's
    structure: 1 where the onset position is drawn afresh at each release (a random static
    threshold ends a row's stick and starts the next row's slip), `None` for a model that
    carries state from cycle to cycle (the rows are a chain: the lag is read from the
    scores), 0 otherwise (every slip from the same onset position)."""
    if getattr(type(model), "carries_state", False):
        return None
    import jax

    try:
        x = [float(model.position(model.onset_state(jax.random.key(i)))) for i in range(4)]
    except Exception:  # an onset the probe cannot take: read the lag from the scores
        return None
    return 1 if np.ptp(x) > 0 else 0


def _dependence(G, G2, names, lag) -> dict:
    """The rows' dependence as the scores show it: each parameter's score autocorrelation
    at lags 1..MAX_LAG (with two seeds, the cross-seed one, free of the simulation's
    noise), and the lag the meat takes: the structural one (`structural_lag`; 0 where
    unknown) or the largest lag whose autocorrelation passes `ACF_BAND` / sqrt(n) for any
    parameter, whichever is larger."""
    n = G.shape[0]
    B = G if G2 is None else G2
    acf = {}
    far = 0
    band = ACF_BAND / math.sqrt(max(n, 1))
    for i, k in enumerate(names):
        a, b = G[:, i], B[:, i]
        norm = math.sqrt(float(a @ a) * float(b @ b))
        values = []
        for m in range(1, min(MAX_LAG, n - 1) + 1):
            r = 0.5 * (float(a[m:] @ b[:-m]) + float(b[m:] @ a[:-m])) / norm if norm > 0 else 0.0
            values.append(r)
            if abs(r) > band:
                far = max(far, m)
        acf[k] = values
    chosen = max(newey_west_lag(n) if lag is None else lag, far)
    return dict(lag=int(chosen), structural=lag, acf=acf, band=band,
                from_scores=bool(far > (lag or 0)), bartlett=lag is None)  # fmt: skip


def newey_west_lag(n: int) -> int:
    r"""The lag a chain's meat takes with Bartlett's weights: Newey and West's rule,
    $\lfloor 4 (n/100)^{2/9} \rfloor$ (4 for 100-272 rows, 5 to 620). A model with memory
    couples its cycles through its state at every lag, fading; a significance band on each
    lag missed it: an independent generator's random threshold held from the stick had
    lag-1 autocorrelations of +0.13 to +0.18 in the threshold's scores, under the band's
    +0.22 at 180 rows, in 3 of 4 fits, and those intervals covered too rarely."""
    return int(4 * (max(n, 1) / 100) ** (2 / 9))


def _meat(G, G2, lag, bartlett=False) -> np.ndarray:
    r"""The sandwich's $J$ from the scores of two seeds (the same `G` twice for one):
    $\Gamma_0 + \sum_{l=1}^{L} (\Gamma_l + \Gamma_l^T)$ with $\Gamma_l$ the symmetrised
    cross product of rows $l$ apart; exact for scores that are $L$-dependent. Where that
    sum is not positive definite (its lagged terms are noisy), Bartlett's weights
    $1 - l/(2L + 1)$ over $2L$ lags, which keep it positive semi-definite (Newey-West).
    `bartlett`: a chain's dependence, which fades rather than ends: Bartlett's weights
    $1 - l/(L + 1)$ over the $L$ lags (Newey-West)."""

    def gamma(m):
        if m == 0:
            return 0.5 * (G.T @ G2 + G2.T @ G)
        c = 0.5 * (G[m:].T @ G2[:-m] + G2[m:].T @ G[:-m])
        return c + c.T

    if bartlett:
        return gamma(0) + sum((1 - m / (lag + 1)) * gamma(m) for m in range(1, lag + 1))
    J = sum(gamma(m) for m in range(lag + 1))
    if lag == 0 or np.all(np.linalg.eigvalsh(J) > 0):
        return J
    wide = 2 * lag
    return gamma(0) + sum((1 - m / (wide + 1)) * gamma(m) for m in range(1, wide + 1))


def _jackknife(surface, block_values) -> np.ndarray | None:
    r"""The simulation's covariance of one seed's vertex: the delete-a-block jackknife over
    the cycles simulated at the design points. `block_values[j, b]`: the log-likelihood at
    design point j with the b-th block of its simulated cycles left out (the same block, by
    position, at every point: the common random numbers), so that replicate b is the
    surface, and its vertex, without those cycles; the covariance is
    $\frac{B-1}{B} \sum_b (\hat u_{(b)} - \bar u)(\hat u_{(b)} - \bar u)^T$ over the B
    replicates. `None` where fewer than `JACK_LEAST` of them have a vertex (the surface's
    noise then decides whether there is a maximum at all)."""
    du = surface.design - surface.centre
    shifts = []
    for column in np.asarray(block_values, float).T:
        x, _ = polynomial_vertex(du, column, surface.steps)
        if x is not None:
            shifts.append(x)
    B = np.shape(block_values)[1]
    if len(shifts) < JACK_LEAST * B:
        return None
    dev = np.array(shifts) - np.mean(shifts, axis=0)
    return (B - 1) / len(shifts) * (dev.T @ dev)  # (B-1)/B times the sum, over those kept


def combine_seeds(surface, shift2, cov, blocks, lo, hi):
    """The estimate (the mean of two seeds' vertices) and its covariance: the sandwich's plus
    the simulation's, and what was found of the simulation's noise. The simulation's is the
    jackknife's over each seed's simulated cycles (`_jackknife`; a quarter of the two
    seeds' sum: the mean of two independent seeds) plus what of the two seeds' half
    difference the jackknife does not explain, per parameter (its square less the
    jackknife's variance, where positive: one draw, rank one). The jackknife sees the noise
    of the cycles themselves; what moves all of a simulated trace's cycles together (the
    statistics its extraction takes over the whole trace) only a second seed sees. Without
    both vertices or a jackknife the covariance is the sandwich's alone, with the reason
    (`wald` then gives no interval)."""
    u_hat = surface.vertex(lo, hi)
    shift = surface.shift
    noise: dict[str, Any] = dict(mc=None, reason=None, check=None)
    if shift is None:
        noise["reason"] = "the first seed's surface has no maximum near the best point found"
        return u_hat, cov, noise
    if shift2 is None:
        noise["reason"] = "the second seed's surface has no maximum near the estimate"
        return u_hat, cov, noise
    half = 0.5 * (shift - shift2)
    u_hat = np.clip(surface.centre + 0.5 * (shift + shift2), lo, hi)
    jack = [_jackknife(surface, b) for b in blocks]
    if any(c is None for c in jack):
        noise["reason"] = (
            f"left out a tenth of the simulated cycles, the surface has no maximum near the "
            f"estimate in more than {1 - JACK_LEAST:.0%} of the jackknife's replicates"
        )
        return u_hat, cov, noise
    mc = 0.25 * (jack[0] + jack[1])
    variance = np.maximum(np.diag(mc), 1e-300)
    noise["check"] = half / np.sqrt(variance)
    excess = np.sign(half) * np.sqrt(np.maximum(half**2 - variance, 0.0))
    mc = mc + np.outer(excess, excess)
    noise["mc"] = mc
    return u_hat, cov + mc, noise


def wald(u_hat, cov, names, scales, lo, hi, free, concave=True) -> tuple[dict, list[str]]:
    """95 % Wald intervals in fit coordinates, and a warning for each estimate on an edge
    of its box. Where the surface is not `concave` there is no interval: `(nan, nan)`
    (its regularised inverse gave (0, inf) or +-1e10, which read as intervals)."""
    ci, said = {}, []
    for i, k in enumerate(names):
        half = Z95 * math.sqrt(max(cov[i, i], 0.0))
        if concave:
            ci[k] = (from_fit_coords(scales[k], u_hat[i] - half),
                     from_fit_coords(scales[k], u_hat[i] + half))  # fmt: skip
        else:
            ci[k] = (math.nan, math.nan)
        edge = min(u_hat[i] - lo[i], hi[i] - u_hat[i]) < 0.01 * (hi[i] - lo[i])
        if edge:
            value = from_fit_coords(scales[k], u_hat[i])
            said.append(f"{k} = {value:.4g} is on the edge of its box {free[k]}: widen it")
    return ci, said


def axis_ends(nominal, u_hat, i) -> tuple[int, int]:
    """The indices of the design's +1 and -1 step points along axis `i`."""
    d = nominal - u_hat
    axis = np.all(np.isclose(np.delete(d, i, axis=1), 0), axis=1)
    ends = np.flatnonzero(axis & (np.abs(d[:, i]) > 0))
    ends = ends[np.argsort(np.abs(d[ends, i]))][:2]  # the +-1 step points
    plus, minus = sorted(ends, key=lambda j: -d[j, i])
    return int(plus), int(minus)


def _score_matrix(nominal, design, u_hat, scores):
    """The per-cycle scores, one row a cycle (differences between the design's +-1 step
    points along each axis, over their distance where they were evaluated: clipped at the
    box, a point is nearer), centred."""
    p = u_hat.size
    grads = []
    for i in range(p):
        plus, minus = axis_ends(nominal, u_hat, i)
        width = design[plus, i] - design[minus, i]
        if width <= 0:  # a box narrower than the design: no difference to take
            grads.append(np.zeros_like(scores[0]))
            continue
        grads.append((scores[plus] - scores[minus]) / width)
    G = np.stack(grads, axis=1)
    return G - G.mean(axis=0)


def mc_noise_report(names, noise, se, n_sim) -> dict[str, Any]:
    """The Monte Carlo sd of the estimate (`combine_seeds`' jackknife) against the standard
    error; a warning when it passes MC_RATIO_WARN of it, with the n_sim that would bring it
    to MC_RATIO_GOAL (its variance falls as 1/n_sim), and one where there is no interval
    for the simulation's noise."""
    out: dict[str, Any] = dict(warning=None)
    if noise["reason"] is not None:
        out["warning"] = (
            f"{noise['reason']}: the simulation noise hides the likelihood's curvature, so "
            f"there is no interval; take n_sim >= {4 * n_sim}"
        )
        return out
    sd = np.sqrt(np.maximum(np.diag(noise["mc"]), 0.0))
    ratio = sd / np.maximum(se, 1e-300)
    worst = int(np.argmax(ratio))
    need = n_sim * (ratio[worst] / MC_RATIO_GOAL) ** 2
    out.update(
        sd={k: float(v) for k, v in zip(names, sd, strict=True)},
        ratio={k: float(v) for k, v in zip(names, ratio, strict=True)},
        seeds_apart={k: float(v) for k, v in zip(names, noise["check"], strict=True)},
        n_sim_needed=int(float(f"{max(need, n_sim):.2g}")),
    )
    said = []
    if np.max(np.abs(noise["check"])) > MC_CHECK:
        j = int(np.argmax(np.abs(noise["check"])))
        said.append(
            f"the two seeds' estimates of {names[j]} differ by {abs(noise['check'][j]):.2g} "
            "times the simulation's sd that the jackknife over its cycles gives (the "
            "simulated trace's own statistics move its cycles together): the difference is "
            "in the interval"
        )
    if ratio[worst] > MC_RATIO_WARN:
        said.append(
            f"the simulation noise is comparable with the likelihood's curvature: its sd in "
            f"{names[worst]}'s estimate is {ratio[worst]:.2g} standard errors; "
            f"the interval includes it; take n_sim >= {out['n_sim_needed']:.2g} (now {n_sim})"
        )
    out["warning"] = "; ".join(said) or None
    return out
