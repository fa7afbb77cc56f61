"""Locating a path's stick inside the step where it happened.

Everything here works on arrays of paths at once. Cubic Hermite pieces are written on the
unit interval: values `p0`, `p1` at the ends and slopes `m0`, `m1` already multiplied by the
piece's length.
"""

from __future__ import annotations

from .._jax import jax, jnp
from .._solver.base import over_paths

_BISECTIONS = 60  # halves the bracket to below 1e-18 of the piece: full float64 precision


def _coefficients(p0, p1, m0, m1):
    a3 = 2.0 * p0 + m0 - 2.0 * p1 + m1
    a2 = -3.0 * p0 - 2.0 * m0 + 3.0 * p1 - m1
    return a3, a2, m0, p0


def hermite(p0, p1, m0, m1, u):
    """The cubic Hermite piece at `u` in [0, 1]."""
    a3, a2, a1, a0 = _coefficients(p0, p1, m0, m1)
    return ((a3 * u + a2) * u + a1) * u + a0


def _critical_points(p0, p1, m0, m1):
    """The two roots of the piece's derivative, sorted, clipped to [0, 1] (1 if absent)."""
    a3, a2, a1, _ = _coefficients(p0, p1, m0, m1)
    # H'(u) = 3 a3 u^2 + 2 a2 u + a1; stable quadratic roots via q.
    disc = a2 * a2 - 3.0 * a3 * a1
    real = disc >= 0.0
    sq = jnp.sqrt(jnp.where(real, disc, 0.0))
    q = -(a2 + jnp.where(a2 >= 0.0, sq, -sq))
    safe = lambda num, den: jnp.where(den != 0.0, num / jnp.where(den != 0.0, den, 1.0), 2.0)
    r1 = safe(q, 3.0 * a3)
    r2 = safe(a1, q)
    r1 = jnp.where(real & (r1 > 0.0) & (r1 < 1.0), r1, 1.0)
    r2 = jnp.where(real & (r2 > 0.0) & (r2 < 1.0), r2, 1.0)
    return jnp.minimum(r1, r2), jnp.maximum(r1, r2)


def interior_reaches(p0, p1, m0, m1, level):
    """True where the piece has an interior local maximum at or above `level` (a crossing
    that a check of the end points alone would miss)."""
    lo, hi = _critical_points(p0, p1, m0, m1)
    reach = jnp.zeros(jnp.shape(p0), dtype=bool)
    for r in (lo, hi):
        inside = r < 1.0
        reach = reach | (inside & (hermite(p0, p1, m0, m1, r) >= level))
    return reach


def first_upcrossing(p0, p1, m0, m1, level):
    """First `u` in (0, 1] where the piece reaches `level` from below.

    The piece is split at its critical points into monotone parts; the first part that starts
    strictly below `level` and ends at or above it holds the crossing. A piece that starts
    exactly at `level` and falls (the slip onset) is not a crossing.

    **Returns:** `(found, lo, hi)`, the bracket of the crossing within the piece.
    """
    c1, c2 = _critical_points(p0, p1, m0, m1)
    knots = (jnp.zeros_like(c1), c1, c2, jnp.ones_like(c1))
    vals = tuple(hermite(p0, p1, m0, m1, k) for k in knots)
    found = jnp.zeros(jnp.shape(p0), dtype=bool)
    lo = jnp.ones_like(c1)
    hi = jnp.ones_like(c1)
    for i in (2, 1, 0):  # reverse, so the earliest candidate wins
        cand = (vals[i] < level) & (vals[i + 1] >= level)
        lo = jnp.where(cand, knots[i], lo)
        hi = jnp.where(cand, knots[i + 1], hi)
        found = found | cand
    return found, lo, hi


def bisect(p0, p1, m0, m1, level, lo, hi):
    """Root of an increasing piece on the bracket [lo, hi] (value below `level` at lo)."""

    def body(_, bracket):
        lo, hi = bracket
        mid = 0.5 * (lo + hi)
        below = hermite(p0, p1, m0, m1, mid) < level
        return jnp.where(below, mid, lo), jnp.where(below, hi, mid)

    lo, hi = jax.lax.fori_loop(0, _BISECTIONS, body, (lo, hi))
    return hi


