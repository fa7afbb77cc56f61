r"""Profile-likelihood intervals (`fit(..., intervals="profile")`).

A Wald interval reads the likelihood's curvature over the surface's design, a few steps
about the estimate. Where the likelihood is not that quadratic beyond it (a random
threshold's mean and sd trade along a curved ridge: the estimates of an independent
generator's traces spread three to four times the intervals' standard errors, while each
fit's own curvature was right where it was measured) the profile follows the ridge: for a
parameter $\psi$ held at a value, the log-likelihood maximised over the others,

$$\ell_p(\psi) = \max_{\lambda} \ell(\psi, \lambda),$$

and the interval is where $2(\hat\ell - \ell_p(\psi))$ stays below $q\,c$, with $q$ the
$\chi^2_1$ 95 % point and $c = V_{\psi\psi} / (H^{-1})_{\psi\psi}$ the composite
likelihood's scalar adjustment: the estimate's variance (the sandwich's, plus the
simulation's noise in one seed's vertex) over the curvature's own. Where the profile is a
quadratic of the surface's curvature this is the Wald interval.

The surface is rough (the simulation's draws move with the parameters, the measurement's
joins come and go), so no value is a raw one: each $\ell_p$, $\hat\ell = \ell_p(\hat\psi)$
included, is the maximum of the polynomial `fit` uses for its vertex
(`surface.polynomial_vertex`) over a design in the other parameters, $\psi$ held
(recentred until its vertex lies within a step, `RECENTRE` times at most). What roughness
the polynomial leaves (its residuals carried through the least squares) is the statistic's
own noise, and the threshold is the 95 % point of $c\chi^2_1$ plus that noise
(`noisy_threshold`). The ends are read from the tries a design vouches for (`read_ends`).
The first seed's surface is profiled; its cost is about that of the fit again per
parameter (a design of $1 + 2m(m+1)$ points for $m$ other parameters, two to four values
of $\psi$ a side).
"""

from __future__ import annotations

import math

import numpy as np

from .params import from_fit_coords
from .surface import polynomial_terms, polynomial_vertex, quadratic_design, quadratic_hessian

CHI2_95 = 3.841458820694124  # the chi-square (1 degree of freedom) 95 % point
# Values of psi tried a side: the first at the Wald interval's end (where a quadratic
# profile meets the threshold), then the secant on the signed root of the statistic,
# which is linear in psi for a quadratic profile; a side stops within ROOT_TOLERANCE of
# the threshold's root (5 % of the interval's half-width for a linear root) and its end is
# the secant's between the tried values nearest the threshold.
TRIES = 4
ROOT_TOLERANCE = 0.05
GROWTH = 3.0  # a try goes at most this many times the last one's distance out
# Tries at least this fraction of the first try's distance apart: through a measurement the
# profile's values are noisy at neighbouring values of psi (the statistic moved by 3-6 units
# between tries 3 % of a standard error apart, `n_sim` 1000), and the quadratic read through
# them (`_smoothed_ends`) needs tries spread to average it.
SPACING = 0.2
# The other parameters' maximum at a held value: their design recentred at most RECENTRE
# times (on a ridge that bends away from the estimate's covariance they move steps from
# where its slope puts them), each time to the vertex, or without one to the plain
# quadratic's vertex within REACH steps.
RECENTRE = 6
REACH = 6.0
# An adjustment past this is said: on an independent generator's random thresholds (`n_sim`
# 1000, 24 fits) c was 0.6-2.9 for 48 of the 52 parameters of fits that also gave a Wald
# interval (15-68 in the fourth set), 0.2-9.6 for most of the others, and 10^14-10^21
# where the bread was nearly singular along the threshold's mean-sd ridge (5 parameters
# in 3 fits without a Wald interval; the interval then its whole box).
WIDE_ADJUSTMENT = 10.0


def _polynomial(du, values):
    """The least-squares coefficients of `polynomial_terms` (None: too few points)."""
    ok = np.isfinite(values)
    X = polynomial_terms(du)
    if ok.sum() < X.shape[1]:
        return None
    return np.linalg.lstsq(X[ok], values[ok], rcond=None)[0]


