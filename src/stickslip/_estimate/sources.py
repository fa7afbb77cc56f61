"""Where the upcrossing densities come from: closed-form Gaussian formulas, or a record of
simulated upcrossings. Both give, on a uniform time grid t_k = k h, per component:

- `n1` (K, n) and `K2` (K, n), with K2(t) = int_0^t n2(t, s) ds (the density of an
  upcrossing at t times the expected number of earlier ones);
- the position-resolved densities as boxes: times `T`, positions `X` and widths in x (all
  (K, P); width 0 for point masses) with the weights of n1(x, t) dx dt and of
  K2(x, t) dx dt they carry, and the onset position of each (broadcastable to `X`);

the component weights `w` (K,) (their sum is the probability that the slip has non-zero
length), and `thresholds`, the law of the onset position as `(nodes, weights)` (for the
next cycle's threshold).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import special

from .._jax import jnp
from .._linear import stationary
from . import gaussian as G
from . import kernels, series

_XI_MAX = 8.5  # standardised positions covered (the rest of a normal law is below 1e-16)
_XI_COARSE = 33  # xi points of the second-order position-resolved correction
_FIRST_PANEL = 1e-6  # the innermost panels: their share of the integral is negligible
_GL_NODES = 8  # Gauss-Legendre nodes per panel
_BLOCK = 224  # grid times per block of K2_grid: their short lags fit in _SHORT_ROWS
_SHORT_ROWS = 8192  # 32 short lags per grid time (last panels) + the shared ones (< 1000)


def _graded(length, first):
    """Panel edges 0, p, 2p, 4p, ... up to `length` (geometric grading from 0)."""
    n = max(1, int(math.ceil(math.log2(max(length, first) / first))) + 1)
    edges = np.minimum(np.concatenate([[0.0], first * 2.0 ** np.arange(n)]), length)
    return edges[np.concatenate([[True], np.diff(edges) > 0])]


_LEGENDRE = np.polynomial.legendre.leggauss(_GL_NODES)


def _gauss(edges):
    x, w = _LEGENDRE
    a, b = edges[:-1, None], edges[1:, None]
    return (0.5 * (b - a) * (x + 1.0) + a).ravel(), (0.5 * (b - a) * w).ravel()


def lag_rule(t):
    """Quadrature over the lag tau in (0, t] for int_0^t n2(t, t - tau) dtau.

    Gauss-Legendre on panels graded geometrically towards both ends. Near the diagonal
    (tau -> 0) n2 varies on the noise's correlation time and behaves like
    alpha + beta sqrt(tau) (exact case) or alpha tau^-1/2 + beta (the closure's integrable
    singularity): with tau = u^2 both are smooth in u, so that half is integrated in u. Near
    the onset (s = t - tau -> 0) the first upcrossings cluster. Returns (tau, weight)."""
    if t <= 0:
        return np.zeros(0), np.zeros(0)
    u, wu = _gauss(_graded(math.sqrt(0.5 * t), math.sqrt(_FIRST_PANEL)))
    s, ws = _gauss(_graded(0.5 * t, _FIRST_PANEL))
    return np.concatenate([u * u, t - s]), np.concatenate([2.0 * u * wu, ws])


def _panels(lengths, first):
    """The panels of `_graded(length, first)` for many lengths, split into what the lengths
    share and what they do not: every panel but the last is one of the fixed geometric
    panels [0, p], [p, 2p], [2p, 4p], ...; only the last, [.., length], is a length's own.
    Returns the nodes and weights of the shared panels (in panel order), how many of them
    each length uses, and the nodes and weights of each length's last panel (n, nodes)."""
    # the edges of `_graded` (its count n from the same math.log2): 0, p 2^i (i < n - 1)
    # and the length, less a repeated last edge
    n = np.array([max(1, int(math.ceil(math.log2(max(L, first) / first))) + 1) for L in lengths])
    n = n.astype(np.int64)
    below = np.where(n >= 2, first * 2.0 ** np.maximum(n - 2, 0), 0.0)
    repeated = (n >= 2) & (np.minimum(below, lengths) == lengths)
    n_panels = n - repeated  # panels: edges - 1
    lo = np.where(repeated, first * 2.0 ** np.maximum(n - 3, 0), below)
    lo = np.where(repeated & (n == 2), 0.0, lo)
    used = (n_panels - 1) * _GL_NODES
    most = int(n_panels.max(initial=1))
    longest = np.concatenate([[0.0], first * 2.0 ** np.arange(most - 1), [np.inf]])
    x, w = _LEGENDRE
    half = 0.5 * (lengths - lo)[:, None]
    last = (half * (x + 1.0) + lo[:, None], half * w)
    shared = _gauss(longest[:-1]) if longest.size > 2 else (np.zeros(0), np.zeros(0))
    return shared, used, last


