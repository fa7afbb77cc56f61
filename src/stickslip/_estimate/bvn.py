"""Bivariate normal probabilities and truncated moments, vectorised in JAX.

`bvn_upper(h, k, r)` is Genz's algorithm (Genz 2004, "Numerical computation of rectangular
bivariate and trivariate normal and t probabilities", the `bvnu` routine; also behind
SciPy's and MATLAB's bivariate normal CDF): Gauss-Legendre quadrature of Drezner and
Wesolowsky's integral over the correlation for |r| < 0.925, and an expansion around
|r| = 1 otherwise. Absolute accuracy about 1e-15 for every r in [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np

from .._jax import jax, jnp

# 20-point Gauss-Legendre rule on [-1, 1] (nodes 1 - x and 1 + x as in Genz's code).
_W = np.array([
    0.01761400713915212, 0.04060142980038694, 0.06267204833410906, 0.08327674157670475,
    0.1019301198172404, 0.1181945319615184, 0.1316886384491766, 0.1420961093183821,
    0.1491729864726037, 0.1527533871307259,
])  # fmt: skip
_X = np.array([
    0.9931285991850949, 0.9639719272779138, 0.9122344282513259, 0.8391169718222188,
    0.7463319064601508, 0.6360536807265150, 0.5108670019508271, 0.3737060887154196,
    0.2277858511416451, 0.07652652113349733,
])  # fmt: skip
_W20 = np.concatenate([_W, _W])
_X20 = np.concatenate([1.0 - _X, 1.0 + _X])
_TWO_PI = 2.0 * math.pi
_SQRT_TWO_PI = math.sqrt(_TWO_PI)


def norm_cdf(x):
    return 0.5 * jax.scipy.special.erfc(-x / math.sqrt(2.0))


def norm_pdf(x):
    return jnp.exp(-0.5 * x * x) / _SQRT_TWO_PI


# Genz's rule for |r| < 0.925: 6 nodes for |r| < 0.3, 12 for |r| < 0.75, else 20.
_MID_RULES = {
    n: tuple(np.asarray(a) for a in (1.0 + np.polynomial.legendre.leggauss(n)[0],
                                     np.polynomial.legendre.leggauss(n)[1]))
    for n in (6, 12)
}  # fmt: skip
_MID_RULES[20] = (_X20, _W20)
BRANCHES = ("mid6", "mid12", "mid20", "high")  # `branch_of` maps r to one of these


_BRANCH_EDGES = np.array([0.3, 0.75, 0.925])  # |r| from which `BRANCHES[1:]` apply


def branch_of(r):
    """Index into `BRANCHES` of the formula `bvn_upper` uses at correlation r (NumPy; NaN
    gives the last). One binary search per value: the table kernels' host side calls this
    on millions of pairs."""
    return np.searchsorted(_BRANCH_EDGES, np.abs(r), side="right")


def _bvn_mid(h, k, r, nodes=20):
    """Drezner-Wesolowsky over asin(r) (|r| < 0.925) with Genz's Gauss-Legendre rule."""
    x, w = _MID_RULES[nodes]
    hk = h * k
    hs = 0.5 * (h * h + k * k)
    asr = 0.5 * jnp.arcsin(jnp.clip(r, -1.0, 1.0))
    sn = jnp.sin(asr[..., None] * x)
    mid = jnp.sum(w * jnp.exp((sn * hk[..., None] - hs[..., None]) / (1.0 - sn * sn)), axis=-1)
    return mid * asr / _TWO_PI + norm_cdf(-h) * norm_cdf(-k)


