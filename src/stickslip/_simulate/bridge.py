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

import collections
import contextlib
import functools
import math
import os
import threading
import time

import equinox as eqx
import numpy as np

from .. import _background, _compile, _rng
from .._jax import jax, jnp, materialised
from .._linear import propagators, propagators_host
from .._solver.exact import psd_factor, psd_pinv

QUADRATURE = 8  # Gauss-Legendre nodes of the Rice integral on one (sub-)interval
MAX_DEPTH = 20  # levels of the tables (the depths used are runtime values below it)
# Location: the stick lies in a sub-interval of the finest located level, at most this many
# times the fastest time scale 1/rho(A) long; inside it, time and state are interpolated
# linearly. Measured against locating 16 times finer (same draws, public set, 1e5 paths, dt
# 0.2 and 0.8): slip-time error rms 3.7e-4 = 0.004/rho, mean 5e-6, largest 5.4e-3; slip
# distance rms 3.7e-4. (Each level deeper costs about one split per path.)
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


def _at(x, k: int, axis: int = 0):
    """`x`'s entry `k` (static) along `axis`, by a slice: the same values as `x[k]`, whose
    general indexing took ~1 ms a use to trace (the bounds below index hundreds of times:
    a second of every first run's tracing)."""
    if isinstance(x, np.ndarray):
        return np.take(x, k, axis)
    return jax.lax.index_in_dim(x, k, axis % x.ndim, keepdims=False)


def _dot(M, X):
    """`sum_k M[..., k, :] * X[k, :]` for path-wise rows `M` `(..., d, n)` and `X` `(d, n)`."""
    acc = _at(M, 0, -2) * _at(X, 0)
    for k in range(1, X.shape[0]):
        acc = acc + _at(M, k, -2) * _at(X, k)
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
        mv = _dot(_at(vP, i), Xa) + _dot(_at(vG, i), Xb) + _at(vq, i)
        ma = _dot(_at(aP, i), Xa) + _dot(_at(aG, i), Xb) + _at(aq, i)
        means.append((mv, ma))
        gap = level - mv
        inv_sv_i, w_i = _at(inv_sv, i), _at(w, i)
        z = gap * inv_sv_i
        # E[a^+ | v = L] = E[(m + s Z)^+] <= m^+ + s E[Z^+]: an upper bound that needs no
        # normal CDF (measured 2.8x cheaper per node on the target CPU, where one exp costs
        # ~10 ns). It is tight where a rises through L and loose only where a falls, so it
        # refines a little more; the bound stays a bound, so exactness is untouched.
        e_plus = jnp.maximum(ma + _at(kappa, i) * gap, 0.0) + _at(s_a, i) * _INV_SQRT_2PI
        if cheap:
            z2min = jnp.minimum(z2min, z * z)
            total = total + (w_i * _INV_SQRT_2PI) * inv_sv_i * e_plus
        else:
            total = total + (w_i * _INV_SQRT_2PI) * inv_sv_i * _exp32(-0.5 * z * z) * e_plus
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
    length = _at(rows(T.length), 0)
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


def _exp32(x):
    """`exp(x)` for `x <= 0` evaluated in float32: a relative error below 1e-6, ample for a
    bound compared with a tolerance, and 0 below exp(-103), where a term cannot matter
    (XLA's float64 exponentials were a sixth of the refinement's time; measured 7 % faster
    on 2 cores, the same refinements to the last bit on the public set)."""
    return jnp.exp(x.astype(jnp.float32)).astype(jnp.float64)


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


# Status of a refinement call (`refine_levels`).
GO, DONE, SHRINK, GROW = 0, 1, 2, 3
# Interval buffers of a refinement call. Each is a compilation (about 2 s on 2 cores), so the
# small ones, where a pass costs little whatever its size, are few (1024 holds the tails of
# small batches: without it those passes ran at 0.18 occupancy in 4096, 5 % of a run; a
# 2048 too gained nothing measurable); the large ones are close, since a pass costs in
# proportion to its buffer, not to its open intervals. Above 32768 a pass leaves the cache
# (measured 1.5x the cost per interval).
CAPACITIES = (256, 1024, 4096, 8192, 16384, 24576, 32768)
# Candidates refined together: their open intervals grow by up to ~1.2x over the first
# levels (measured at dt = 1.6 on the public set), so a batch fits the largest buffer.
BATCH = 26000
HEADROOM = 1.25  # a buffer is chosen for this many times its open intervals
# A first run's refinement buffer (`Refiner.prefetch`): later rounds refine a few candidates
# each, and every pass costs its whole buffer (on 32768 a first run's 33 small refinements
# took 0.84 s, 25 ms each, where 256 takes 1.4 ms); on this one they cost ~3 ms, and the
# large first round runs in batches of its size.
COLD_CAPACITY = 4096


