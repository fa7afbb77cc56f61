r"""Exact-in-law stick detection for linear-Gaussian slip phases.

Between two grid points the slip state of a linear SDE $dX = (AX + b)dt + B\,dW$ is a
Gaussian bridge: given $X(0) = X_a$ and $X(\ell) = X_b$, $X(s)$ is Gaussian with mean
$P_s X_a + G_s X_b + q_s$ and a covariance $K_s$ that does not depend on the end states
($G_s = \Sigma_s \Phi_{\ell-s}^\top \Sigma_\ell^{-1}$, $P_s = \Phi_s - G_s \Phi_\ell$,
$q_s = c_s - G_s c_\ell$, $K_s = \Sigma_s - G_s \Phi_{\ell-s} \Sigma_s$). With a
differentiable crossing variable $v = c^\top X$ (rate $a = c^\top(AX + b)$), Rice's
formula on the bridge gives the expected number of upcrossings of the level $L$ inside
the interval,
$$E[N_\ell] = \int_0^\ell p_{v(s)}(L)\, E[a(s)^+ \mid v(s) = L]\, ds,$$
which bounds the probability that a path starting and ending below $L$ crossed in between
(the code bounds $E[a^+ \mid v = L]$ once more by $m^+ + s/\sqrt{2\pi}$, see below).

The detector (Taillefumier & Magnasco's refinement, on one coordinate of a multivariate
Gauss-Markov state):

1. every step, evaluate $E[N_h]$ for each slipping path (Gauss-Legendre, `QUADRATURE`
   nodes); a step that ends at or above $L$, or whose bound exceeds the tolerance, is a
   *candidate*;
2. a candidate step is refined, earliest half first (computed level by level over all
   candidates, which gives the same result as depth first): the bridge midpoint is
   sampled exactly (a conditional Gaussian, with noise keyed by path, step and tree node),
   a half that ends at or above $L$ holds a crossing, a half that ends below with a bound
   at or below the tolerance is certified crossing-free, any other half is split again;
3. the first half-interval at the location level that ends at or above $L$ holds the
   stick (after every earlier half-interval is certified, refining those down to the
   certification level); inside it, time and state are interpolated linearly (the interval
   is at most `LOCATE_SCALE` times the fastest time scale of $A$).

The probability that a crossing was missed is at most the sum of the bounds of the
certified intervals; the simulator reports that sum (`Ensemble.stats["miss_bound"]`).
Every coefficient depends only on the step size and the model, so it is computed once per
run, for all `MAX_DEPTH + 1` levels, as runtime arrays.
"""

from __future__ import annotations

import functools
import math

import equinox as eqx
import numpy as np

from .. import _compile, _rng
from .._jax import jax, jnp
from .._linear import propagators, propagators_host
from .._solver.exact import psd_factor, psd_pinv

QUADRATURE = 8  # Gauss-Legendre nodes of the Rice integral on one (sub-)interval
MAX_DEPTH = 20  # levels of the tables (the depths used are runtime values below it)
# Location: the stick lies in a sub-interval of the finest located level, at most this many
# times the fastest time scale 1/rho(A) long; inside it, time and state are interpolated
# linearly. The bridge's spread about that line there is ~(0.1)^1.5 of the slip's own
# scale, so the time error is below 1e-3/rho (measured effect: none at 2e5 paths).
LOCATE_SCALE = 0.1
# Certification: an interval that ends below the level but keeps a bound above the tolerance
# is split further, down to sub-intervals this many times 1/rho(A) (where the bridge
# coefficients still hold ~8 digits in float64); one still undecided there is counted as
# unresolved (`Ensemble.stats["unresolved"]`) and its bound goes into the miss bound.
CERTIFY_SCALE = 1e-5
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
_U, _W = np.polynomial.legendre.leggauss(QUADRATURE)
_U, _W = 0.5 * (_U + 1.0), 0.5 * _W  # on (0, 1)
_KNOTS = np.concatenate([[0.0], _U, [1.0]])