def _smoothed_max(points, centre, steps, loglik):
    """The polynomial's maximum over `points` (rows: fit coordinates of the axes profiled
    over, about `centre`): its value, where, whether it is a vertex within two steps, and
    the value's variance (the residuals' about the polynomial, through its least squares:
    the surface's roughness left in the value; 0 where the points leave no residual
    degree of freedom); where there is no vertex, the best point's predicted value and,
    as where to look next, the plain quadratic's vertex (where concave) within `REACH`
    steps, else that point."""
    values = np.array([loglik(u) for u in points], float)
    du = points - centre
    coef = _polynomial(du, values)
    if coef is None:
        return -np.inf, centre, False, 0.0
    ok = np.isfinite(values)
    X = polynomial_terms(du)[ok]
    dof = X.shape[0] - X.shape[1]
    rss = float(np.sum((values[ok] - X @ coef) ** 2))
    XtX = np.linalg.pinv(X.T @ X)

    def variance(x):
        return 0.0 if dof <= 0 else rss / dof * float(x @ XtX @ x)

    shift, _ = polynomial_vertex(du, values, steps)
    if shift is not None:
        x = polynomial_terms(shift[None, :])[0]
        return float(x @ coef), centre + shift, True, variance(x)
    predicted = np.where(ok, polynomial_terms(du) @ coef, -np.inf)
    b = int(np.argmax(predicted))
    where = points[b]
    H = quadratic_hessian(du, values)
    if H is not None and np.all(np.linalg.eigvalsh(H) < 0):
        p = centre.size
        # (the slopes of a linear fit: over the symmetric design the odd columns are
        # orthogonal to the quadratic's, so these are the quadratic's own slopes)
        g = np.linalg.lstsq(X[:, : 1 + p], values[ok], rcond=None)[0][1:]
        step = np.linalg.solve(H, -g)
        reach = np.max(np.abs(step) / steps)
        where = centre + step * min(1.0, REACH / reach) if reach > 0 else where
    return float(predicted[b]), where, False, variance(polynomial_terms(du)[b])


class _Profiler:
    """The first seed's log-likelihood, each point once (the designs overlap)."""

    def __init__(self, loglik, lo, hi):
        self.loglik, self.lo, self.hi = loglik, lo, hi
        self.known: dict[bytes, float] = {}

    def __call__(self, u) -> float:
        u = np.clip(np.asarray(u, float), self.lo, self.hi)
        key = u.tobytes()
        if key not in self.known:
            self.known[key] = float(self.loglik(u)[0])
        return self.known[key]

    def profiled(self, j, psi, start, steps):
        """l_p(psi) for axis j: the others' design about `start`, recentred (`RECENTRE`
        times at most) until its vertex lies within a step of the centre: the value,
        where, and whether it was a vertex."""
        others = [i for i in range(start.size) if i != j]
        u = np.array(start, float)
        u[j] = psi
        if not others:
            return self(u), u, True, 0.0
        lo, hi = self.lo[others], self.hi[others]
        found = (-np.inf, u.copy(), False, 0.0)
        for _ in range(RECENTRE):
            centre = np.clip(u[others], lo, hi)
            points = np.clip(quadratic_design(centre, steps[others]), lo, hi)

            def value(row, u=u):
                full = u.copy()
                full[others] = row
                return self(full)

            best, where, vertex, var = _smoothed_max(points, centre, steps[others], value)
            u[others] = np.clip(where, lo, hi)
            if vertex or best > found[0]:
                found = (best, u.copy(), vertex, var)
            if vertex and np.all(np.abs(where - centre) <= steps[others]):
                break
        return found


