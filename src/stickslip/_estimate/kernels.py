"""Compiled evaluation of the crossing densities over many times, lags and components."""

from __future__ import annotations

import functools

import equinox as eqx
import numpy as np

from .. import _compile
from .._jax import jax, jnp
from .._linear import propagators_many
from . import gaussian as G

_PAIR_CHUNK = 1 << 15  # pairs evaluated at once (bounds the memory of the n2 kernels)


def _kept(fn):
    """`eqx.filter_jit(fn)` whose trace and executable are kept on disk (`_compile.call`,
    one per shape: a new process loads them instead of tracing the formulas again, a few
    seconds of a warm study) and, for the configurations `_ship` runs, shipped with the
    package."""
    jitted = eqx.filter_jit(fn)

    @functools.wraps(fn)
    def run(*args):
        return _compile.call(jitted, *args, paths=0)

    run.jitted = jitted  # (for `_compile.Fixed`: calls that share their leading arguments)
    return run


def _host(cr):
    """The drift and diffusion of `cr` as NumPy arrays."""
    return tuple(np.asarray(x, dtype=np.float64) for x in (cr.A, cr.b, cr.B))


def _carried(m0s, P0s, Phi, c, Sig):
    """Moments from N(m0s, P0s) (K, d), (K, d, d) over the lags of propagators with leading
    shape S: Phi m0 + c (K, *S, d) and Phi P0 Phi^T + Sigma (K, *S, d, d). Phi m0 and Phi P0
    are single matrix products over the stacked rows of Phi (BLAS); only (Phi P0) Phi^T is
    a stack."""
    m0s, P0s = np.asarray(m0s, dtype=np.float64), np.asarray(P0s, dtype=np.float64)
    K, d = m0s.shape
    rows = Phi.reshape(-1, d)  # (S d, d)
    ms = np.moveaxis((rows @ m0s.T).reshape(Phi.shape[:-1] + (K,)), -1, 0) + c[None]
    PhiT = np.swapaxes(Phi, -1, -2)
    Ps = np.stack([(rows @ P0).reshape(Phi.shape) @ PhiT for P0 in P0s]) + Sig[None]
    return ms, Ps


# The propagators and the moments they carry are a few products of d x d matrices per lag:
# computed in NumPy (`propagators_many`: the same series and doublings as `propagators`),
# they compile nothing. As jitted kernels they were five XLA programs of ~1 s each to
# compile (the order-20 series unrolled under `vmap`), a quarter of a cold main job's
# compiling, for a few milliseconds of arithmetic.


def lag_propagators(cr, taus):
    """(Phi, Phi1, c, Sigma) at the lags `taus` (n,): (n, d, d), (n, d, d), (n, d), (n, d, d)."""
    return propagators_many(*_host(cr), np.asarray(taus, dtype=np.float64))


def grid_lag_propagators(cr, h, n):
    """`lag_propagators` at the lags j h, j < n."""
    return lag_propagators(cr, h * np.arange(n))


def grid_moments(cr, m0s, P0s, h, n):
    """Moments of every component at t_k = k h, k < n: shapes (K, n, d), (K, n, d, d)."""
    Phi, _, c, Sig = grid_lag_propagators(cr, h, n)
    return _carried(m0s, P0s, Phi, c, Sig)


def moments_at(cr, m0s, P0s, t):
    """Moments of every component at arbitrary times `t` (n,)."""
    Phi, _, c, Sig = lag_propagators(cr, t)
    return _carried(m0s, P0s, Phi, c, Sig)


def step_moments(cr, ms, Ps, s):
    """Moments (K, n, ...) carried on by the lag `s` (one propagator for all)."""
    Phi, _, c, Sig = propagators_many(*_host(cr), float(s))
    ms, Ps = np.asarray(ms, dtype=np.float64), np.asarray(Ps, dtype=np.float64)
    return ms @ Phi.T + c, Phi @ Ps @ Phi.T + Sig


@_kept
def n1_from(cr, ms, Ps):
    """n1 for moments of shape (K, n, ...): (K, n)."""
    return jax.vmap(jax.vmap(lambda m, P: G.n1(cr, m, P)))(ms, Ps)