class BridgeTables(eqx.Module):
    """The bridge coefficients of one step size, for intervals `h / 2**j`, j = 0..MAX_DEPTH.

    The level axis (J = MAX_DEPTH + 1) is last. Midpoint: `mid_P`, `mid_G` `(d, d, J)`,
    `mid_q` `(d, J)`, `mid_L` `(d, d, J)` (a factor of the midpoint covariance). Rice
    integral at the quadrature nodes: the bridge means of the crossing variable (`v_P`, `v_G`
    `(Q, d, J)`, `v_q` `(Q, J)`) and of its rate (`a_*`), `inv_sv` (one over the standard
    deviation of v), `kappa` (regression of a on v), `s_a` (conditional standard deviation
    of a given v) and `weight` (quadrature weight times interval length), all `(Q, J)`;
    `crossing` the functional `(d, J)`, `rate` that of its rate `(d, J)` with offset
    `rate_offset` `(J,)` (the same at every level), and `length` the intervals' `(J,)`.
    """

    mid_P: jax.Array
    mid_G: jax.Array
    mid_q: jax.Array
    mid_L: jax.Array
    v_P: jax.Array
    v_G: jax.Array
    v_q: jax.Array
    a_P: jax.Array
    a_G: jax.Array
    a_q: jax.Array
    inv_sv: jax.Array
    kappa: jax.Array
    s_a: jax.Array
    weight: jax.Array
    crossing: jax.Array
    rate: jax.Array
    rate_offset: jax.Array
    length: jax.Array


def bridge_tables(A, b, B, crossing, h, host: bool = False) -> BridgeTables:
    """The `BridgeTables` of $dX = (AX + b)dt + B\\,dW$ with crossing functional `crossing`
    for the step `h`: traceable (`h` may be a runtime value), or with `host=True` computed in
    NumPy outside any trace (no compilation)."""
    xp = np if host else jnp
    J = MAX_DEPTH + 1
    lengths = h / 2.0 ** xp.arange(J)
    frac = xp.concatenate([xp.array([0.5]), xp.asarray(_U)])  # midpoint, then nodes
    s = lengths[:, None] * frac[None, :]  # (J, Q + 1)
    if host:
        A, b, B = (np.asarray(x, dtype=np.float64) for x in (A, b, B))
        prop = lambda t: propagators_host(A, b, B, t)
    else:
        vmapped = jax.vmap(lambda t: propagators(A, b, B, t))
        prop = lambda t: tuple(x.reshape(t.shape + x.shape[1:]) for x in vmapped(t.ravel()))
    Phi_l, _, c_l, S_l = prop(lengths)
    Phi_s, _, c_s, S_s = prop(s)
    Phi_r = prop(lengths[:, None] - s)[0]
    Sp = psd_pinv(S_l, xp)  # (J, d, d)
    G = S_s @ xp.swapaxes(Phi_r, -1, -2) @ Sp[:, None]
    P = Phi_s - G @ Phi_l[:, None]
    q = c_s - xp.einsum("jqik,jk->jqi", G, c_l)
    K = S_s - G @ Phi_r @ S_s
    K = 0.5 * (K + xp.swapaxes(K, -1, -2))
    cvec = xp.asarray(crossing, dtype=xp.float64)
    rvec = A.T @ cvec  # a = r.X + c.b
    ra = cvec @ b
    quad = slice(1, None)
    v_P = xp.einsum("i,jqik->jqk", cvec, P[:, quad])
    v_G = xp.einsum("i,jqik->jqk", cvec, G[:, quad])
    v_q = xp.einsum("i,jqi->jq", cvec, q[:, quad])
    a_P = xp.einsum("i,jqik->jqk", rvec, P[:, quad])
    a_G = xp.einsum("i,jqik->jqk", rvec, G[:, quad])
    a_q = xp.einsum("i,jqi->jq", rvec, q[:, quad]) + ra
    Kq = K[:, quad]
    var_v = xp.einsum("i,jqik,k->jq", cvec, Kq, cvec)
    cov = xp.einsum("i,jqik,k->jq", cvec, Kq, rvec)
    var_a = xp.einsum("i,jqik,k->jq", rvec, Kq, rvec)
    tiny = xp.finfo(xp.float64).tiny
    var_v = xp.maximum(var_v, tiny)
    s_a = xp.sqrt(xp.maximum(var_a - cov * cov / var_v, tiny))

    # Level axis last: per-path gathers need no copy.
    def last(a):
        return np.ascontiguousarray(np.moveaxis(a, 0, -1)) if host else jnp.moveaxis(a, 0, -1)

    return jax.tree_util.tree_map(
        last,
        BridgeTables(
            mid_P=P[:, 0],
            mid_G=G[:, 0],
            mid_q=q[:, 0],
            mid_L=psd_factor(K[:, 0], xp),
            v_P=v_P,
            v_G=v_G,
            v_q=v_q,
            a_P=a_P,
            a_G=a_G,
            a_q=a_q,
            inv_sv=1.0 / xp.sqrt(var_v),
            kappa=cov / var_v,
            s_a=s_a,
            weight=lengths[:, None] * xp.asarray(_W)[None, :] * xp.ones((1, QUADRATURE)),
            crossing=xp.broadcast_to(cvec, (J,) + cvec.shape),
            rate=xp.broadcast_to(rvec, (J,) + rvec.shape),
            rate_offset=xp.broadcast_to(ra, (J,)),
            length=lengths,
        ),
    )