def profile_intervals(loglik, surface, cov, mc, names, coords, lo, hi):
    """95 % profile intervals of every free parameter, from the first seed's surface.

    - `loglik`: the fit's `Likelihood` (at its first seed);
    - `surface`: its local surface (`surface.local_surface`): the estimate's design, steps
      and the curvature (`hessian`, the bread the covariance was built with);
    - `cov`: the sandwich covariance (fit coordinates, no simulation part); `mc`: the
      simulation's covariance of the two seeds' mean (`None`: not measured);
    - `names`, `coords`, `lo`, `hi`: the free parameters, their scales and box.

    Returns `(ci, records, said)`: the intervals (parameter units), per parameter a record
    of what was evaluated (`psi` and the statistic there, in fit coordinates; the
    threshold and its adjustment; the ends; whether an end is the box's), and warnings."""
    prof = _Profiler(loglik, lo, hi)
    steps = np.asarray(surface.steps, float)
    centre = np.asarray(surface.centre, float)
    _, u1, _, _ = _smoothed_max(np.asarray(surface.design, float), centre, steps, prof)
    u1 = np.clip(u1, lo, hi)
    H = np.asarray(surface.hessian, float)
    # the estimate's covariance: one seed's vertex, so twice the two seeds' mean's noise
    total = np.asarray(cov, float) + (0.0 if mc is None else 2.0 * np.asarray(mc, float))
    var, sandwich = np.diag(total), np.diag(np.asarray(cov, float))
    try:
        h_inv = np.diag(np.linalg.inv(-0.5 * (H + H.T)))
    except np.linalg.LinAlgError:
        h_inv = np.full(len(names), np.nan)
    ci, records, said = {}, {}, []
    for j, name in enumerate(names):
        c = var[j] / h_inv[j] if h_inv[j] > 0 and var[j] > 0 else math.nan
        if not math.isfinite(c):
            said.append(
                f"the profile interval of {name} is not adjusted for the composite "
                "likelihood (the surface's curvature there is not a maximum's): its "
                "threshold is the plain chi-square's"
            )
            c = 1.0
        elif c > WIDE_ADJUSTMENT:
            said.append(
                f"the profile interval of {name} is adjusted by c = {c:.3g} for the composite "
                "likelihood (the sandwich's variance over the curvature's, where the "
                "curvature is nearly flat): its threshold, and the interval, are that wide"
            )
        chi2_q = CHI2_95 * c
        # the other parameters' start at psi: their regression on psi under the estimate's
        # covariance (the ridge's direction where the surface is a quadratic)
        slope = total[:, j] / total[j, j] if total[j, j] > 0 else np.zeros(len(names))
        first = math.sqrt(chi2_q * h_inv[j]) if h_inv[j] > 0 else 2 * steps[j]
        # the reference: the profile at the estimate itself, by the same designs (the
        # whole design's maximum is another smoother's: 2-4 units above, measured)
        ref, _, _, var_ref = prof.profiled(j, u1[j], u1.copy(), steps)
        # the statistic's own noise: the reference's and a try's, each about var_ref
        noise = 2.0 * math.sqrt(2.0 * var_ref)
        q = noisy_threshold(c, noise)
        # (the adjustment's parts, fit coordinates: the sandwich's variance, the
        # simulation's in one seed's vertex, and the curvature's own)
        parts = dict(sandwich=float(sandwich[j]), simulation=float(var[j] - sandwich[j]),
                     curvature=float(h_inv[j]))  # fmt: skip
        record = dict(threshold=float(q), adjustment=float(c), noise=float(noise),
                      variances=parts, estimate=float(u1[j]), value=float(ref), psi=[],
                      statistic=[], vertex=[], box=[False, False])  # fmt: skip
        for side, sign in enumerate((-1.0, 1.0)):
            rises = _side(prof, j, u1, ref, q, sign, first, slope, steps, lo, hi, record, side)
            if rises > q:  # (the statistic below -q: not the profile's noise alone)
                said.append(
                    f"the profile of {name} rises {rises / 2:.1f} log-likelihood units above "
                    "its value at the estimate: the surface's maximum is not at the estimate"
                )
        if any(record["box"]):
            said.append(
                f"the profile interval of {name} reaches its box (the likelihood there is "
                f"within its threshold of the maximum): that end is the box's, widen it"
            )
        ends = read_ends(record, lo[j], hi[j])
        record["ends"] = [float(e) for e in ends]
        records[name] = record
        ci[name] = tuple(from_fit_coords(coords[name], e) for e in ends)
    return ci, records, said