@_kept
def n1_joint_from(cr, ms, Ps, xs):
    """n1(x, t) for moments (K, n, ...) and positions xs (K, nx): (K, nx, n)."""

    def one(m_k, P_k, x_k):
        return jax.vmap(lambda x: jax.vmap(lambda m, P: G.n1_joint(cr, m, P, x))(m_k, P_k))(x_k)

    return jax.vmap(one)(ms, Ps, xs)


@_kept
def n1_joint_nodes(cr, ms, Ps, X):
    """n1(x, t) at per-time positions: moments (K, n, ...), positions X (K, J, n): (K, J, n)."""

    def one(m_k, P_k, X_k):
        return jax.vmap(
            lambda xrow: jax.vmap(lambda m, P, x: G.n1_joint(cr, m, P, x))(m_k, P_k, xrow)
        )(X_k)

    return jax.vmap(one)(ms, Ps, X)


def _chunked(fn, n_pairs, *arrays):
    """Map `fn` over the leading axis of `arrays` in chunks (sequentially), padding the last."""
    n_chunks = -(-n_pairs // _PAIR_CHUNK)
    size = n_chunks * _PAIR_CHUNK

    def pad(a):
        return (
            jnp.concatenate([a, jnp.repeat(a[:1], size - n_pairs, axis=0)]) if size > n_pairs else a
        )

    padded = [pad(a).reshape((n_chunks, _PAIR_CHUNK) + a.shape[1:]) for a in arrays]
    out = jax.lax.map(lambda xs: jax.vmap(fn)(*xs), padded)
    return out.reshape((size,) + out.shape[2:])[:n_pairs]


@_kept
def n2_pairs(cr, m1, P1, Phi, Phi1, c, Sig, tau):
    """n2 for a flat list of pairs: moments at the earlier time and propagators over the lag
    (all with leading axis n_pairs)."""
    n_pairs = tau.shape[0]
    return _chunked(lambda *a: G.n2(cr, *a), n_pairs, m1, P1, Phi, Phi1, c, Sig, tau)


def _table_pair(cr, ms, Ps, table, moment, carry, first, second):
    """Moments at the earlier time and propagators over the lag of one pair given as rows of
    tables: the moments of row `moment` carried over the lag of propagator row `carry`, and
    the lag of row `first` followed by that of row `second` (row 0: the identity, for which
    both compositions are exact)."""
    Phi_t, Phi1_t, c_t, Sig_t = table
    F, S = Phi_t[carry], Sig_t[carry]
    m1 = F @ ms[moment] + c_t[carry]
    P1 = F @ Ps[moment] @ F.T + S
    Fa, Fb = Phi_t[first], Phi_t[second]
    Phi = Fb @ Fa
    Phi1 = Phi1_t[second] + Fb @ Phi1_t[first]
    Sig = Fb @ Sig_t[first] @ Fb.T + Sig_t[second]
    return m1, P1, Phi, Phi1, Phi1 @ cr.b, Sig


_TABLE_CHUNK = 1 << 14  # pairs per call of the table kernels


def _full_chunk(a, fill, dtype=np.float64):
    """`a` (at most `_TABLE_CHUNK` rows) padded with `fill` to a whole chunk: the kernels
    see one shape."""
    out = np.full((_TABLE_CHUNK,) + a.shape[1:], fill, dtype)
    out[: a.shape[0]] = a
    return out


def bucket(n):
    """Table length padded to a power of two (>= 64), so that few shapes get compiled."""
    return max(64, 1 << (int(n) - 1).bit_length())


def table_pairs(cr, ms, Ps, table, rows, tau, positions=None):
    """n2 (or, with `positions`, n2(s; x, t)) over pairs given by table rows (`rows`:
    (n_pairs, 4) integers: moment, carry, first, second; see `_table_pair`). NumPy array
    (n_pairs,) or (n_pairs, J).

    In two passes of fixed-size chunks (the compiled code depends on the shapes of the
    tables alone, however many pairs a call has): the Gaussian part of every pair first
    (`n2_parts`), then the factor E[a1^+ a2^+], grouped by the formula its correlation
    needs (Genz's rule for the bivariate normal: a 6-, 12- or 20-node quadrature, or the
    expansion near |r| = 1; evaluated for every pair under `vmap`, the costliest of them
    would be paid each time). `positions`: a table (n_t, J) and each pair's row in it (the
    positions of its later time). Each pass hands every chunk to XLA before it reads any
    result (the calls return at once), so that the host's work on one chunk overlaps the
    kernels of the others."""
    from .bvn import BRANCHES, branch_of

    n = tau.shape[0]
    if n == 0:
        return np.zeros((0,) if positions is None else (0, 0))
    # Every chunk shares the tables: partitioned and put on the device once (`_compile.Fixed`;
    # a generic call costs ~1 ms on the host, and a block makes a few hundred).
    kernel = n2_parts_chunk if positions is None else n2_joint_parts_chunk
    parts_of = _compile.Fixed(kernel.jitted, cr, ms, Ps, table)
    if positions is not None:
        xs = jnp.asarray(positions[0])
    pending = []
    for lo in range(0, n, _TABLE_CHUNK):
        hi = min(lo + _TABLE_CHUNK, n)
        r = _full_chunk(rows[lo:hi], 0, np.int32)  # row 0: harmless
        t = _full_chunk(tau[lo:hi], 1.0)
        if positions is None:
            pending.append((hi - lo, parts_of(r, t, paths=0)))
        else:
            kk = _full_chunk(positions[1][lo:hi], 0, np.int32)
            pending.append((hi - lo, parts_of(r, t, xs, kk, paths=0)))
    parts = [[np.asarray(a)[:m] for a in out] for m, out in pending]
    pre, m1, m2, s1, s2, rho = (np.concatenate(a) for a in zip(*parts, strict=True))
    # (s1, s2, rho) are the pair's, whatever the position: indexed by pair, not copied J times
    shape, J = pre.shape, (pre.shape[1] if pre.ndim > 1 else 1)
    pre, m1, m2 = pre.ravel(), m1.ravel(), m2.ravel()
    value = np.zeros(pre.size)
    branch = np.repeat(branch_of(rho), J)
    pending = []
    for b, name in enumerate(BRANCHES):
        product = _compile.Fixed(product_chunk.jitted, name)
        (idx,) = np.nonzero((branch == b) & (pre != 0))
        for lo in range(0, idx.size, _TABLE_CHUNK):
            sel = idx[lo : lo + _TABLE_CHUNK]
            pair = sel // J
            args = [_full_chunk(m1[sel], 1.0), _full_chunk(m2[sel], 1.0),
                    _full_chunk(s1[pair], 1.0), _full_chunk(s2[pair], 1.0),
                    _full_chunk(rho[pair], 0.0)]  # fmt: skip
            pending.append((sel, product(*args, paths=0)))
    for sel, prod in pending:
        value[sel] = pre[sel] * np.asarray(prod)[: sel.size]
    return value.reshape(shape)


@_kept
def product_chunk(branch, m1, m2, s1, s2, rho):
    """E[a1^+ a2^+] for a chunk, by one formula of the bivariate normal (`bvn_upper`)."""
    from .bvn import positive_product_mean

    return positive_product_mean(m1, m2, s1, s2, rho, branch)


@_kept
def n2_parts_chunk(cr, ms, Ps, table, rows, tau):
    """`gaussian.n2_parts` for a chunk of pairs given by table rows: density, means (2) and
    (s1, s2, rho), each (chunk,)."""

    def one(r, t):
        pre, mu, spread = G.n2_parts(cr, *_table_pair(cr, ms, Ps, table, *r), t)
        return (pre, mu[0], mu[1], *spread)

    return jax.vmap(one)(rows, tau)


@_kept
def n2_joint_parts_chunk(cr, ms, Ps, table, rows, tau, xs, k):
    """`gaussian.n2_joint_parts` for a chunk of pairs given by table rows, at the positions
    xs[k] (J,) of each pair's later time: density and means (chunk, J), and
    (s1, s2, rho) (chunk,) (they do not depend on x)."""

    def one(r, t, kk):
        args = _table_pair(cr, ms, Ps, table, *r)
        pre, mu, spread = jax.vmap(lambda x: G.n2_joint_parts(cr, *args, t, x))(xs[kk])
        return (pre, mu[:, 0], mu[:, 1], *(a[0] for a in spread))

    return jax.vmap(one)(rows, tau, k)