def depth_for(A, h: float, scale: float = LOCATE_SCALE) -> int:
    """Levels of refinement for the step `h` until a sub-interval is at most `scale` times the
    fastest time scale of `A` (at least 1, at most `MAX_DEPTH`)."""
    rho = float(np.max(np.abs(np.linalg.eigvals(np.asarray(A, dtype=float)))))
    need = math.log2(max(h * rho / scale, 2.0))
    return int(min(MAX_DEPTH, max(1, math.ceil(need))))


def _rows(table):
    """Rows of a `(..., J)` table at its first level, shapes `(..., 1)`: the whole step for
    the tables of a run, or the one level of a table `_unpack` made."""
    return table[..., :1]


def _dot(M, X):
    """`sum_k M[..., k, :] * X[k, :]` for path-wise rows `M` `(..., d, n)` and `X` `(d, n)`."""
    acc = M[..., 0, :] * X[0]
    for k in range(1, X.shape[0]):
        acc = acc + M[..., k, :] * X[k]
    return acc


def crossing_value(T: BridgeTables, X):
    return _dot(T.crossing[:, :1], X)


def expected_upcrossings(T: BridgeTables, Xa, Xb, level, cheap: bool = False):
    """Rice's expected number of upcrossings of `level` by the bridge from `Xa` to `Xb`
    (each `(d, n)`) over the interval of the tables' first level.

    `cheap`: one exponential instead of one per node, with the smallest standardised gap
    at every node, so a larger value (the simulator's every-step screen: at small steps the
    exponentials were 3/4 of the cost of a step; a step it passes on is bounded exactly
    by the refinement)."""
    # One elementwise expression per quadrature node, summed in a Python loop: XLA then
    # fuses the whole bound into one pass (a (Q, n) array reduced over Q ran ~5x slower).
    rows = _rows
    vP, vG, vq, aP, aG, aq = (rows(t) for t in (T.v_P, T.v_G, T.v_q, T.a_P, T.a_G, T.a_q))
    inv_sv, kappa, s_a, w = (rows(t) for t in (T.inv_sv, T.kappa, T.s_a, T.weight))
    total = jnp.zeros(jnp.broadcast_shapes(Xa.shape[1:], Xb.shape[1:]))
    z2min = jnp.full(total.shape, jnp.inf)
    # The bridge mean of v and its slope (the mean of a) at 0, the nodes and the end, for
    # the guard below.
    c, r, ra = T.crossing[:, :1], T.rate[:, :1], T.rate_offset[:1]
    means = [(_dot(c, Xa), _dot(r, Xa) + ra)]
    for i in range(QUADRATURE):
        mv = _dot(vP[i], Xa) + _dot(vG[i], Xb) + vq[i]
        ma = _dot(aP[i], Xa) + _dot(aG[i], Xb) + aq[i]
        means.append((mv, ma))
        gap = level - mv
        z = gap * inv_sv[i]
        # E[a^+ | v = L] = E[(m + s Z)^+] <= m^+ + s E[Z^+]: an upper bound that needs no
        # normal CDF (measured 2.8x cheaper per node on the target CPU, where one exp costs
        # ~10 ns). It is tight where a rises through L and loose only where a falls, so it
        # refines a little more; the bound stays a bound, so exactness is untouched.
        e_plus = jnp.maximum(ma + kappa[i] * gap, 0.0) + s_a[i] * _INV_SQRT_2PI
        if cheap:
            z2min = jnp.minimum(z2min, z * z)
            total = total + (w[i] * _INV_SQRT_2PI) * inv_sv[i] * e_plus
        else:
            total = total + (w[i] * _INV_SQRT_2PI) * inv_sv[i] * jnp.exp(-0.5 * z * z) * e_plus
    # Guard: where the bridge mean itself may reach the level inside the interval, the
    # integrand is a peak of width ~ sd(v) / |a| that a fixed quadrature can step over
    # (measured: bound 0.003 against Rice's 1.0 for a mean that crosses up and back within
    # 0.1). Such an interval is always split (bound infinite). The mean is followed by
    # cubic Hermite pieces through the end points and the nodes, with the mean of a as
    # slope; on a piece, H(u) = line + u(1-u)[(m0 - D)(1-u) - (m1 - D)u] with D = p1 - p0,
    # so H <= max(p0, p1) + M / 4 with M = max(m0 - D, D - m1, 0): a cheap test that never
    # misses. A piece that starts at the level (the slip onset) reaches it again only if
    # H(u) - L <= u (D + (1 - u) M) can be positive, i.e. D + M > 0. The interval's own
    # end is not tested (a step that ends above is a candidate anyway).
    means.append((_dot(c, Xb), _dot(r, Xb) + ra))
    length = rows(T.length)[0]
    reach = jnp.zeros(total.shape, dtype=bool)
    for k in range(QUADRATURE + 1):
        (p0, m0), (p1, m1) = means[k], means[k + 1]
        piece = length * (_KNOTS[k + 1] - _KNOTS[k])
        rise = p1 - p0
        bulge = jnp.maximum(jnp.maximum(piece * m0 - rise, rise - piece * m1), 0.0)
        top = p0 if k == QUADRATURE else jnp.maximum(p0, p1)
        hit = top + 0.25 * bulge >= level
        if k == 0:
            hit = jnp.where(p0 >= level, rise + bulge > 0.0, hit)
        reach = reach | hit
    if cheap:
        total = total * jnp.exp(-0.5 * z2min)
    return jnp.where(reach, jnp.inf, total)


