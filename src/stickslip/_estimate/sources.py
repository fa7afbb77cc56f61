"""Where the upcrossing densities come from: closed-form Gaussian formulas, or a record of
simulated upcrossings. Both give, on a uniform time grid t_k = k h, per component:

- `n1` (K, n) and `K2` (K, n), with K2(t) = int_0^t n2(t, s) ds (the density of an
  upcrossing at t times the expected number of earlier ones);
- point masses of the position-resolved densities: positions `X` (K, P), times `T` (K, P),
  and the weights of n1(x, t) dx dt and of K2(x, t) dx dt at those points,

and the component weights `w` (K,) (their sum is the probability that the slip has
non-zero length) and onset positions `x0` (K,).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from .._jax import jnp
from .._linear import stationary
from . import gaussian as G
from . import kernels, series

_FIRST_PANEL = 1e-6  # the innermost panels: their share of the integral is negligible
_GL_NODES = 8  # Gauss-Legendre nodes per panel


def _graded(length):
    """Panel edges 0, p, 2p, 4p, ... up to `length` (geometric grading from 0)."""
    n = max(1, int(math.ceil(math.log2(max(length, _FIRST_PANEL) / _FIRST_PANEL))) + 1)
    edges = np.minimum(np.concatenate([[0.0], _FIRST_PANEL * 2.0 ** np.arange(n)]), length)
    return edges[np.concatenate([[True], np.diff(edges) > 0])]


def lag_rule(t):
    """Quadrature over the lag tau in (0, t] for int_0^t n2(t, t - tau) dtau.

    Gauss-Legendre on panels graded geometrically towards both ends: towards tau = 0, where
    n2 varies on the noise's correlation time (with a sqrt(tau) cusp, or the closure's
    integrable tau^-1/2 singularity), and towards the onset s = t - tau = 0, where the first
    upcrossings cluster. Returns (tau, weight) arrays."""
    if t <= 0:
        return np.zeros(0), np.zeros(0)
    half = _graded(0.5 * t)
    edges = np.unique(np.concatenate([half, t - half]))
    x, w = np.polynomial.legendre.leggauss(_GL_NODES)
    a, b = edges[:-1, None], edges[1:, None]
    tau = (0.5 * (b - a) * (x + 1.0) + a).ravel()
    weight = (0.5 * (b - a) * w).ravel()
    return tau, weight


class GaussianSource:
    """Closed-form densities of a linear-Gaussian slip (see `gaussian.py`)."""

    def __init__(self, cr, m0, P0, *, exact, quadrature_nodes, x_points):
        self.cr, self.exact, self.x_points = cr, exact, x_points
        A, b = np.asarray(cr.A), np.asarray(cr.b)
        g, p = np.asarray(cr.g), np.asarray(cr.p)
        self._g, self._p, self.level = g, p, float(cr.level)
        h = A.T @ g
        mu = float(h @ m0 + g @ b)
        var = float(h @ P0 @ h)
        if var <= 0.0 or not exact:
            # A sharp onset (or the closure, which has no finite a(0)): one component; the
            # slip is immediate when the crossing variable is already rising.
            self.immediate_probability = 1.0 if (exact and mu >= 0.0) else 0.0
            self.m0s, self.P0s = m0[None], P0[None]
            self.w = np.array([1.0 - self.immediate_probability])
        else:
            # Quadrature over the initial rate a(0) < 0, uniform in its distribution function.
            sd = math.sqrt(var)
            p_slip = float(special.ndtr(-mu / sd))
            self.immediate_probability = 1.0 - p_slip
            x, wq = np.polynomial.legendre.leggauss(quadrature_nodes)
            a0 = mu + sd * special.ndtri(0.5 * (x + 1.0) * p_slip)
            k = P0 @ h / var
            self.m0s = m0[None] + np.outer(a0 - mu, k)
            P_cond = P0 - np.outer(k, h @ P0)
            self.P0s = np.repeat(0.5 * (P_cond + P_cond.T)[None], a0.size, axis=0)
            self.w = 0.5 * wq * p_slip
        self.x0 = self.m0s @ p
        self._grids: dict = {}

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

    def nodes(self, entry, n_t):
        """Gauss-Hermite nodes of the position at an upcrossing, per component and grid
        time, from the Gaussian law of x given v = L; its width shrinks to nothing as t -> 0
        (short slips stick on a thin ridge x ~ x0 + v_b t that no fixed grid resolves).
        Returns positions and cell widths, shape (K, J, n_t)."""
        ms, Ps = np.asarray(entry["ms"][:, :n_t]), np.asarray(entry["Ps"][:, :n_t])
        g, p = self._g, self._p
        svv = np.einsum("i,knij,j->kn", g, Ps, g)
        sxv = np.einsum("i,knij,j->kn", p, Ps, g)
        sxx = np.einsum("i,knij,j->kn", p, Ps, p)
        ok = svv > 0
        ratio = np.where(ok, sxv / np.where(ok, svv, 1.0), 0.0)
        mu = ms @ p + ratio * (self.level - ms @ g)
        sd = np.sqrt(np.maximum(sxx - ratio * sxv, 0.0))
        xi, wt = np.polynomial.hermite.hermgauss(self.x_points)
        X = mu[:, None, :] + math.sqrt(2.0) * sd[:, None, :] * xi[None, :, None]
        width = math.sqrt(2.0) * sd[:, None, :] * (wt * np.exp(xi**2))[None, :, None]
        return X, width

    def points(self, t_end, h, order, coarse_h):
        """Point masses of n1(x, t) dx dt and K2(x, t) dx dt at the position nodes of every
        grid time. The second-order K2(x, t) is computed on a coarser grid and interpolated
        in t at fixed standardised node (it varies slowly; n1(x, t), which carries the thin
        short-slip ridge, is exact on the fine grid)."""
        entry = self.grid(t_end, h)
        n_t = int(round(t_end / h)) + 1
        t = np.arange(n_t) * h
        X, width = self.nodes(entry, n_t)
        n1x = np.array(
            kernels.n1_joint_nodes(
                self.cr, entry["ms"][:, :n_t], entry["Ps"][:, :n_t], jnp.asarray(X)
            )
        )
        n1x[:, :, 0] = 0.0
        dt_w = series.trapezoid_weights(n_t, h)
        K2x = None
        if order == 2:
            coarse = self.grid(t_end, coarse_h)
            n_c = int(round(t_end / coarse_h)) + 1
            Xc, wc = self.nodes(coarse, n_c)
            tc = np.arange(n_c) * coarse_h
            # Interpolate in t each node's fraction of K2 (density times cell width, over
            # their sum) and scale it by K2(t) on the fine grid: the position-resolved term
            # then sums to the marginal one exactly. (The density itself scales like
            # 1 / width, which changes fast at short times.)
            share = self.K2(tc, Xc) * wc
            total = share.sum(axis=1, keepdims=True)
            frac = np.where(total > 0, share / np.where(total > 0, total, 1.0), 1.0 / X.shape[1])
            frac = np.array([[np.interp(t, tc, row) for row in fc] for fc in frac])
            frac /= np.maximum(frac.sum(axis=1, keepdims=True), 1e-300)
            K_fine = self.second_order(entry)[:, :n_t]
            K2x = frac * K_fine[:, None, :] * dt_w
        T = np.broadcast_to(t, X.shape)
        return T, X, n1x * width * dt_w, K2x


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
        self.x0 = np.array([float(np.mean(u.onset_position[slip])) if slip.any() else 0.0])
        times, pos = u.times[slip], u.positions[slip]
        self.n_slip = max(int(slip.sum()), 1)
        index = np.broadcast_to(np.arange(times.shape[1]), times.shape)
        ok = np.isfinite(times)
        self.t, self.x, self.index = times[ok], pos[ok], index[ok].astype(float)
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
        return self.t[keep][None], self.x[keep][None], w[None], K2