def _bvn_high(h, k, r):
    """Genz's expansion around |r| = 1 (|r| >= 0.925), with k -> -k for r < 0."""
    hk = h * k
    neg = r < 0
    kk = jnp.where(neg, -k, k)
    hk2 = jnp.where(neg, -hk, hk)
    as_ = jnp.maximum(1.0 - r * r, 0.0)
    a = jnp.sqrt(as_)
    bs = (h - kk) ** 2
    c = (4.0 - hk2) / 8.0
    d = (12.0 - hk2) / 80.0
    safe_as = jnp.where(as_ > 0, as_, 1.0)
    asr2 = -0.5 * (bs / safe_as + hk2)
    bvn = jnp.where(
        (asr2 > -100) & (as_ > 0),
        a * jnp.exp(asr2) * (1 - c * (bs - as_) * (1 - d * bs) / 3 + c * d * as_ * as_),
        0.0,
    )
    b = jnp.sqrt(bs)
    sp = _SQRT_TWO_PI * norm_cdf(-b / jnp.where(a > 0, a, 1.0))
    sp = jnp.where(a > 0, sp, 0.0)
    bvn = jnp.where(
        hk2 > -100, bvn - jnp.exp(-hk2 / 2) * sp * b * (1 - c * bs * (1 - d * bs) / 3), bvn
    )
    a2 = a / 2
    xs = (a2[..., None] * _X20) ** 2
    safe_xs = jnp.where(xs > 0, xs, 1.0)
    asr3 = -0.5 * (bs[..., None] / safe_xs + hk2[..., None])
    rs = jnp.sqrt(1.0 - xs)
    sp3 = 1.0 + c[..., None] * xs * (1.0 + 5.0 * d[..., None] * xs)
    ep = jnp.exp(-(hk2[..., None] / 2) * xs / (1.0 + rs) ** 2) / rs
    term = jnp.where(
        (asr3 > -100) & (xs > 0), a2[..., None] * _W20 * jnp.exp(asr3) * (ep - sp3), 0.0
    )
    bvn = -(bvn + jnp.sum(term, axis=-1)) / _TWO_PI
    pos_tail = bvn + norm_cdf(-jnp.maximum(h, kk))
    band = jnp.where(h < 0, norm_cdf(kk) - norm_cdf(h), norm_cdf(-h) - norm_cdf(-kk))
    neg_tail = jnp.where(h >= kk, -bvn, band - bvn)
    return jnp.where(neg, neg_tail, pos_tail)


def bvn_upper(h, k, r, branch=None):
    """P(U > h, V > k) for standard normals U, V with correlation r (arrays broadcast).

    `branch` (one of `BRANCHES`) evaluates only that formula, for arrays whose r all lie
    in its range (`branch_of`); by default both formulas are evaluated and the one for each
    r is kept (the 20-node rule below |r| = 0.925)."""
    h, k, r = jnp.broadcast_arrays(
        jnp.asarray(h, float), jnp.asarray(k, float), jnp.asarray(r, float)
    )
    if branch == "high":
        out = _bvn_high(h, k, r)
    elif branch is not None:
        out = _bvn_mid(h, k, r, int(branch.removeprefix("mid")))
    else:
        out = jnp.where(jnp.abs(r) < 0.925, _bvn_mid(h, k, r), _bvn_high(h, k, r))
    return jnp.clip(out, 0.0, 1.0)


def positive_part_mean(mu, s):
    """E[a^+] for a ~ N(mu, s^2): s phi(mu/s) + mu Phi(mu/s) (mu^+ when s = 0)."""
    safe = jnp.where(s > 0, s, 1.0)
    z = mu / safe
    return jnp.where(s > 0, s * norm_pdf(z) + mu * norm_cdf(z), jnp.maximum(mu, 0.0))


def positive_product_mean(m1, m2, s1, s2, rho, branch=None):
    r"""E[X^+ Y^+] for (X, Y) bivariate normal: means `m1, m2`, standard deviations
    `s1, s2 > 0`, correlation `rho` in (-1, 1).

    With U, V the standardised variables and thresholds h = -m1/s1, k = -m2/s2,
    E[X^+ Y^+] = m1 m2 P + m1 s2 E[V 1] + m2 s1 E[U 1] + s1 s2 E[U V 1], 1 = 1{U > h, V > k},
    with the truncated moments of Rosenbaum (1961):
    E[U 1] = phi(h) Q((k - rho h)/r) + rho phi(k) Q((h - rho k)/r),
    E[U V 1] = rho P + rho h phi(h) Q((k - rho h)/r) + rho k phi(k) Q((h - rho k)/r)
               + r^2 phi_2(h, k; rho),  r = sqrt(1 - rho^2), Q = 1 - Phi.
    `branch`: the formula for P (see `bvn_upper`).
    """
    h = -m1 / s1
    k = -m2 / s2
    rho = jnp.clip(rho, -1.0 + 1e-15, 1.0 - 1e-15)
    r = jnp.sqrt(1.0 - rho * rho)
    P = bvn_upper(h, k, rho, branch)
    qh = norm_cdf(-(k - rho * h) / r)
    qk = norm_cdf(-(h - rho * k) / r)
    ph, pk = norm_pdf(h), norm_pdf(k)
    EU = ph * qh + rho * pk * qk
    EV = pk * qk + rho * ph * qh
    quad = (h * h - 2.0 * rho * h * k + k * k) / (r * r)
    phi2_r2 = r * jnp.exp(-0.5 * quad) / _TWO_PI  # r^2 * phi_2(h, k; rho)
    EUV = rho * P + rho * h * ph * qh + rho * k * pk * qk + phi2_r2
    return m1 * m2 * P + m1 * s2 * EV + m2 * s1 * EU + s1 * s2 * EUV