def midpoint(T: BridgeTables, Xa, Xb, z):
    """A draw of the bridge at the middle of the interval of the tables' first level."""
    return (
        _dot(_rows(T.mid_P), Xa)
        + _dot(_rows(T.mid_G), Xb)
        + _rows(T.mid_q)
        + _dot(_rows(T.mid_L), z)
    )


def level_tables(T: BridgeTables):
    """Every level's tables packed into one array `(MAX_DEPTH + 1, K)` (one argument per
    refinement pass instead of thirty), with the structure to unpack a row."""
    leaves, treedef = jax.tree_util.tree_flatten(T)
    shapes = tuple(leaf.shape[:-1] for leaf in leaves)
    rows = np.concatenate([np.reshape(leaf, (-1, leaf.shape[-1])) for leaf in leaves], axis=0).T
    return rows, (treedef, shapes)


def _unpack(rows, j, layout):
    """The tables of level `j` (arrays `(..., 1)`) from `level_tables`' packed rows."""
    treedef, shapes = layout
    row = rows[j]
    out, start = [], 0
    for shape in shapes:
        size = math.prod(shape)
        out.append(row[start : start + size].reshape(shape + (1,)))
        start += size
    return jax.tree_util.tree_unflatten(treedef, out)


def _split(rows, j, level, ends, ids, key, layout):
    """Split intervals of level `j` at their midpoints. `ends` stacks the states at both ends
    `(2d, n)`; `ids` the path, step and tree node `(3, n)`, which key the exact bridge draw
    at the midpoint. Returns one array `(d + 4, n)`: the midpoint state, whether each half
    ends at or above `level` (as 0/1) and each half's bound on an upcrossing inside it."""
    d = ends.shape[0] // 2
    Xa, Xb = ends[:d], ends[d:]
    T_parent, T_child = _unpack(rows, j, layout), _unpack(rows, j + 1, layout)
    z = _rng.tree_normals(key, ids[0], ids[1], ids[2], d)
    # Materialise the draw once: XLA would otherwise re-derive it (three Threefry hashes)
    # inside each of its consumers.
    Xm = jax.lax.optimization_barrier(midpoint(T_parent, Xa, Xb, z))
    left_above = crossing_value(T_parent, Xm) >= level
    right_above = crossing_value(T_parent, Xb) >= level
    p_left = expected_upcrossings(T_child, Xa, Xm, level)
    p_right = expected_upcrossings(T_child, Xm, Xb, level)
    flags = jnp.stack([left_above, right_above]).astype(Xm.dtype)
    return jnp.concatenate([Xm, flags, p_left[None], p_right[None]])