def noisy_threshold(c, noise, level=0.95):
    """The `level` quantile of c X + noise Z, X a chi-square of one degree of freedom and Z
    a standard normal: the threshold of a statistic that is c chi2_1 at the truth, read
    with independent normal noise of sd `noise` (c chi2_1's own quantile where none)."""
    from scipy.optimize import brentq
    from scipy.stats import chi2, norm

    plain = float(chi2.ppf(level, 1)) * c
    if not noise > 0:
        return plain
    z = np.linspace(-9.0, 9.0, 4001)  # (the chi-square's kink at 0 defeats Gauss-Hermite)
    w = norm.pdf(z)
    w = w / w.sum()

    def below(t):
        return float(w @ chi2.cdf(np.maximum(t - noise * z, 0.0) / c, 1)) - level

    # noise far below the threshold (a surface the polynomial fits to rounding): the
    # bracket is a point within rounding, and its ends are the quantile
    top = plain + 12 * noise
    if below(plain) >= 0.0:
        return plain
    if not below(top) > 0.0:
        return float(top)
    return float(brentq(below, plain, top))


def _side(prof, j, u1, best, q, sign, first, slope, steps, lo, hi, record, side):
    """The tries of one side of axis j's profile (`TRIES` at most, into `record`): the
    first at `first` from the estimate, then by the secant on the statistic's signed root
    (`_next`); a side stops where a try's statistic is within `ROOT_TOLERANCE` of q (its
    design with a vertex), or below q at the box (`record["box"]`). Returns how far the
    statistic fell below 0 (the profile above `best`)."""
    root_q = math.sqrt(q)
    edge = lo[j] if sign < 0 else hi[j]
    tried = [(0.0, 0.0)]  # (distance from the estimate, root of the statistic)
    rises = 0.0
    start = np.array(u1, float)
    room = abs(edge - u1[j])
    d = min(first, room)
    for _ in range(TRIES):
        psi = u1[j] + sign * d
        guess = u1 + slope * (psi - u1[j])
        guess[j] = psi
        if len(tried) > 1:  # from the last profile point, moved along the ridge's slope
            guess = start + slope * (psi - start[j])
            guess[j] = psi
        value, start, vertex, _ = prof.profiled(j, psi, np.clip(guess, lo, hi), steps)
        stat = 2.0 * (best - value)
        rises = max(rises, -stat)
        root = math.sqrt(max(stat, 0.0))
        tried.append((d, root))
        record["psi"].append(float(psi))
        record["statistic"].append(float(stat))
        record["vertex"].append(bool(vertex))
        if vertex and abs(root - root_q) <= ROOT_TOLERANCE * root_q:
            break
        if root < root_q and abs(edge - psi) <= 1e-12 * max(1.0, abs(edge)):
            record["box"][side] = True
            break
        d = _next(tried, root_q, room, SPACING * first)
    return rises


def read_ends(record, lo, hi):
    """A profile interval's ends (fit coordinates) from what its tries found (`record`:
    the estimate, the threshold, each try's psi, statistic and whether its design had a
    vertex, and whether a side reached the box), between `lo` and `hi`.

    A value whose design found no vertex is only a lower bound on the profile (its
    statistic an upper bound): it is read where it lies inside the threshold, not past it.
    Each side's end is the secant's between the read tries that bracket the threshold's
    root, else the root's line through the estimate fitted to the read tries (never
    nearer than the farthest of them, never past `GROWTH` times it); then, where a side
    has two read tries or more, a quadratic a side through all of them, joined at the
    estimate (`_smoothed_ends`), sets the end where it meets the threshold within half
    again the farthest read try."""
    u1, q = record["estimate"], record["threshold"]
    root_q = math.sqrt(q)
    psi = np.array(record["psi"], float)
    stat = np.array(record["statistic"], float)
    read = np.isfinite(stat) & (np.array(record["vertex"], bool) | (stat < q))
    ends = []
    for side, (sign, edge) in enumerate(((-1.0, lo), (1.0, hi))):
        if record["box"][side]:
            ends.append(float(edge))
            continue
        on = np.flatnonzero(np.sign(psi - u1) == sign)
        room = abs(edge - u1)
        points = [(0.0, 0.0)] + [(abs(psi[i] - u1), math.sqrt(max(stat[i], 0.0)))
                                 for i in on if read[i]]  # fmt: skip
        if len(points) < 2:  # nothing read: as far as the first try (the Wald end)
            d = abs(psi[on[0]] - u1) if on.size else 0.0
        else:
            d = _end_of(points, root_q, room)
        ends.append(float(u1 + sign * d))
    return _smoothed_ends(record, ends, q, lo, hi, read)