def refine_levels(
    rows_t, j0, depths, level, tol, key, shrink_at, keyed, a, b, owner, pos, k0, k1, count, layout
):
    """Refine the open intervals of one tree level after another, inside one compiled call.

    The intervals are the first `count` columns of a buffer of capacity `C` (the last axis):
    end states `a`, `b` `(d, C)`, `owner` (the candidate each belongs to, `< C`; an owner's
    intervals are contiguous and in time order), position `pos` in their level, and the
    key words of their candidate's tree (`_rng.candidate_key`; `keyed` 0: the buffer holds
    the candidate's path and step counters instead, hashed here once). A pass splits every
    interval at its exact bridge midpoint (noise keyed by path, step and tree node, through
    the candidate's key), decides each half as
    `Refiner.first_crossing` describes, and compacts the halves still open into the buffer,
    in order. Passes run from level `j0` while at least `shrink_at` intervals are open. The
    call returns to the host when the refinement is done (`DONE`), when fewer are open
    (`SHRINK`: a smaller buffer is cheaper), or when the next level would
    overflow the buffer (`GROW`: that level is left undone). It returns the buffer and,
    per owner, what its passes found: `found`, `frac` (fraction of the step), `state`,
    `unresolved` and the summed bounds of its certified halves (`miss`); and the number of
    intervals split.

    The two halves of every interval are kept as two planes, left and right, never
    interleaved: XLA evaluated both operands of an interleaving for every element (measured
    1.8x the cost of the bounds)."""
    d, C = a.shape
    rows = rows_t.T
    locate, certify = depths[0], depths[1]
    slots = jnp.arange(C, dtype=jnp.int32)

    # The bridge noise of the midpoints must be materialised once: XLA re-derived a draw
    # (Threefry hashes and the inverse error function) inside each of its consumers. On a
    # CPU a pass draws it in a branch of its own; elsewhere (a branch in the loop waits for
    # the host) it is drawn a level ahead and carried, as everywhere before 2026-11-30,
    # which compiles its code twice, before the loop and inside it (on a CPU: 74 kernels,
    # 1.12 MB of LLVM IR at capacity 4096, against 71 and 1.01 MB in a branch; compiled
    # alone in 2.72-2.88 s then, 2.37-2.78 s now). The same draws either way.
    carried = jax.default_backend() != "cpu"

    def draw(j, pos, k0, k1):
        # The noise of the midpoints of level j, keyed by path, step and tree node.
        node = (jnp.left_shift(1, j) + pos).astype(jnp.uint32)
        return _rng.node_normals((k0, k1), node, d)

    def one_level(carry):
        j, a, b, owner, pos, k0, k1, count = carry[:8]
        found, frac, state, miss, unres, splits, z = carry[8:-1]
        Tp, Tc = _unpack(rows, j, layout), _unpack(rows, j + 1, layout)
        valid = slots < count
        if not carried:
            z = materialised(lambda: draw(j, pos, k0, k1), count >= 0)
        Xm = midpoint(Tp, a, b, z)
        va, vm, vb = crossing_value(Tp, a), crossing_value(Tp, Xm), crossing_value(Tp, b)
        # Each half: ends above the level, bound on an upcrossing inside (l: left, r: right).
        above_l, above_r = valid & (vm >= level), valid & (vb >= level)
        # The bounds are computed in a branch of their own so that they are materialised once
        # (XLA re-derived them inside each consumer; an optimization barrier did not stop it),
        # both halves by one expression over a stacked axis: one copy of the quadrature's
        # code to compile instead of two, element for element the same arithmetic. (The
        # stacked array leaves the branch whole: halves sliced inside it were fused again,
        # each with a copy of the quadrature.)
        p_l, p_r = materialised(
            lambda: jax.vmap(lambda u, w: expected_upcrossings(Tc, u, w, level))(
                jnp.stack([a, Xm]), jnp.stack([Xm, b])
            ),
            count >= 0,
        )
        # Keep each owner's halves up to and including its first one that ends above (halves
        # in time order: 2i + r).
        idx = jnp.where(valid, owner, C)
        never = 2 * C
        first = jnp.full(C, never, jnp.int32)
        first = first.at[idx].min(jnp.where(above_l, 2 * slots, never), mode="drop")
        first = first.at[idx].min(jnp.where(above_r, 2 * slots + 1, never), mode="drop")
        first = first[jnp.minimum(idx, C - 1)]
        keep_l, keep_r = valid & (2 * slots <= first), valid & (2 * slots + 1 <= first)
        cert_l = keep_l & ~above_l & (p_l <= tol)
        cert_r = keep_r & ~above_r & (p_r <= tol)
        und_l, und_r = keep_l & ~above_l & ~cert_l, keep_r & ~above_r & ~cert_r
        hit_l, hit_r = keep_l & above_l, keep_r & above_r
        last_level = j + 1 == certify
        # Locate (past the location depth: move the location earlier). A half that starts at
        # the level (the slip onset, v(0) = L, a(0) < 0) holds a return to it somewhere
        # inside: it is split on to the last level and placed at its middle, so that the slip
        # time stays positive.
        onset_l, onset_r = va >= level, vm >= level
        locating = j + 1 >= locate
        now_l = hit_l & locating & (~onset_l | last_level)
        now_r = hit_r & locating & (~onset_r | last_level)

        def place(found, frac, state):
            # Each owner's located half, if any (at most one: its first that ends above).
            pick = jnp.full(C, -1, jnp.int32)
            pick = pick.at[jnp.where(now_l, owner, C)].set(2 * slots, mode="drop")
            pick = pick.at[jnp.where(now_r, owner, C)].set(2 * slots + 1, mode="drop")
            has, i, r = pick >= 0, jnp.maximum(pick, 0) >> 1, (pick & 1).astype(bool)
            X0 = jnp.where(r, Xm[:, i], a[:, i])
            X1 = jnp.where(r, b[:, i], Xm[:, i])
            c0, c1 = jnp.where(r, vm[i], va[i]), jnp.where(r, vb[i], vm[i])
            f = jnp.clip((level - c0) / jnp.where(c1 > c0, c1 - c0, 1.0), 0.0, 1.0)
            f = jnp.where(jnp.where(r, onset_r[i], onset_l[i]), 0.5, f)
            at = jnp.ldexp(2 * pos[i] + r + f, -(j + 1))
            return found | has, jnp.where(has, at, frac), jnp.where(has, X0 + f * (X1 - X0), state)

        found, frac, state = jax.lax.cond(locating, place, lambda *x: x, found, frac, state)

        # Certified halves add their bounds to the miss bound; at the last level, so do the
        # halves left undecided (at most 1 each), and their owner is unresolved.
        def added(cert, und, p):
            return jnp.where(cert, p, jnp.where(und & last_level, jnp.minimum(p, 1.0), 0.0))

        add = added(cert_l, und_l, p_l) + added(cert_r, und_r, p_r)
        miss = miss.at[idx].add(add, mode="drop")

        def unresolved(unres):
            left_over = (und_l | und_r).astype(jnp.int32)
            return unres | (jnp.zeros(C, jnp.int32).at[idx].add(left_over, mode="drop") > 0)

        unres = jax.lax.cond(last_level, unresolved, lambda u: u, unres)
        # Compact the halves still open into the buffer, in time order.
        open_l, open_r = und_l | (hit_l & ~now_l), und_r | (hit_r & ~now_r)
        n_open = open_l.astype(jnp.int32) + open_r
        before = jnp.cumsum(n_open, dtype=jnp.int32) - n_open
        total = jnp.sum(n_open, dtype=jnp.int32)
        # Compaction by gathers: each slot of the new buffer is told which half it takes (one
        # scatter of an index; transposing the halves' columns for one scatter cost 4x more).
        src = jnp.zeros(C, jnp.int32)
        src = src.at[jnp.where(open_l, before, C)].set(2 * slots, mode="drop")
        src = src.at[jnp.where(open_r, before + open_l, C)].set(2 * slots + 1, mode="drop")
        i, r = src >> 1, (src & 1).astype(bool)
        Xm_i = Xm[:, i]
        a_ = jnp.where(r, Xm_i, a[:, i])
        b_ = jnp.where(r, b[:, i], Xm_i)
        owner_, k0_, k1_, pos_ = owner[i], k0[i], k1[i], 2 * pos[i] + r
        new = (
            j + 1, a_, b_, owner_, pos_, k0_, k1_, total,
            found, frac, state, miss, unres, splits + count,
            draw(j + 1, pos_, k0_, k1_) if carried else (),
        )  # fmt: skip
        status = jnp.where(
            (j + 1 >= certify) | (total == 0),
            DONE,
            jnp.where(total < shrink_at, SHRINK, GO),
        )
        grow = total > C
        kept = jax.tree_util.tree_map(lambda n, o: jnp.where(grow, o, n), new, carry[:-1])
        return kept + (jnp.where(grow, GROW, status),)

    zeros = jnp.zeros(C)
    k0, k1 = jax.lax.cond(keyed > 0, lambda: (k0, k1), lambda: _rng.candidate_key(key, k0, k1))
    init = (
        j0, a, b, owner, pos, k0, k1, count,
        jnp.zeros(C, bool), zeros, jnp.zeros_like(a), zeros, jnp.zeros(C, bool),
        jnp.zeros((), count.dtype), draw(j0, pos, k0, k1) if carried else (), jnp.asarray(GO),
    )  # fmt: skip
    out = jax.lax.while_loop(lambda c: c[-1] == GO, one_level, init)
    return out[:-2] + out[-1:]  # (the carried noise, if any, stays inside)