@dataclasses.dataclass
class _GridPairs:
    """The (earlier time s, lag tau) pairs of `lag_rule` at the times k h of a uniform grid,
    described through tables that many pairs share (see `GaussianSource._grid_pairs`)."""

    k: np.ndarray  # grid index of the later time t of each pair
    weight: np.ndarray  # quadrature weight
    tau: np.ndarray  # the lag t - s
    moment: np.ndarray  # grid time g h <= s: its moments are carried on to s
    carry: np.ndarray  # row of the propagator table that carries them (lag s - g h)
    first: np.ndarray  # short lag of the propagator table followed by grid lag `grid_lag`:
    grid_lag: np.ndarray  # together the lag tau
    lags: np.ndarray  # the short lags (< h) of the propagator table's rows 1, 2, ...


# Error control of the cell integrals of n1 (`GaussianSource._cell_integrals`).
CELL_RTOL = 1e-7
CELL_ATOL = 1e-11
CELL_DEPTH = 14  # finest sub-interval h / 2**14
N1_BLOCK = 1024  # times per evaluation of n1 at arbitrary times


def _padded(a):
    """`a` (1-d) padded with its last entry to a power-of-two length (`kernels.bucket`):
    the point evaluations' kernels are compiled per length, and a user's time grids come
    in every length."""
    a = np.asarray(a)
    size = kernels.bucket(a.size)
    return np.pad(a, (0, size - a.size), mode="edge") if 0 < a.size < size else a


def _n1_blocked(cr, ms, Ps):
    """`kernels.n1_from` for moments `(K, n, ...)` on a grid, in blocks of `N1_BLOCK` times
    (when they divide n): the one compiled shape of the point evaluations (`_n1_at`) serves
    the grids too (a first run compiled n1 twice). n1 is computed time by time: the same
    numbers. A NumPy array `(K, n)`."""
    n = ms.shape[1]
    if n % N1_BLOCK:
        return np.array(kernels.n1_from(cr, ms, Ps))
    ms, Ps = np.asarray(ms), np.asarray(Ps)
    blocks = [
        np.asarray(kernels.n1_from(cr, ms[:, lo : lo + N1_BLOCK], Ps[:, lo : lo + N1_BLOCK]))
        for lo in range(0, n, N1_BLOCK)
    ]
    return np.concatenate(blocks, axis=1)


