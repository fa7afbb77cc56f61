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


def _graded(length, first):
    """Panel edges 0, p, 2p, 4p, ... up to `length` (geometric grading from 0)."""
    n = max(1, int(math.ceil(math.log2(max(length, first) / first))) + 1)
    edges = np.minimum(np.concatenate([[0.0], first * 2.0 ** np.arange(n)]), length)
    return edges[np.concatenate([[True], np.diff(edges) > 0])]


def _gauss(edges):
    x, w = np.polynomial.legendre.leggauss(_GL_NODES)
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
        return kernels.moments_at(
            self.cr, jnp.asarray(self.m0s), jnp.asarray(self.P0s), jnp.asarray(t)
        )

    def n1(self, t):
        ms, Ps = self.moments(t)
        out = self.w @ np.asarray(kernels.n1_from(self.cr, ms, Ps))
        return np.where(t > 0, out, 0.0)

    def n1_joint(self, x, t):
        ms, Ps = self.moments(t)
        xs = jnp.broadcast_to(jnp.asarray(x), (self.n_components, x.size))
        out = np.einsum("k,kxt->xt", self.w, np.asarray(kernels.n1_joint_from(self.cr, ms, Ps, xs)))
        out[:, t <= 0] = 0.0
        return out

    def n2(self, lo, lag):
        """n2 for flat arrays of (earlier time, lag > 0), mixed over components."""
        ut, ti = np.unique(lo, return_inverse=True)
        ul, li = np.unique(lag, return_inverse=True)
        ms, Ps = self.moments(ut)
        prop = kernels.lag_propagators(self.cr, jnp.asarray(ul))
        total = np.zeros(lo.size)
        for c in range(self.n_components):
            vals = kernels.n2_pairs(
                self.cr, ms[c][ti], Ps[c][ti], *(a[li] for a in prop), jnp.asarray(ul[li])
            )
            total += self.w[c] * np.asarray(vals)
        return total

    def stationary_rate(self):
        m, P = stationary(self.cr.A, self.cr.b, self.cr.B)
        return float(G.n1(self.cr, m, P))

    # -- grids -------------------------------------------------------------------------------
    def grid(self, t_end, h):
        n = int(math.ceil(t_end / h - 1e-9)) + 1
        have = self._grids.get(h)
        if have is not None and have["n"] >= n:
            return have
        ms, Ps = kernels.grid_moments(self.cr, jnp.asarray(self.m0s), jnp.asarray(self.P0s), h, n)
        n1 = np.array(kernels.n1_from(self.cr, ms, Ps))
        n1[:, 0] = 0.0
        entry = dict(n=n, h=h, ms=ms, Ps=Ps, n1=n1, K2=None)
        self._grids[h] = entry
        return entry

    def second_order(self, entry):
        if entry["K2"] is None:
            t = np.arange(entry["n"]) * entry["h"]
            entry["K2"] = self.K2(t)
        return entry["K2"]

    def K2(self, times, X=None):
        """K2(t) = int_0^t n2(t, s) ds per component at `times` (n,), or, with positions X
        (K, J, n), the position-resolved K2(x, t) at X (K, J, n), by the lag quadrature of
        `lag_rule`."""
        rules = [lag_rule(t) for t in times]
        k = np.concatenate([np.full(r[0].size, i) for i, r in enumerate(rules)])
        tau = np.concatenate([r[0] for r in rules])
        wts = np.concatenate([r[1] for r in rules])
        s = np.maximum(np.asarray(times)[k] - tau, 0.0)
        ut, ti = np.unique(s, return_inverse=True)
        ul, li = np.unique(tau, return_inverse=True)
        ms, Ps = self.moments(ut)
        prop = kernels.lag_propagators(self.cr, jnp.asarray(ul))
        lagged = [a[li] for a in prop]
        n = len(times)
        shape = (self.n_components, n) if X is None else (self.n_components, X.shape[1], n)
        out = np.zeros(shape)
        for c in range(self.n_components):
            args = (self.cr, ms[c][ti], Ps[c][ti], *lagged, jnp.asarray(tau))
            if X is None:
                vals = np.asarray(kernels.n2_pairs(*args))
                out[c] = np.bincount(k, weights=wts * vals, minlength=n)
            else:
                vals = np.asarray(kernels.n2_joint_pairs(*args, jnp.asarray(X[c].T)[k]))
                for ix in range(X.shape[1]):
                    out[c, ix] = np.bincount(k, weights=wts * vals[:, ix], minlength=n)
        return out

    def positions(self, entry, n_t, n_xi):
        """Positions at an upcrossing on a uniform grid of the standardised position
        xi in [-8.5, 8.5] under the Gaussian law of x given v = L, per component and grid
        time, as boxes: centres X and widths (K, n_xi, n_t). The law is narrow at short
        times (short slips stick on a thin ridge x ~ x0 + v_b t that no fixed grid
        resolves) and wide later; boxes rather than points keep histograms free of
        aliasing at any cell size."""
        ms, Ps = np.asarray(entry["ms"][:, :n_t]), np.asarray(entry["Ps"][:, :n_t])
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

    def points(self, t_end, h, order, coarse_h):
        """Boxes of n1(x, t) dx dt and K2(x, t) dx dt at the positions of every grid time.

        K2(x, t) is computed on a coarser grid, in time (`coarse_h`) and in xi
        (`_XI_COARSE` points): its profile over xi is interpolated onto the fine grid and
        scaled to K2(t) on the fine grid, so that it sums to the marginal term exactly
        (n1(x, t), which carries the thin short-slip ridge, is exact on the fine grid)."""
        entry = self.grid(t_end, h)
        n_t = int(round(t_end / h)) + 1
        t = np.arange(n_t) * h
        X, width = self.positions(entry, n_t, self.x_points)
        ms, Ps = entry["ms"][:, :n_t], entry["Ps"][:, :n_t]
        n1x = np.array(kernels.n1_joint_nodes(self.cr, ms, Ps, jnp.asarray(X)))
        n1x[:, :, 0] = 0.0
        dt_w = series.trapezoid_weights(n_t, h)
        K2x = None
        if order == 2:
            coarse = self.grid(t_end, coarse_h)
            n_c = int(round(t_end / coarse_h)) + 1
            tc = np.arange(n_c) * coarse_h
            Xc, _ = self.positions(coarse, n_c, _XI_COARSE)
            profile = self.K2(tc, Xc)  # (K, coarse xi, n_c), per unit x
            xi_c = np.linspace(-_XI_MAX, _XI_MAX, _XI_COARSE)
            xi_f = np.linspace(-_XI_MAX, _XI_MAX, self.x_points)
            K_fine = self.second_order(entry)[:, :n_t]
            K2x = np.zeros_like(n1x)
            for c in range(self.n_components):
                # per unit xi at coarse times -> fine times -> fine xi
                over_t = np.array([np.interp(t, tc, row) for row in profile[c]])
                fine = np.array([np.interp(xi_f, xi_c, col) for col in over_t.T]).T
                total = fine.sum(axis=0)
                share = np.where(total > 0, fine / np.where(total > 0, total, 1.0), 0.0)
                K2x[c] = share * K_fine[c] * dt_w
        T = np.broadcast_to(t, X.shape)
        X0 = self.x0.reshape((-1,) + (1,) * (X.ndim - 1))
        return T, X, width, n1x * width * dt_w, K2x, X0


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
        return dict(n=n, h=h, n1=n1[None], K2=K2[None])

    def second_order(self, entry):
        return entry["K2"]

    def points(self, t_end, h, order, coarse_h):
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