_PACKED: collections.OrderedDict = collections.OrderedDict()  # `packed`, by tables


def packed(tables: BridgeTables):
    """`level_tables(tables)`, transposed `(K, J)` (J is never a capacity) and on the device,
    with its layout: kept for the tables of the last few runs (the simulator's solver, and
    with it its tables, is one object for the runs of one model and step; ~0.5 ms a run)."""
    with _PACKED_LOCK:
        entry = _PACKED.get(id(tables))
        if entry is not None and entry[0] is tables:
            _PACKED.move_to_end(id(tables))
            return entry[1:]
        rows, layout = level_tables(tables)
        entry = _PACKED[id(tables)] = (
            tables, jax.device_put(np.ascontiguousarray(np.asarray(rows, np.float64).T)), layout
        )  # fmt: skip
        while len(_PACKED) > 8:
            _PACKED.popitem(last=False)
        return entry[1:]


_PACKED_LOCK = threading.Lock()


def _capacity(n: int) -> int:
    """The interval buffer for `n` open intervals (the smallest of `CAPACITIES` that holds
    them, or a power of two above)."""
    n = math.ceil(n)
    for C in CAPACITIES:
        if C >= n:
            return C
    return 1 << (n - 1).bit_length()


def _shrink_at(C: int) -> int:
    """Open intervals below which a call with buffer `C` hands back for a smaller one."""
    smaller = [c for c in CAPACITIES if c < C]
    return int(smaller[-1] / HEADROOM) if smaller else 0