def bridge_crossing_fraction(alpha, beta, var, h, z, u):
    r"""Sample where, inside a step of length `h`, a Brownian bridge first hits a level.

    The crossing variable starts `alpha >= 0` below the level and ends `beta` below it
    (`beta <= 0`: it ends above); its noise has variance rate `var`. Given that it hits, the
    hitting time $s$ satisfies $r = s/(h - s) \sim IG(\mu = \alpha/|\beta|,
    \lambda = \alpha^2/(\mathrm{var}\,h))$: the first-passage density of Brownian motion
    times the bridge's remaining density, changed to the variable $r$, is an inverse Gaussian.
    Sampled with Michael, Schucany & Haas (1976) from one normal `z` and one uniform `u`.

    **Returns:** $s/h$ in [0, 1].
    """
    alpha = jnp.maximum(alpha, 0.0)
    b = jnp.maximum(jnp.abs(beta), 1e-12 * alpha)  # beta = 0: the Levy limit mu -> inf
    mu = alpha / jnp.where(b > 0.0, b, 1.0)
    lam = alpha * alpha / jnp.where(var * h > 0.0, var * h, 1.0)
    q = mu * z * z / (2.0 * jnp.where(lam > 0.0, lam, 1.0))
    x = mu / (1.0 + q + jnp.sqrt(q * q + 2.0 * q))
    r = jnp.where(u <= mu / (mu + x), x, mu * mu / jnp.where(x > 0.0, x, 1.0))
    frac = r / (1.0 + r)
    return jnp.where(alpha > 0.0, frac, 0.0)


def locate(model, solver, y0, y1, h, *, smooth, monitor, z, u):
    """Where a path stuck inside its last step: `(fraction of the step, state at the stick,
    found)` for each path, from the states `y0`, `y1` (each `(d, n)`) at the step's ends.

    Grid monitoring: linear interpolation (the classic convention). Continuous monitoring:

    - differentiable crossing variable: the first upcrossing of the solver's interpolant
      (cubic Hermite pieces between the solver's dense nodes); if that interpolant has none
      (a graze caught only by the coarse in-step check), the coarse cubic through the end
      points with the drift as slope;
    - noise in the crossing variable: the Brownian-bridge hitting time.
    """
    level = model.stick_level
    cross = over_paths(model.crossing)
    if monitor == "grid":
        # The classic convention (the paper's simulations, the reference data): the stick is
        # found at the first grid point at or above the level, and placed by linear
        # interpolation of the crossing variable and of the state.
        c0, c1 = cross(y0), cross(y1)
        frac = jnp.clip((level - c0) / jnp.where(c1 > c0, c1 - c0, 1.0), 0.0, 1.0)
        return frac, y0 + frac * (y1 - y0), jnp.ones(c0.shape, dtype=bool)
    values, slopes = solver.dense_nodes(model, y0, y1, h)  # (M+1, d, n)
    M = values.shape[0] - 1
    hs = h / M
    c = jax.vmap(cross)(values)  # (M+1, n)
    if smooth:
        rate = over_paths(lambda y, dy: jax.jvp(model.crossing, (y,), (dy,))[1])
        m = hs * jax.vmap(rate)(values, slopes)
        found, lo, hi = first_upcrossing(c[:-1], c[1:], m[:-1], m[1:], level)
        j = jnp.argmax(found, axis=0)
        fine = jnp.any(found, axis=0)
        take = lambda a: jnp.take_along_axis(a, j[None], axis=0)[0]
        # Coarse cubic through the end points (what the in-step check looked at).
        crate = over_paths(model.crossing_rate)
        cc0, cc1 = c[0], c[M]
        cm0, cm1 = h * crate(y0), h * crate(y1)
        cfound, clo, chi = first_upcrossing(cc0, cc1, cm0, cm1, level)
        pick = lambda fine_value, coarse_value: jnp.where(fine, fine_value, coarse_value)
        p0, p1 = pick(take(c[:-1]), cc0), pick(take(c[1:]), cc1)
        m0, m1 = pick(take(m[:-1]), cm0), pick(take(m[1:]), cm1)
        uu = bisect(p0, p1, m0, m1, level, pick(take(lo), clo), pick(take(hi), chi))
        found = fine | cfound
        frac = jnp.where(found, pick((j + uu) / M, uu), 1.0)
    else:
        c0, c1 = c[0], c[M]
        var = over_paths(model.crossing_noise)(y0)
        frac = bridge_crossing_fraction(level - c0, level - c1, var, h, z, u)
        found = jnp.ones(c0.shape, dtype=bool)
    # State at the stick: Hermite interpolation on the piece holding it.
    pos = jnp.clip(frac * M, 0.0, M)
    j = jnp.minimum(jnp.floor(pos).astype(jnp.int32), M - 1)
    node = lambda a, k: jnp.take_along_axis(a, (j + k)[None, None], axis=0)[0]
    state = hermite(
        node(values, 0), node(values, 1), hs * node(slopes, 0), hs * node(slopes, 1), pos - j
    )
    return frac, state, found