class GaussianSource:
    """Closed-form densities of a linear-Gaussian slip (see `gaussian.py`)."""

    def __init__(self, cr, mixture, *, exact, quadrature_nodes, x_points):
        """`mixture`: the onset law as Gaussian components `(m0s, P0s, weights)`."""
        self.cr, self.exact, self.x_points = cr, exact, x_points
        g, p = np.asarray(cr.g), np.asarray(cr.p)
        self._g, self._p, self.level = g, p, float(cr.level)
        parts = [
            self._onset(m0, P0, exact, quadrature_nodes)
            for m0, P0 in zip(mixture[0], mixture[1], strict=True)
        ]
        weights = np.asarray(mixture[2], float)
        self.m0s = np.concatenate([part[0] for part in parts])
        self.P0s = np.concatenate([part[1] for part in parts])
        self.w = np.concatenate([wm * part[2] for wm, part in zip(weights, parts, strict=True)])
        self.immediate_probability = float(
            sum(wm * part[3] for wm, part in zip(weights, parts, strict=True))
        )
        self.x0 = self.m0s @ p
        # The law of the onset position (the threshold), for the next cycle's threshold.
        pos, inverse = np.unique(np.round(mixture[0] @ p, 14), return_inverse=True)
        self.thresholds = (pos, np.bincount(inverse, weights=weights))
        self._grids: dict = {}
        self._K2: dict = {}  # K2 on the grid of step h, per h
        self._profiles: dict = {}
        self.progress = None  # see CrossingEstimator
        self._boxes: dict = {}  # first-order boxes of the position-resolved densities

    def _onset(self, m0, P0, exact, quadrature_nodes):
        """Components for one Gaussian onset N(m0, P0): `(m0s, P0s, weights, p0)`."""
        A, b = np.asarray(self.cr.A), np.asarray(self.cr.b)
        g = self._g
        h = A.T @ g
        mu = float(h @ m0 + g @ b)
        var = float(h @ P0 @ h)
        if var <= 0.0 or not exact:
            # A sharp onset (or the closure, which has no finite a(0)): one component; the
            # slip is immediate when the crossing variable is already rising.
            p0 = 1.0 if (exact and mu >= 0.0) else 0.0
            return m0[None], P0[None], np.array([1.0 - p0]), p0
        # Gauss-Legendre over the initial rate a(0) in [mu - 8.5 sd, 0] with its normal
        # density as part of the integrand (smooth: the rule converges exponentially, where a
        # rule uniform in the distribution function met a log singularity).
        sd = math.sqrt(var)
        lo = min(mu - 8.5 * sd, -1e-12 * sd)
        x, wq = np.polynomial.legendre.leggauss(quadrature_nodes)
        a0 = 0.5 * lo * (1.0 - x)  # from lo to 0
        k = P0 @ h / var
        P_cond = P0 - np.outer(k, h @ P0)
        density = np.exp(-0.5 * ((a0 - mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
        return (
            m0[None] + np.outer(a0 - mu, k),
            np.repeat(0.5 * (P_cond + P_cond.T)[None], a0.size, axis=0),
            0.5 * (-lo) * wq * density,
            float(special.ndtr(mu / sd)),
        )

    @property
    def n_components(self):
        return self.w.size

    # -- point evaluation --------------------------------------------------------------------
    def moments(self, t):
        return kernels.moments_at(self.cr, self.m0s, self.P0s, t)

    def n1(self, t):
        return self.w @ self._n1_at(t)  # in blocks of one shape: any t compiles nothing new

    def n1_joint(self, x, t):
        nx, nt = x.size, t.size
        ms, Ps = self.moments(_padded(t))
        x = _padded(x)
        xs = jnp.broadcast_to(jnp.asarray(x), (self.n_components, x.size))
        joint = np.asarray(kernels.n1_joint_from(self.cr, ms, Ps, xs))[:, :nx, :nt]
        out = np.einsum("k,kxt->xt", self.w, joint)
        out[:, t <= 0] = 0.0
        return out

    def n2(self, lo, lag):
        """n2 for flat arrays of (earlier time, lag > 0), mixed over components. (Times,
        lags and pairs are padded to a few lengths, `_padded`: any request compiles nothing
        new once those are.)"""
        ut, ti = np.unique(lo, return_inverse=True)
        ul, li = np.unique(lag, return_inverse=True)
        ul = _padded(ul)
        ms, Ps = self.moments(_padded(ut))
        prop = kernels.lag_propagators(self.cr, ul)
        n = lo.size
        ti, li = _padded(ti), _padded(li)
        ul = jnp.asarray(ul[li])
        total = np.zeros(n)
        for c in range(self.n_components):
            vals = kernels.n2_pairs(self.cr, ms[c][ti], Ps[c][ti], *(a[li] for a in prop), ul)
            total += self.w[c] * np.asarray(vals)[:n]
        return total

    def stationary_rate(self):
        m, P = stationary(self.cr.A, self.cr.b, self.cr.B)
        return float(G.n1(self.cr, m, P))

    # -- grids -------------------------------------------------------------------------------
    def grid(self, t_end, h):
        """Moments and n1 at t_k = k h for k < n, n >= t_end / h + 1 (rounded up to a power
        of two: each grid time's moments are computed from its own lag, so their values do
        not depend on the grid's length, and the n1 kernels meet few lengths)."""
        n = int(math.ceil(t_end / h - 1e-9)) + 1
        have = self._grids.get(h)
        if have is not None and have["n"] >= n:
            return have
        n = max(8192, 1 << (n - 1).bit_length())
        ms, Ps = kernels.grid_moments(self.cr, self.m0s, self.P0s, h, n)
        n1 = _n1_blocked(self.cr, ms, Ps)
        n1[:, 0] = 0.0
        cells, unresolved = self._cell_integrals(n1, h, ms, Ps)
        I1 = np.concatenate([np.zeros((n1.shape[0], 1)), np.cumsum(cells, axis=1)], axis=1)
        entry = dict(n=n, h=h, ms=ms, Ps=Ps, n1=n1, I1=I1, unresolved=unresolved)
        self._grids[h] = entry
        return entry

    def _cell_integrals(self, n1, h, ms, Ps):
        """The integral of n1 over every grid cell [t_k, t_k + h], per component, to a
        controlled error: Simpson's rule with the cell's midpoint (the grid's moments `ms`,
        `Ps` carried on exactly by h/2), and where its error (estimated by Richardson over
        pairs of cells) exceeds `CELL_RTOL` (relative) or `CELL_ATOL`, adaptive Simpson
        (`integrate_n1`). The onset
        transient is as short as the noise's correlation time, which a grid step fixed in
        advance may not resolve (tau = 0.01: the trapezoid gave int_0^0.5 n1 = 1.22 for
        1.82). Returns the integrals (K, n - 1) and the number of sub-intervals still
        unresolved at the finest level (their last estimate is kept)."""
        mm, Pm = kernels.step_moments(self.cr, ms, Ps, 0.5 * h)
        mid = _n1_blocked(self.cr, mm, Pm)[:, :-1]
        f0, f1 = n1[:, :-1], n1[:, 1:]
        simpson = h / 6.0 * (f0 + 4.0 * mid + f1)
        # Simpson's error, by Richardson over pairs of cells: the pair's rule of step h
        # (grid values alone) against the two cells' rules of step h/2 differs by about 15
        # times the latter's error. An odd last cell is checked against the trapezoid.
        c = simpson.shape[1]
        pairs = c // 2
        fine = simpson[:, 0 : 2 * pairs : 2] + simpson[:, 1 : 2 * pairs : 2]
        coarse = h / 3.0 * (n1[:, 0 : 2 * pairs : 2] + 4.0 * n1[:, 1 : 2 * pairs + 1 : 2]
                            + n1[:, 2 : 2 * pairs + 2 : 2])  # fmt: skip
        pair_bad = np.abs(fine - coarse) / 15.0 > CELL_ATOL + CELL_RTOL * np.abs(fine)
        bad = np.zeros_like(simpson, dtype=bool)
        bad[:, 0 : 2 * pairs : 2] = bad[:, 1 : 2 * pairs : 2] = pair_bad
        if c % 2:
            trapezoid = 0.5 * h * (f0[:, -1] + f1[:, -1])
            last = simpson[:, -1]
            bad[:, -1] = np.abs(last - trapezoid) > CELL_ATOL + CELL_RTOL * np.abs(last)
        flagged = np.nonzero(bad.any(axis=0))[0]  # cells to refine (every component)
        if flagged.size == 0:
            return simpson, 0
        a = flagged * h
        values, unresolved = self.integrate_n1(
            a, a + h, ends=(f0[:, flagged], mid[:, flagged], f1[:, flagged])
        )
        simpson[:, flagged] = values
        return simpson, unresolved

    def integrate_n1(self, a, b, ends=None):
        """int_a^b n1 per component for intervals `(a_i, b_i)` (arrays), by adaptive Simpson
        to `CELL_RTOL` / `CELL_ATOL`, bisecting down to (b - a) / 2**`CELL_DEPTH`; `ends`: n1
        at a, the midpoint and b if known. Level by level over every open sub-interval; a
        sub-interval is kept where its halves agree with it (Richardson-corrected).
        Returns `(integrals (K, m), sub-intervals unresolved at the finest level)`."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        m = a.size
        if m == 0:
            return np.zeros((self.n_components, 0)), 0
        w = b - a
        if ends is None:
            q = self._n1_at(np.concatenate([a, a + 0.5 * w, b]))
            fa, fm, fb = q[:, :m], q[:, m : 2 * m], q[:, 2 * m :]
        else:
            fa, fm, fb = ends
        whole = w / 6.0 * (fa + 4.0 * fm + fb)
        owner = np.arange(m)
        total = np.zeros((self.n_components, m))
        unresolved = 0
        for depth in range(CELL_DEPTH):
            q = self._n1_at(np.concatenate([a + 0.25 * w, a + 0.75 * w]))
            f_l, f_r = q[:, : a.size], q[:, a.size :]
            left = w / 12.0 * (fa + 4.0 * f_l + fm)
            right = w / 12.0 * (fm + 4.0 * f_r + fb)
            diff = left + right - whole
            ok = np.all(np.abs(diff) <= CELL_ATOL + CELL_RTOL * np.abs(left + right), axis=0)
            last = depth == CELL_DEPTH - 1
            keep = ok | last
            if last:
                unresolved = int(np.sum(~ok))
            np.add.at(total.T, owner[keep], (left + right + diff / 15.0)[:, keep].T)
            go = ~keep
            if not go.any():
                break
            a = np.concatenate([a[go], a[go] + 0.5 * w[go]])
            w = np.concatenate([0.5 * w[go], 0.5 * w[go]])
            fa, fm, fb, whole = (
                np.concatenate([fa[:, go], fm[:, go]], axis=1),
                np.concatenate([f_l[:, go], f_r[:, go]], axis=1),
                np.concatenate([fm[:, go], fb[:, go]], axis=1),
                np.concatenate([left[:, go], right[:, go]], axis=1),
            )
            owner = np.concatenate([owner[go], owner[go]])
        return total, unresolved

    def I1_at(self, t, entry):
        """int_0^t n1 per component at arbitrary times `t` (within the grid of `entry`): the
        grid's error-controlled integral to the cell's start plus the rest of the cell."""
        t = np.asarray(t, float)
        h = entry["h"]
        k = np.clip(np.floor(t / h).astype(int), 0, entry["n"] - 1)
        start = k * h
        rest, _ = self.integrate_n1(start, np.maximum(t, start))
        return entry["I1"][:, k] + rest

    def _n1_at(self, t):
        """n1 per component at arbitrary times, in blocks of `N1_BLOCK` (one compiled
        shape: the adaptive integrals ask for every size; smaller blocks for the small
        requests saved nothing measurable and cost 0.8 s of loading on a first call)."""
        t = np.asarray(t, float)
        out = np.empty((self.n_components, t.size))
        for lo in range(0, t.size, N1_BLOCK):
            part = t[lo : lo + N1_BLOCK]
            padded = np.concatenate([part, np.full(N1_BLOCK - part.size, part[-1])])
            ms, Ps = self.moments(padded)
            values = np.asarray(kernels.n1_from(self.cr, ms, Ps))
            out[:, lo : lo + part.size] = values[:, : part.size]
        return np.where(t > 0, out, 0.0)

    def second_order(self, entry, n):
        """K2 at the first `n` times of the grid of `entry`. Kept per step h: a longer grid
        (a longer horizon) computes K2 only at its new times."""
        h = entry["h"]
        have = self._K2.get(h, np.zeros((self.n_components, 0)))
        if have.shape[1] < n:
            have = np.concatenate([have, self.K2_grid(entry, have.shape[1], n)], axis=1)
            self._K2[h] = have
        return have[:, :n]

    def K2_grid(self, entry, start, stop, X=None):
        """K2(t) = int_0^t n2(t, s) ds per component at the grid times k h of `entry`,
        start <= k < stop: (K, stop - start); with positions X (K, J, stop - start), the
        position-resolved K2(x, t) there. The quadrature is `lag_rule`'s, evaluated through
        tables (`_grid_pairs`), in blocks of `_BLOCK` grid times whose tables have one
        shape (compiled once)."""
        n_out = stop - start
        shape = (self.n_components, n_out) if X is None else (self.n_components, X.shape[1], n_out)
        out = np.zeros(shape)
        blocks = range(start, stop, _BLOCK)
        step = self.n_components * (1 if X is None else 4)  # cost of a block, ~0.1 s
        bar = self._bar(len(blocks) * step)
        for lo in blocks:
            hi = min(lo + _BLOCK, stop)
            self._K2_block(entry, lo, hi, out[..., lo - start : hi - start], X, start)
            if bar is not None:
                bar.update(step)
        if bar is not None:
            bar.close()
        return out

    def _K2_block(self, entry, lo, hi, out, X, start):
        """`K2_grid` at the grid times lo <= k < hi, into `out` (K, [J,] hi - lo); X: the
        positions of `K2_grid` (from grid time `start` on) or None."""
        h = entry["h"]
        pairs = self._grid_pairs(entry, lo, hi)
        if pairs.k.size == 0:
            return
        if "lag_props" not in entry:
            entry["lag_props"] = kernels.grid_lag_propagators(self.cr, h, entry["n"])
        # the propagator table: the identity, the short lags (< h), the grid lags j h
        d = self._g.size
        ident = (np.eye(d)[None], np.zeros((1, d, d)), np.zeros((1, d)), np.zeros((1, d, d)))
        n_rows = max(_SHORT_ROWS, kernels.bucket(pairs.lags.size))
        short = kernels.lag_propagators(self.cr, np.pad(pairs.lags, (0, n_rows - pairs.lags.size)))
        table = tuple(
            np.concatenate([i, a, g])
            for i, a, g in zip(ident, short, entry["lag_props"], strict=True)
        )
        second = 1 + n_rows + pairs.grid_lag
        rows = np.stack([pairs.moment, pairs.carry, pairs.first, second], axis=1)
        local = pairs.k - lo
        ms_all, Ps_all = entry["ms"], entry["Ps"]
        for c in range(self.n_components):
            args = (self.cr, ms_all[c], Ps_all[c], table, rows, pairs.tau)
            if X is None:
                vals = kernels.table_pairs(*args)
                out[c] = np.bincount(local, weights=pairs.weight * vals, minlength=hi - lo)
            else:
                xs = X[c, :, lo - start : hi - start].T  # (hi - lo, J)
                xs = np.pad(xs, ((0, _BLOCK - (hi - lo)), (0, 0)), mode="edge")
                vals = kernels.table_pairs(*args, positions=(xs, local))
                for ix in range(X.shape[1]):
                    w = pairs.weight * vals[:, ix]
                    out[c, ix] = np.bincount(local, weights=w, minlength=hi - lo)

    def _bar(self, work):
        """A progress bar for `work` steps of K2 (about 0.1 s each on 2 cores) when they
        take more than about 2 s: with `progress=True`, or by default on a terminal."""
        show = self.progress
        if show is None:
            import sys

            show = sys.stderr.isatty()
        if not show or work < 20:
            return None
        from tqdm.auto import tqdm

        return tqdm(total=work, desc="n2 integrals", unit="step", leave=False)

    def _grid_pairs(self, entry, start, stop):
        """The pairs (s, tau) of `lag_rule(t)` for t = k h, start <= k < stop, as rows of
        tables (see `kernels._table_pair`).

        The moments at s and the propagator over tau cost a matrix exponential each if
        computed directly. Here every time is a grid time plus a short lag below h: the
        moments at s are the grid moments at g h <= s carried on over s - g h, and the
        propagator over tau is that of a short lag followed by one of the grid lags j h (the
        grid moments and grid propagators are computed once per grid, `kernels`). Short lags
        are shared where the rule shares nodes: in the u-half all panels but the last are
        the same for every t (so are their lags tau_j, and s = k h - tau_j is the grid time
        (k - q_j) h plus q_j h - tau_j); in the s-half the nodes s_i of all panels but the
        last are shared (tau = k h - s_i is q_i h - s_i followed by (k - q_i) h). Only the
        last panels (8 + 8 nodes per t) need short lags of their own. Row 0 of the
        propagator table is the identity, then come the `lags` rows; `grid_lag` indexes
        the grid lags."""
        h, n_grid = entry["h"], entry["n"]
        ks = np.arange(max(start, 1), stop)  # t = 0 has no lag
        t = np.arange(n_grid)[ks] * h  # as np.arange(n) * h: the times of the grid
        sq = math.sqrt(_FIRST_PANEL)
        (u_sh, wu_sh), u_used, (u_last, wu_last) = _panels(np.sqrt(0.5 * t), sq)
        (s_sh, ws_sh), s_used, (s_last, ws_last) = _panels(0.5 * t, _FIRST_PANEL)
        tau_sh, wtau_sh = u_sh * u_sh, 2.0 * u_sh * wu_sh
        lags: list = []

        def short(values):
            """Rows of the short lags `values` (each in [0, h])."""
            rows = 1 + sum(v.size for v in lags) + np.arange(values.size)
            lags.append(values)
            return rows

        def below(x):
            """Grid steps g with g h <= x (floating point), at most the last grid time."""
            g = np.minimum(np.floor(x / h).astype(np.int64), n_grid - 1)
            return g - (g * h > x)

        def above(x):
            q = np.ceil(x / h).astype(np.int64)
            return q + (q * h < x)

        def expand(used):
            k = np.repeat(np.arange(ks.size), used)
            j = np.arange(k.size) - np.repeat(np.cumsum(used) - used, used)
            return k, j

        parts = []
        # u-half, shared panels: s = (k - q_j) h + eps_j; tau_j = j_j h + delta_j
        k, j = expand(u_used)
        q = above(tau_sh)
        eps = short(q * h - tau_sh)
        g = below(tau_sh)
        delta = short(tau_sh - g * h)
        parts.append((k, wtau_sh[j], tau_sh[j], ks[k] - q[j], eps[j], delta[j], g[j]))
        # s-half, shared panels: s_i = g_i h + eps_i; tau = (q_i h - s_i) + (k - q_i) h
        k, j = expand(s_used)
        g = below(s_sh)
        eps = short(s_sh - g * h)
        q = above(s_sh)
        delta = short(q * h - s_sh)
        parts.append((k, ws_sh[j], t[k] - s_sh[j], g[j], eps[j], delta[j], ks[k] - q[j]))
        # the last panels: short lags of their own
        k = np.repeat(np.arange(ks.size), _GL_NODES)
        u = u_last.ravel()
        last = ((u * u, 2.0 * u * wu_last.ravel()), (t[k] - s_last.ravel(), ws_last.ravel()))
        for tau, w in last:
            s_ = np.maximum(t[k] - tau, 0.0)
            g, gt = below(s_), below(tau)
            parts.append((k, w, tau, g, short(s_ - g * h), short(tau - gt * h), gt))

        def column(i, dtype=float):
            return np.concatenate([np.asarray(p[i], dtype) for p in parts])

        return _GridPairs(
            k=ks[column(0, np.int64)],
            weight=column(1),
            tau=column(2),
            moment=column(3, np.int64),
            carry=column(4, np.int64),
            first=column(5, np.int64),
            grid_lag=column(6, np.int64),
            lags=np.concatenate(lags) if lags else np.zeros(0),
        )

    def positions(self, entry, n_t, n_xi, start=0):
        """Positions at an upcrossing on a uniform grid of the standardised position
        xi in [-8.5, 8.5] under the Gaussian law of x given v = L, per component and grid
        time, as boxes: centres X and widths (K, n_xi, n_t). The law is narrow at short
        times (short slips stick on a thin ridge x ~ x0 + v_b t that no fixed grid
        resolves) and wide later; boxes rather than points keep histograms free of
        aliasing at any cell size. `start`: only the grid times from it on."""
        ms, Ps = entry["ms"][:, start:n_t], entry["Ps"][:, start:n_t]
        g, p = self._g, self._p
        svv = np.einsum("i,knij,j->kn", g, Ps, g)
        sxv = np.einsum("i,knij,j->kn", p, Ps, g)
        sxx = np.einsum("i,knij,j->kn", p, Ps, p)
        ok = svv > 0
        ratio = np.where(ok, sxv / np.where(ok, svv, 1.0), 0.0)
        mu = ms @ p + ratio * (self.level - ms @ g)
        sd = np.sqrt(np.maximum(sxx - ratio * sxv, 0.0))
        xi = np.linspace(-_XI_MAX, _XI_MAX, n_xi)
        X = mu[:, None, :] + sd[:, None, :] * xi[None, :, None]
        width = np.broadcast_to(sd[:, None, :] * (xi[1] - xi[0]), X.shape)
        return X, width

    def points(self, t_end, h, order, coarse_h, n_t=None):
        """Boxes of n1(x, t) dx dt and K2(x, t) dx dt at the positions of the grid times
        up to t_end, or of the first `n_t` of them (each grid time's values do not depend on
        the later ones; the trapezoid weights are those of the grid up to t_end).

        K2(x, t) is computed on a coarser grid, in time (`coarse_h`) and in xi
        (`_XI_COARSE` points): its profile over xi is interpolated onto the fine grid and
        scaled to K2(t) on the fine grid, so that it sums to the marginal term exactly
        (n1(x, t), which carries the thin short-slip ridge, is exact on the fine grid)."""
        entry = self.grid(t_end, h)
        n_all = int(round(t_end / h)) + 1
        n_t = n_all if n_t is None else min(n_t, n_all)
        t = np.arange(n_t) * h
        X, width, n1w = self._first_order(entry, n_all, n_t)
        dt_w = series.trapezoid_weights(n_all, h)[:n_t]
        K2x = None
        if order == 2:
            tc = np.arange(int(round(t_end / coarse_h)) + 1) * coarse_h
            n_c = min(tc.size, int(np.searchsorted(tc, t[-1])) + 1)  # tc[n_c - 1] >= t[-1]
            tc = tc[:n_c]
            profile = self._profile(t_end, coarse_h, n_c)  # (K, coarse xi, n_c), per unit x
            xi_c = np.linspace(-_XI_MAX, _XI_MAX, _XI_COARSE)
            xi_f = np.linspace(-_XI_MAX, _XI_MAX, self.x_points)
            K_fine = self.second_order(entry, n_t)
            K2x = np.zeros(X.shape)
            for c in range(self.n_components):
                # per unit xi at coarse times -> fine times -> fine xi
                over_t = np.array([np.interp(t, tc, row) for row in profile[c]])
                fine = np.array([np.interp(xi_f, xi_c, col) for col in over_t.T]).T
                total = fine.sum(axis=0)
                share = np.where(total > 0, fine / np.where(total > 0, total, 1.0), 0.0)
                K2x[c] = share * K_fine[c] * dt_w
        T = np.broadcast_to(t, X.shape)
        X0 = self.x0.reshape((-1,) + (1,) * (X.ndim - 1))
        return T, X, width, n1w, K2x, X0

    def _first_order(self, entry, n_all, n_t):
        """Positions X (K, J, n_t), widths and the weights n1(x, t) dx dt of the boxes of
        the first n_t times of the grid of `entry` cut at n_all times (trapezoid weights
        of that grid). Kept, and extended when more times are asked for: the boxes of a
        time do not depend on later ones."""
        key = (entry["h"], n_all)
        have = self._boxes.get(key)
        shape = (self.n_components, self.x_points, n_all)
        if have is None:
            have = dict(done=0, X=np.empty(shape), wd=np.empty(shape[::2]), n1w=np.empty(shape))
            self._boxes[key] = have
        done = have["done"]
        if done < n_t:
            X, width = self.positions(entry, n_t, self.x_points, start=done)
            n1x = self._n1_joint(entry, X, done)
            if done == 0:
                n1x[:, :, 0] = 0.0
            dt_w = series.trapezoid_weights(n_all, entry["h"])[done:n_t]
            have["X"][:, :, done:n_t] = X
            have["wd"][:, done:n_t] = width[:, 0, :]
            have["n1w"][:, :, done:n_t] = n1x * width * dt_w
            have["done"] = n_t
        X = have["X"][:, :, :n_t]
        width = np.broadcast_to(have["wd"][:, None, :n_t], X.shape)
        return X, width, have["n1w"][:, :, :n_t]

    def _n1_joint(self, entry, X, start):
        """n1(x, t) at the positions X (K, J, n) of the grid times start, start + 1, ...,
        in blocks of grid times of one size (one compiled shape)."""
        ms, Ps = entry["ms"], entry["Ps"]
        n = X.shape[2]
        out = np.empty(X.shape)
        block = 256
        for lo in range(0, n, block):
            hi = min(lo + block, n)
            a, b = start + lo, min(start + lo + block, ms.shape[1])
            Xb, mb, Pb = X[:, :, lo:hi], ms[:, a:b], Ps[:, a:b]
            if hi - lo < block:  # the last block: padded to the one shape
                Xb = np.concatenate([Xb, np.repeat(Xb[:, :, -1:], block - (hi - lo), axis=2)], 2)
            if b - a < block:
                mb = np.concatenate([mb, np.repeat(mb[:, -1:], block - (b - a), axis=1)], 1)
                Pb = np.concatenate([Pb, np.repeat(Pb[:, -1:], block - (b - a), axis=1)], 1)
            out[:, :, lo:hi] = np.asarray(kernels.n1_joint_nodes(self.cr, mb, Pb, Xb))[
                :, :, : hi - lo
            ]
        return out

    def _profile(self, t_end, coarse_h, n_c):
        """K2(x, t) at `_XI_COARSE` positions at the first `n_c` times of the coarse grid
        (kept, and extended when more are asked for)."""
        key = (coarse_h, int(round(t_end / coarse_h)))
        have = self._profiles.get(key)
        done = 0 if have is None else have.shape[2]
        if done < n_c:
            coarse = self.grid(t_end, coarse_h)
            Xc, _ = self.positions(coarse, n_c, _XI_COARSE)
            new = self.K2_grid(coarse, done, n_c, Xc[:, :, done:])
            have = new if have is None else np.concatenate([have, new], axis=2)
            self._profiles[key] = have
        return have[:, :, :n_c]


class EmpiricalSource:
    """Densities estimated from the upcrossings of simulated free paths (any model).

    Histograms on the grid: n1(t_k) counts the upcrossings in [t_k - h/2, t_k + h/2) per
    path and unit time; K2(t_k) weights each of them by the number of earlier upcrossings of
    its path. The recorded upcrossings themselves are the point masses of the
    position-resolved densities. Statistics are those of the slipping paths (immediate
    re-sticks are the atom p0), weighted by their share.
    """

    def __init__(self, upcrossings):
        u = upcrossings
        slip = ~u.immediate
        self.n_paths = u.n_paths
        self.immediate_probability = float(np.mean(u.immediate))
        self.w = np.array([1.0 - self.immediate_probability])
        onset = u.onset_position
        times, pos = u.times[slip], u.positions[slip]
        self.n_slip = max(int(slip.sum()), 1)
        index = np.broadcast_to(np.arange(times.shape[1]), times.shape)
        ok = np.isfinite(times)
        self.t, self.x, self.index = times[ok], pos[ok], index[ok].astype(float)
        # each upcrossing's own onset position (for the slip distance), and the law of the
        # onset position (all paths: the next cycle's threshold), as up to 64 quantile groups
        self.x0_point = np.broadcast_to(onset[slip][:, None], times.shape)[ok]
        self.thresholds = _empirical_law(onset)
        self.t_complete = u.t_complete
        self.t_max = u.t_max

    @property
    def n_components(self):
        return 1

    def grid(self, t_end, h):
        n = int(math.ceil(t_end / h - 1e-9)) + 1
        edges = (np.arange(n + 1) - 0.5) * h
        scale = 1.0 / (self.n_slip * h)
        n1 = np.histogram(self.t, bins=edges)[0] * scale
        K2 = np.histogram(self.t, bins=edges, weights=self.index)[0] * scale
        # The first cell is half as wide (times are >= 0).
        n1[0] *= 2.0
        K2[0] *= 2.0
        I1 = np.zeros(n)
        I1[1:] = np.cumsum(0.5 * h * (n1[1:] + n1[:-1]))  # the histogram's own integral
        return dict(n=n, h=h, n1=n1[None], K2=K2[None], I1=I1[None], unresolved=0)

    def second_order(self, entry, n):
        return entry["K2"][:, :n]

    def points(self, t_end, h, order, coarse_h, n_t=None):
        keep = self.t <= t_end
        w = np.full(keep.sum(), 1.0 / self.n_slip)
        K2 = (self.index[keep] / self.n_slip)[None] if order == 2 else None
        zero = np.zeros((1, keep.sum()))
        x0 = self.x0_point[keep][None]
        return self.t[keep][None], self.x[keep][None], zero, w[None], K2, x0


def _empirical_law(values, groups=64):
    """A sample as a discrete law `(nodes, weights)`: its distinct values if few, else the
    means of `groups` equal-count quantile groups."""
    values = np.sort(np.asarray(values, float))
    distinct, counts = np.unique(values, return_counts=True)
    if distinct.size <= groups:
        return distinct, counts / counts.sum()
    parts = np.array_split(values, groups)
    return np.array([q.mean() for q in parts]), np.array([q.size for q in parts]) / values.size