@functools.cache
def _threads() -> int:
    """Threads for the refinement: 2 on a CPU with 2 cores or more (measured there), 1 on
    one core or on an accelerator (one call keeps it busy). The cores are those the process
    may use (its affinity: a batch job's share of a node), where the system says."""
    cpu = jax.default_backend() == "cpu"
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # (not Linux)
        cores = os.cpu_count() or 1
    return 2 if cpu and cores >= 2 else 1


POOL_THREADS = "stickslip-refine"  # the names of the refinement pool's threads begin so


@functools.cache
def _pool():
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(2, thread_name_prefix=POOL_THREADS)


# A forked child has none of the parent's threads: it makes a pool of its own.
os.register_at_fork(after_in_child=_pool.cache_clear)


class Refiner:
    """The exact refinement of one run (its tables, level, tolerance, depths and key):
    `first_crossing` on the host, `refine_levels` compiled once per buffer capacity (traced
    once for all of them, `_compile`, path axis symbolic)."""

    def __init__(self, tables: BridgeTables, level, key, depths, tol, timer=None):
        rows_t, self.layout = packed(tables)
        # The arguments every call shares, on the device once (not copied at every call; the
        # tables of a model and step, and the small values, kept across runs by content).
        self.fixed = (rows_t,) + tuple(
            _compile.on_device(np.asarray(x, dtype))
            for x, dtype in (
                (depths, np.int32), (level, np.float64), (tol, np.float64), (key, np.uint32),
            )
        )  # fmt: skip
        self.timer = timer
        self.sizes: dict = {}
        self._lock = threading.Lock()
        self._prefetch = None  # the thread compiling the first buffer (`prefetch`)

    def prefetch(self, n: int, d: int, exact: bool = True) -> None:
        """Start compiling, in a thread, the buffer that the first refinement of `n`
        candidates at most will want (cut into batches; `exact`: about `n`, else a loose
        bound), unless it is compiled already.
        A first run then compiles it while the stepping loop is compiled and runs (XLA
        compiles without Python's lock): on 2 cores the two compilations overlap. Nothing
        changes but when it is compiled."""
        if self._prefetch is not None or self.sizes:
            return
        parts = 2 if n >= 2 * CAPACITIES[1] and _threads() >= 2 else 1
        C = _capacity(min(BATCH, -(-n // parts)))
        if self._ready(C, d):
            return
        if _compile.policy() != "eager":
            C = min(C, COLD_CAPACITY)
            if any(self._ready(c, d) for c in CAPACITIES if C < c <= COLD_CAPACITY):
                return  # a larger capacity at hand stands in (`_choose`): nothing to compile
            if any(self._ready(c, d) for c in CAPACITIES if c < C <= _compile.STAND_IN * c):
                return  # a smaller one at hand takes smaller batches (`_batch`)
        elif not exact:
            return  # (a loose bound: an eager run compiles what it meets)

        def build():
            with contextlib.suppress(Exception):  # (the call compiles it then, and says why)
                self._ready(C, d, build=True)

        self._prefetch = threading.Thread(target=build, name="stickslip-prefetch", daemon=True)
        self._prefetch.start()

    def _joined(self) -> None:
        """Wait for the prefetching thread, if any (its time is the run's compile time)."""
        thread = self._prefetch
        if thread is not None and thread.is_alive():
            start = time.perf_counter()
            thread.join()
            if self.timer is not None:
                self.timer.compile_seconds += time.perf_counter() - start

    def _args(self, j, keyed, a, b, owner, pos, k0, k1, count, want=None):
        rows_t, depths, level, tol, key = self.fixed
        C = a.shape[-1] if want is None else want
        return (
            rows_t, np.asarray(j, np.int32), depths, level, tol, key,
            np.asarray(_shrink_at(C), np.int32), np.asarray(keyed, np.int32),
            a, b, owner, pos, k0, k1,
            np.asarray(count, np.int32),
        )  # fmt: skip

    def _choose(self, want: int, d: int) -> int:
        """The capacity that `want` open intervals' buffer runs on: `want` where it is
        compiled (in memory or on disk), under the `"eager"` policy, or once its rent has
        passed a compilation's cost (`_compile.rent`); else the smallest larger capacity that
        is compiled (the background compiler is asked for `want`), else `want` (compiled at
        its first call). A larger buffer gives the same refinement (keyed by path, step and
        tree node; each pass reads only the open intervals)."""
        self._joined()
        if want in self.sizes or _compile.policy() == "eager":
            return want
        if _compile.due(self._rent_key):
            _compile.pay(self._rent_key)
            return want
        for C in [c for c in CAPACITIES if c >= want] + [want]:
            if C in self.sizes or self._ready(C, d):
                if C != want:
                    _background.request(refine_levels, *self._stand_ins(want, d), paths=want)
                return C
        return want

    def _batch(self, n: int, d: int) -> int:
        """Candidates refined together out of `n`: `BATCH`, sized for the largest buffer,
        unless the buffer `n` candidates want is not compiled (`_choose`) while a smaller
        one is: then as many as that one holds (the same refinements, each candidate's own;
        the wanted buffer is asked of the background compiler)."""
        self._joined()
        want = _capacity(min(BATCH, n))
        if want in self.sizes or _compile.policy() == "eager" or _compile.due(self._rent_key):
            return BATCH
        smaller = [C for C in sorted(self.sizes) if C < want]
        if not smaller or self._ready(want, d):
            return BATCH
        _background.request(refine_levels, *self._stand_ins(want, d), paths=want)
        return max(1, smaller[-1] * BATCH // CAPACITIES[-1])

    @property
    def _rent_key(self):
        """The refinement's rent key (`_compile.rent`): one for all its capacities."""
        return (refine_levels, self.layout)

    def _key(self, C: int):
        return (refine_levels, self.layout, C)

    def _stand_ins(self, C: int, d: int):
        zeros = lambda shape, dtype: np.broadcast_to(np.zeros((), dtype), shape)  # noqa: E731
        f, i, u = np.float64, np.int32, np.uint32
        bufs = (zeros((d, C), f), zeros((d, C), f), zeros(C, i), zeros(C, i), zeros(C, u),
                zeros(C, u))  # fmt: skip
        return self._args(0, 0, *bufs, 0) + (self.layout,)

    def _ready(self, C: int, d: int, build: bool = False) -> bool:
        """Whether the executable of capacity `C` is compiled (then kept in `sizes`); with
        `build`, compile it if not."""
        with self._lock:
            if C in self.sizes:
                return True
            entry = _compile.remembered(self._key(C))  # (a run of the same structure made it)
            if entry is not None:
                self.sizes[C] = entry
                return True
            found = _compile.executable(refine_levels, *self._stand_ins(C, d), paths=C, build=build)
            if found is None:
                return False
            compiled, flat, _ = found
            entry = compiled if flat else functools.partial(_tail, compiled, self.layout)
            self.sizes[C] = _compile.memoized(self._key(C), lambda: entry)
            return True

    def _call(self, j, keyed, a, b, owner, pos, k0, k1, count, want=None):
        """One compiled call on the buffer `a, b, owner, pos, k0, k1` (capacity `C`, its last
        axis); `want`: the capacity the open intervals called for, if smaller (a stand-in
        buffer: it hands back where `want`'s would, so the capacities wanted next are
        known, and its wasted time is rent for `want`)."""
        C = a.shape[-1]
        stand_in = want is not None and want < C
        args = self._args(j, keyed, a, b, owner, pos, k0, k1, count, want if stand_in else None)
        if C not in self.sizes:
            with self._lock:  # the two threads of `first_crossing` compile each size once
                if C not in self.sizes:

                    def make():
                        compiled, flat, _ = _compile.executable(
                            refine_levels, *args, self.layout, timer=self.timer, paths=C
                        )
                        return compiled if flat else functools.partial(_tail, compiled, self.layout)

                    # The layout fixes every argument's shape and dtype: the runs of one
                    # model structure share the executables.
                    self.sizes[C] = _compile.memoized(self._key(C), make)
        if not stand_in:
            return self.sizes[C](*args)
        start = time.perf_counter()
        out = self.sizes[C](*args)
        int(out[-1])  # (the call's time: wait for it)
        _compile.rent(self._rent_key, (time.perf_counter() - start) * (1.0 - want / C))
        return out

    def first_crossing(self, Xa, Xb, path, step):
        """Refine candidate steps and find each one's first crossing of the level.

        Breadth first, one level of the dyadic tree at a time, so that every pass uses one
        level's coefficients and only the open intervals (compacted) are computed. At each
        level an interval is split at its exact bridge midpoint; a half that ends at or
        above the level holds a crossing; a half that ends below is certified crossing-free
        when its bound is at most the tolerance, and is undecided otherwise. Halves after a
        path's first half that ends above are dropped: the first crossing comes before
        their start. Down to the location depth both kinds are split again; past it only
        the undecided halves before the located one are (down to the certification depth),
        and a crossing found there replaces the location (it is earlier). The result does
        not depend on the order of exploration: it is what the depth-first refinement of
        the module docstring finds with the same draws.

        `Xa`, `Xb` `(d, n)`, `path`, `step` `(n,)`: the candidate steps (host arrays).

        **Returns:** `(found, frac, state, miss, unresolved, splits)`: per candidate, whether
        it crossed inside the step, where (fraction of the step) and the state there (linear
        interpolation inside the finest interval); per candidate, the summed bounds of its
        certified intervals (breadth first, this may include intervals after a crossing
        found later at a deeper level, so it bounds the depth-first sum); per candidate,
        whether an interval stayed undecided at the certification depth
        (certified all the same); the number of intervals split.
        """
        d, n = Xa.shape
        found = np.zeros(n, dtype=bool)
        frac = np.ones(n)
        state = np.array(Xb, dtype=float, copy=True)
        unresolved = np.zeros(n, dtype=bool)
        miss = np.zeros(n)
        into = (found, frac, state, unresolved, miss)
        Xa, Xb = np.asarray(Xa, float), np.asarray(Xb, float)
        path, step = np.asarray(path, np.uint32), np.asarray(step, np.uint32)
        # Two halves of the candidates in two threads (JAX releases the GIL while a call
        # runs): the refinement's many small operations per pass keep XLA's own threads
        # half idle (measured on 2 cores, 211 000 candidates: 0.125 s in one call, 0.097 s
        # in two threads; the same refinements, each candidate's being its own).
        parts = 2 if n >= 2 * CAPACITIES[1] and _threads() >= 2 else 1
        cuts = np.linspace(0, n, parts + 1).astype(int)
        args = [(Xa, Xb, path, step, cuts[i], cuts[i + 1], into) for i in range(parts)]
        if parts == 1:
            splits = self._refine_part(*args[0])
        else:
            splits = sum(_pool().map(lambda a: self._refine_part(*a), args))
        return found, frac, state, miss, unresolved, splits

    def _refine_part(self, Xa, Xb, path, step, lo, hi, into):
        """`first_crossing` for the candidates `lo:hi`, written into `into` (found, frac,
        state, unresolved, miss); returns their number of splits."""
        found, frac, state, unresolved, miss = into
        splits = 0
        d = Xa.shape[0]
        cuts = _batch_cuts(lo, hi, self._batch(hi - lo, d))
        for first, last in zip(cuts[:-1], cuts[1:], strict=True):
            who = np.arange(first, last)  # the candidate of each owner
            m = who.size
            want = _capacity(m)
            C = self._choose(want, d)
            # Slices, not gathers (`who` is a range): each copied once, into its buffer.
            part = slice(first, last)
            buf = [
                Xa[:, part], Xb[:, part], np.arange(m, dtype=np.int32), np.zeros(m, np.int32),
                path[part], step[part],
            ]  # fmt: skip
            buf = [_padded(x, C - m) for x in buf]
            j, count, keyed = 0, m, 0  # the first call hashes (path, step) into a key
            while True:
                out = self._call(j, keyed, *buf, count, want=want)
                keyed = 1
                status, j, count = int(out[-1]), int(out[0]), int(out[7])
                k = who.size
                found_ = np.asarray(out[8])[:k]
                hit = np.nonzero(found_)[0]
                # (numpy: columns by `take` and row by row, 3x faster than fancy indexing;
                # the batch's own candidates, a range at its first call, by slices)
                rows = slice(who[0], who[-1] + 1) if k and who[-1] - who[0] + 1 == k else who
                if hit.size:
                    at = who[hit]
                    found[at] = True
                    frac[at] = np.asarray(out[9])[hit]
                    for row, x in zip(state, np.asarray(out[10]), strict=True):
                        row[at] = x.take(hit)
                miss[rows] += np.asarray(out[11])[:k]
                unresolved[rows] |= np.asarray(out[12])[:k]
                splits += int(out[13])
                if status == DONE:
                    break
                # The open intervals are the first `count` slots of the returned buffer; on a
                # smaller buffer the slots past them are left as they are (never read).
                want = _capacity(2 * count if status == GROW else HEADROOM * count)
                C = self._choose(want, d)
                buf = [np.asarray(x) for x in out[1:7]]
                buf = [x[..., :C] if C <= x.shape[-1] else _padded(x, C - x.shape[-1])
                       for x in buf]  # fmt: skip
                # Renumber the owners that still have open intervals (they stay in order).
                owner = buf[2][:count]
                starts = np.ones(count, dtype=bool)
                np.not_equal(owner[1:], owner[:-1], out=starts[1:])
                who = who[owner[starts]]
                buf[2] = np.array(buf[2])
                buf[2][:count] = np.cumsum(starts) - 1
        return splits


def _batch_cuts(lo: int, hi: int, batch: int):
    """Bounds of the refinement batches of the candidates `lo:hi`: as few as hold at most
    `batch` each, of equal size. (Batches of `batch` and a remainder: the remainder could fill
    its buffer and outgrow it at its first level, e.g. a run's 100 000 onset steps as
    26000 + 24000 per thread, the 24000 in 24576 slots, then 4 passes over 65536, out of the
    cache; `python benchmarks/refine_batches.py`.)"""
    batches = max(1, -(-(hi - lo) // batch))
    return np.linspace(lo, hi, batches + 1).astype(int)


def _padded(x, pad):
    """`x` with `pad` more columns of zeros (the unused slots of a buffer), a new array."""
    out = np.empty(x.shape[:-1] + (x.shape[-1] + pad,), x.dtype)
    out[..., : x.shape[-1]] = x
    out[..., x.shape[-1] :] = 0
    return out


def _tail(compiled, layout, *args):
    return compiled(*args, layout)