class Splitter:
    """`_split` for one run's tables, level and key. A refinement makes a few hundred small
    calls, so each padded size's executable is called directly (the generic call's Python
    overhead, ~0.5 ms, exceeded their run time); it is traced once for every size
    (`_compile`, path axis symbolic). Arguments and results are packed for the same reason."""

    def __init__(self, tables: BridgeTables, level, key, timer=None):
        rows, self.layout = level_tables(tables)
        self.rows = np.asarray(rows)
        self.level = np.asarray(level, dtype=np.float64)
        self.key = np.asarray(key, dtype=np.uint32)
        self.crossing = np.asarray(tables.crossing[:, 0])
        self.sizes: dict = {}
        self.timer = timer

    def __call__(self, j: int, ends, ids):
        args = (self.rows, np.asarray(j, dtype=np.int32), self.level, ends, ids, self.key)
        size = ends.shape[-1]
        if size not in self.sizes:
            compiled, flat, _ = _compile.executable(
                _split, *args, self.layout, timer=self.timer, paths=size
            )
            self.sizes[size] = compiled if flat else functools.partial(_tail, compiled, self.layout)
        return np.asarray(self.sizes[size](*args))


def _tail(compiled, layout, *args):
    return compiled(*args, layout)


def first_crossing(splitter, level, depths, tol, Xa, Xb, path, step):
    """Refine candidate steps and find each one's first crossing of `level`.

    Breadth first, one level of the dyadic tree at a time, so that every pass uses one
    level's coefficients and only the open intervals (compacted) are computed. At each
    level an interval is split at its exact bridge midpoint; a half that ends at or above
    the level holds a crossing; a half that ends below is certified crossing-free when its
    bound is at most `tol`, and is undecided otherwise. Halves after a path's first half
    that ends above are dropped: the first crossing comes before their start. Down to the
    location depth both kinds are split again; past it only the undecided halves before
    the located one are (down to the certification depth), and a crossing found there
    replaces the location (it is earlier). The result does not depend on the order of
    exploration: it is what the depth-first refinement of the module docstring finds with
    the same draws.

    `splitter` is the run's `Splitter`; `depths` `(locate, certify)`; `Xa`, `Xb` `(d, n)`,
    `path`, `step` `(n,)` host arrays.

    **Returns:** `(found, frac, state, miss, unresolved, intervals)` per candidate: whether
    it crossed inside the step, where (fraction of the step), the state there (linear
    interpolation inside the finest interval), the summed bounds of the certified
    intervals before the crossing, whether an interval stayed undecided at the
    certification depth (certified all the same), and the number of intervals split.
    """
    d, n = Xa.shape
    level = float(level)  # a host number: the bookkeeping below is NumPy
    locate_depth, certify_depth = depths
    found = np.zeros(n, dtype=bool)
    frac = np.ones(n)
    state = np.array(Xb, dtype=float, copy=True)
    miss = np.zeros(n)
    unresolved = np.zeros(n, dtype=bool)
    owner = np.arange(n)
    a, b = np.asarray(Xa, float), np.asarray(Xb, float)
    pos = np.zeros(n, dtype=np.int64)
    splits = 0
    cvec = splitter.crossing
    path, step = np.asarray(path, np.uint32), np.asarray(step, np.uint32)
    for j in range(certify_depth):
        m = owner.size
        if m == 0:
            break
        splits += m
        node = ((np.uint64(1) << np.uint64(j)) + pos.astype(np.uint64)).astype(np.uint32)
        ends = np.concatenate([a, b])
        ids = np.stack([path[owner], step[owner], node])
        out = np.concatenate(
            [
                splitter(j, _pad(ends[:, k : k + size], pad), _pad(ids[:, k : k + size], pad))
                for k, size, pad in _pieces(m)
            ],
            axis=1,
        )[:, :m]
        Xm = out[:d]
        # Children in time order, child 2i + r the left (r = 0) or right half of interval i;
        # each path's children are contiguous.
        c_owner = np.repeat(owner, 2)
        c_above = (out[d : d + 2] > 0.5).T.ravel()
        c_p = out[d + 2 : d + 4].T.ravel()
        # Keep each path's children up to and including its first one that ends above.
        starts = np.empty(2 * m, dtype=bool)
        starts[0] = True
        np.not_equal(c_owner[1:], c_owner[:-1], out=starts[1:])
        cum = np.cumsum(c_above) - c_above  # above-children strictly before each child
        group_start = np.maximum.accumulate(np.where(starts, np.arange(2 * m), 0))
        keep = cum == cum[group_start]
        below = keep & ~c_above
        certified = below & (c_p <= tol)
        miss += np.bincount(c_owner[certified], weights=c_p[certified], minlength=n)
        undecided = below & ~certified
        hit = keep & c_above
        last_level = j + 1 == certify_depth
        if j + 1 >= locate_depth:
            # Locate (or, past the location depth, move the location earlier). A half that
            # starts at the level (the slip onset, v(0) = L, a(0) < 0) holds a return to it
            # somewhere inside: it is split on to the last level and placed at its middle,
            # so that the slip time stays positive.
            ch = np.nonzero(hit)[0]
            ha, hb = _child_ends(ch, a, b, Xm)
            ca, cb = cvec @ ha, cvec @ hb
            onset = ca >= level
            f = np.clip((level - ca) / np.where(cb > ca, cb - ca, 1.0), 0.0, 1.0)
            f = np.where(onset, 0.5, f)
            now = ~onset | last_level
            ch, f, ha, hb = ch[now], f[now], ha[:, now], hb[:, now]
            who = c_owner[ch]
            found[who] = True
            frac[who] = (2 * pos[ch >> 1] + (ch & 1) + f) / 2.0 ** (j + 1)
            state[:, who] = ha + f * (hb - ha)
            open_ = undecided.copy()
            open_[np.nonzero(hit)[0][~now]] = True
        else:
            open_ = undecided | hit
        if last_level:
            last = np.bincount(
                c_owner[undecided], weights=np.minimum(c_p[undecided], 1.0), minlength=n
            )
            miss += last
            unresolved |= last > 0
        co = np.nonzero(open_)[0]
        a, b = _child_ends(co, a, b, Xm)
        owner, pos = c_owner[co], 2 * pos[co >> 1] + (co & 1)
    return found, frac, state, miss, unresolved, splits


def _child_ends(children, a, b, Xm):
    """End states of children `2i + r` of intervals `(a_i, b_i)` split at `Xm_i`."""
    parent, right = children >> 1, (children & 1).astype(bool)
    return (
        np.where(right, Xm[:, parent], a[:, parent]),
        np.where(right, b[:, parent], Xm[:, parent]),
    )


_BUCKETS = (256, 1024, 4096, 16384, 65536)  # the padded sizes of a pass (compiled once each)


def _pieces(m: int):
    """`(start, size, pad)` of the calls that cover `m` intervals: whole largest buckets,
    then the rest padded to the smallest bucket that holds it (few compiled shapes; the
    padding of a small pass costs little)."""
    top = _BUCKETS[-1]
    for start in range(0, m - m % top, top):
        yield start, top, 0
    rest = m % top
    if rest:
        bucket = next(b for b in _BUCKETS if b >= rest)
        yield m - rest, rest, bucket - rest


def _pad(a, pad):
    a = np.asarray(a)
    if pad == 0:
        return a
    return np.concatenate([a, np.repeat(a[..., :1], pad, axis=-1)], axis=-1)
