"""Compiled evaluation of the crossing densities over many times, lags and components."""

from __future__ import annotations

import equinox as eqx

from .._jax import jax, jnp
from .._linear import propagators
from . import gaussian as G

_PAIR_CHUNK = 1 << 15  # pairs evaluated at once (bounds the memory of the n2 kernels)


@eqx.filter_jit
def grid_moments(cr, m0s, P0s, h, n):
    """Moments of every component at t_k = k h, k < n: shapes (K, n, d), (K, n, d, d)."""
    Phi, _, c, Sig = G.grid_propagators(cr.A, cr.b, cr.B, h, n)
    return jax.vmap(
        lambda m0, P0: jax.vmap(lambda a, b, s: G.moments(m0, P0, a, b, s))(Phi, c, Sig)
    )(m0s, P0s)


@eqx.filter_jit
def moments_at(cr, m0s, P0s, t):
    """Moments of every component at arbitrary times `t` (n,)."""
    Phi, _, c, Sig = jax.vmap(lambda s: propagators(cr.A, cr.b, cr.B, s))(t)
    return jax.vmap(
        lambda m0, P0: jax.vmap(lambda a, b, s: G.moments(m0, P0, a, b, s))(Phi, c, Sig)
    )(m0s, P0s)


@eqx.filter_jit
def n1_from(cr, ms, Ps):
    """n1 for moments of shape (K, n, ...): (K, n)."""
    return jax.vmap(jax.vmap(lambda m, P: G.n1(cr, m, P)))(ms, Ps)


@eqx.filter_jit
def n1_joint_from(cr, ms, Ps, xs):
    """n1(x, t) for moments (K, n, ...) and positions xs (K, nx): (K, nx, n)."""

    def one(m_k, P_k, x_k):
        return jax.vmap(lambda x: jax.vmap(lambda m, P: G.n1_joint(cr, m, P, x))(m_k, P_k))(x_k)

    return jax.vmap(one)(ms, Ps, xs)


@eqx.filter_jit
def n1_joint_nodes(cr, ms, Ps, X):
    """n1(x, t) at per-time positions: moments (K, n, ...), positions X (K, J, n): (K, J, n)."""

    def one(m_k, P_k, X_k):
        return jax.vmap(
            lambda xrow: jax.vmap(lambda m, P, x: G.n1_joint(cr, m, P, x))(m_k, P_k, xrow)
        )(X_k)

    return jax.vmap(one)(ms, Ps, X)


@eqx.filter_jit
def lag_propagators(cr, taus):
    return jax.vmap(lambda s: propagators(cr.A, cr.b, cr.B, s))(taus)


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


@eqx.filter_jit
def n2_pairs(cr, m1, P1, Phi, Phi1, c, Sig, tau):
    """n2 for a flat list of pairs: moments at the earlier time and propagators over the lag
    (all with leading axis n_pairs)."""
    n_pairs = tau.shape[0]
    return _chunked(lambda *a: G.n2(cr, *a), n_pairs, m1, P1, Phi, Phi1, c, Sig, tau)


@eqx.filter_jit
def n2_joint_pairs(cr, m1, P1, Phi, Phi1, c, Sig, tau, xs):
    """n2(s; x, t) for a flat list of pairs, each with its own positions xs (n_pairs, J):
    shape (n_pairs, J)."""
    n_pairs = tau.shape[0]

    def one(m, P, a, b_, cc, s, t, x_row):
        return jax.vmap(lambda x: G.n2_joint(cr, m, P, a, b_, cc, s, t, x))(x_row)

    return _chunked(one, n_pairs, m1, P1, Phi, Phi1, c, Sig, tau, xs)