def _end_of(points, root_q, room):
    """Where the statistic's root meets `root_q` (distances from the estimate): linear
    between the read points that bracket it, else the least-squares line through the
    origin, at least the farthest point and at most `GROWTH` times it (and the box)."""
    pts = sorted(points)
    below = [p for p in pts if p[1] < root_q]
    above = [p for p in pts if p[1] >= root_q]
    if above:
        b = min(above, key=lambda p: p[0])
        a = max((p for p in below if p[0] < b[0]), key=lambda p: p[0])
        return a[0] + (root_q - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    d = np.array([p[0] for p in pts[1:]])
    r = np.array([p[1] for p in pts[1:]])
    far = float(d.max())
    beta = float(d @ r / (d @ d))
    cap = min(GROWTH * far, room)
    return cap if beta <= 0 else float(min(max(root_q / beta, far), cap))


def _smoothed_ends(record, ends, q, lo, hi, read):
    """The ends read off a quadratic on each side through all of a parameter's profile
    values, joined at the estimate (least squares: the values' noise, a few units at a
    point through a measurement at `n_sim` 1000, is averaged over the tries), where it
    meets the threshold within half again the farthest try; the secant's `ends` where it
    does not (or a side has fewer than two tries, or ends at the box)."""
    u1 = record["estimate"]
    psi = np.array(record["psi"], float)
    values = -0.5 * np.array(record["statistic"], float)  # relative to the reference
    psi, values = psi[read], values[read]
    left, right = psi < u1, psi > u1
    if left.sum() < 2 or right.sum() < 2:
        return ends
    d = np.abs(psi - u1)
    X = np.stack([np.ones(psi.size + 1),
                  np.r_[0.0, d * left], np.r_[0.0, (d * left) ** 2],
                  np.r_[0.0, d * right], np.r_[0.0, (d * right) ** 2]], axis=1)  # fmt: skip
    c = np.linalg.lstsq(X, np.r_[0.0, values], rcond=None)[0]
    out = list(ends)
    for side, (a, b, mask, sign) in enumerate(((c[1], c[2], left, -1.0), (c[3], c[4], right, 1.0))):
        if record["box"][side]:
            continue
        # 2 (c0 - value(d)) = q: b d^2 + a d + q / 2 = 0, its smallest positive root
        roots = np.roots([b, a, q / 2]) if b != 0 else np.array([-q / (2 * a)])
        roots = roots[np.isreal(roots)].real
        roots = roots[(roots > 0) & (roots <= 1.5 * d[mask].max())]
        if roots.size:
            out[side] = float(np.clip(u1 + sign * roots.min(), lo, hi))
    return out


def _next(tried, root_q, room, apart):
    """The next distance: the secant through the two tried points nearest the threshold's
    root on either side (or the last two), within `GROWTH` times the farthest tried and
    the box, and at least `apart` from every tried distance (outwards where the last try
    was below the threshold, inwards where above)."""
    d = min(_crossing(tried, root_q, room), GROWTH * max(t[0] for t in tried), room)
    out = tried[-1][1] < root_q
    for t, _ in sorted(tried, reverse=not out):
        if abs(d - t) < apart:
            d = t + apart if out else t - apart
    return float(min(max(d, apart), room))


def _crossing(tried, root_q, room):
    """Where the signed root meets `root_q`, for placing the next try: linear between the
    nearest bracketing tried points, else extrapolated from the two farthest (within the
    box). Not `_end_of`'s line through the estimate: on a profile whose root grows slower
    than linearly (a ridge's long side) that line falls short, and four tries did not
    reach the threshold on the curved ridge of `tests/test_profile_intervals.py`."""
    pts = sorted(tried)
    below = [p for p in pts if p[1] < root_q]
    above = [p for p in pts if p[1] >= root_q]
    if below and above:
        a = max(below, key=lambda p: p[0])
        b = min((p for p in above if p[0] > a[0]), key=lambda p: p[0], default=None)
        if b is None:  # not monotone: the nearest point past the threshold, from 0
            b, a = min(above, key=lambda p: p[0]), (0.0, 0.0)
        return a[0] + (root_q - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    a, b = pts[-2], pts[-1]
    if b[1] <= a[1]:  # flat or falling: as far as the box allows
        return room
    return float(min(b[0] + (root_q - b[1]) * (b[0] - a[0]) / (b[1] - a[1]), room))
