r"""The estimate's uncertainty: 95 % Wald intervals in fit coordinates (so asymmetric in the
parameter) with the sandwich covariance $H^{-1} J H^{-1}$ (`_sandwich`: per-cycle scores
summed over the columns, `_score_matrix`; the smoothed likelihood is not a likelihood, and
the columns of one cycle are dependent), widened by $\sqrt{1 + n/n_{sim}}$ for the
simulation's own noise; and the Monte Carlo noise check (`_mc_noise`): the surface's design
evaluated again with a second seed, the estimate the mean of the two vertices, the square
of their half difference, the Monte Carlo covariance of that mean, added to the covariance
(`_combine_seeds`). The two seeds' per-cycle scores also give $J$ free of the simulation's
noise (their cross product, `_sandwich`).

Successive cycles are not independent where one draw reaches two rows: a row is a slip
and the stick that follows it, and a random static threshold ends that stick and starts
the next row's slip (`structural_lag`). $J$ then holds the scores' lagged cross products
up to that lag, $J = \Gamma_0 + \sum_{l=1}^{L} (\Gamma_l + \Gamma_l^T)$ (`_meat`), and the
lags the scores themselves show beyond it (`_dependence`: an autocorrelation past
`ACF_BAND` of its sampling sd) are added too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .params import _from_fit

Z95 = 1.959963984540054
# The Monte Carlo noise check: a warning when the estimate's Monte Carlo sd (from two seeds)
# passes this fraction of its standard error (its variance then a quarter of the data's: the
# interval, which includes it, 12 % wider from the simulation alone); the n_sim advised
# brings it to MC_RATIO_GOAL (under 5 % wider).
MC_RATIO_WARN = 0.5
MC_RATIO_GOAL = 0.3
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


def _sandwich(surface, names, scores2=None, lag=0) -> tuple[np.ndarray, list[str], dict]:
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
    dependence: dict = dict(lag=0, structural=lag, acf={}, band=None)
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
        if G2 is not None:
            J = _meat(G, G2, dependence["lag"])
            if not np.all(np.linalg.eigvalsh(J) > 0):
                J = None
        if J is None:
            J = _meat(G, G, dependence["lag"])
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
    chosen = max(lag or 0, far)
    return dict(lag=int(chosen), structural=lag, acf=acf, band=band,
                from_scores=bool(far > (lag or 0)))  # fmt: skip


def _meat(G, G2, lag) -> np.ndarray:
    r"""The sandwich's $J$ from the scores of two seeds (the same `G` twice for one):
    $\Gamma_0 + \sum_{l=1}^{L} (\Gamma_l + \Gamma_l^T)$ with $\Gamma_l$ the symmetrised
    cross product of rows $l$ apart; exact for scores that are $L$-dependent. Where that
    sum is not positive definite (its lagged terms are noisy), Bartlett's weights
    $1 - l/(2L + 1)$ over $2L$ lags, which keep it positive semi-definite (Newey-West)."""

    def gamma(m):
        if m == 0:
            return 0.5 * (G.T @ G2 + G2.T @ G)
        c = 0.5 * (G[m:].T @ G2[:-m] + G2[m:].T @ G[:-m])
        return c + c.T

    J = sum(gamma(m) for m in range(lag + 1))
    if lag == 0 or np.all(np.linalg.eigvalsh(J) > 0):
        return J
    wide = 2 * lag
    return gamma(0) + sum((1 - m / (wide + 1)) * gamma(m) for m in range(1, wide + 1))


def _combine_seeds(surface, shift2, cov, n_data, n_sim, lo, hi):
    """The estimate and covariance from two seeds' vertices: the covariance widened by
    $1 + n/n_{sim}$, and, when both seeds have a vertex, the estimate their mean and the
    square of their half difference added (unbiased; one draw, so added on top of the
    widening rather than instead of it)."""
    u_hat = surface.vertex(lo, hi)
    cov = cov * (1.0 + n_data / n_sim)
    shift = surface.shift
    if shift is not None and shift2 is not None:
        half = 0.5 * (shift - shift2)
        u_hat = np.clip(surface.centre + 0.5 * (shift + shift2), lo, hi)
        cov = cov + np.outer(half, half)
    return u_hat, cov


def _wald(u_hat, cov, names, scales, lo, hi, free, concave=True) -> tuple[dict, list[str]]:
    """95 % Wald intervals in fit coordinates, and a warning for each estimate on an edge
    of its box. Where the surface is not `concave` there is no interval: `(nan, nan)`
    (its regularised inverse gave (0, inf) or +-1e10, which read as intervals)."""
    ci, said = {}, []
    for i, k in enumerate(names):
        half = Z95 * math.sqrt(max(cov[i, i], 0.0))
        if concave:
            ci[k] = (_from_fit(scales[k], u_hat[i] - half),
                     _from_fit(scales[k], u_hat[i] + half))  # fmt: skip
        else:
            ci[k] = (math.nan, math.nan)
        edge = min(u_hat[i] - lo[i], hi[i] - u_hat[i]) < 0.01 * (hi[i] - lo[i])
        if edge:
            value = _from_fit(scales[k], u_hat[i])
            said.append(f"{k} = {value:.4g} is on the edge of its box {free[k]}: widen it")
    return ci, said


def _score_matrix(nominal, design, u_hat, scores):
    """The per-cycle scores, one row a cycle (differences between the design's +-1 step
    points along each axis, over their distance where they were evaluated: clipped at the
    box, a point is nearer), centred."""
    p = u_hat.size
    grads = []
    for i in range(p):
        d = nominal - u_hat
        axis = np.all(np.isclose(np.delete(d, i, axis=1), 0), axis=1)
        ends = np.flatnonzero(axis & (np.abs(d[:, i]) > 0))
        ends = ends[np.argsort(np.abs(d[ends, i]))][:2]  # the +-1 step points
        plus, minus = sorted(ends, key=lambda j: -d[j, i])
        width = design[plus, i] - design[minus, i]
        if width <= 0:  # a box narrower than the design: no difference to take
            grads.append(np.zeros_like(scores[0]))
            continue
        grads.append((scores[plus] - scores[minus]) / width)
    G = np.stack(grads, axis=1)
    return G - G.mean(axis=0)


def _mc_noise(names, shift, shift2, se, n_sim) -> dict[str, Any]:
    """The Monte Carlo sd of the estimate (the mean of two seeds' vertices: |difference|
    / 2) against the standard error; a warning when it passes MC_RATIO_WARN of it, with the
    n_sim that would bring it to MC_RATIO_GOAL (its variance falls as 1/n_sim)."""
    out: dict[str, Any] = dict(warning=None)
    if shift is None:
        return out
    if shift2 is None:
        out["warning"] = (
            "with a second seed the surface has no maximum near the estimate: the simulation "
            "noise hides the likelihood's curvature, so there is no interval; take n_sim >= "
            f"{4 * n_sim}"
        )
        return out
    sd = 0.5 * np.abs(shift - shift2)
    ratio = sd / np.maximum(se, 1e-300)
    worst = int(np.argmax(ratio))
    need = n_sim * (ratio[worst] / MC_RATIO_GOAL) ** 2
    out.update(
        sd={k: float(v) for k, v in zip(names, sd, strict=True)},
        ratio={k: float(v) for k, v in zip(names, ratio, strict=True)},
        n_sim_needed=int(float(f"{max(need, n_sim):.2g}")),
    )
    if ratio[worst] > MC_RATIO_WARN:
        out["warning"] = (
            f"the simulation noise is comparable with the likelihood's curvature: its sd in "
            f"{names[worst]}'s estimate (two seeds) is {ratio[worst]:.2g} standard errors; "
            f"the interval includes it; take n_sim >= {out['n_sim_needed']:.2g} (now {n_sim})"
        )
    return out
