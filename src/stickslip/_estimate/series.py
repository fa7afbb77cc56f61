r"""Level-crossing series for the first-passage density on a uniform time grid.

With $t_k = k h$, the inputs are $n_1(t_k)$ and $K(t_k) = \int_0^{t_k} n_2(t_k, s)\,ds$ (or
their position-resolved versions, with a leading position axis). Then (eqs. 6-7):

- truncation: $F_n^{(1)} = n_1$, $F_n^{(2)} = n_1 - K$;
- decoupling (cumulants): $F = \dot S e^{-S}$ with $g_1 = n_1$, $g_2 = n_2 - n_1 n_1$:
  $F_g^{(1)} = n_1 e^{-\int n_1}$, and $F_g^{(2)} = \dot S e^{-S}$ with the escape rate
  $\dot S(t) = n_1(t) - G(t)$, $G(t) = \int_0^t g_2(t, s)\,ds = K(t) - n_1(t)\int_0^t n_1$,
  and $S(t) = \int_0^t n_1 - \int_0^t G$;
- the normalised truncation $\hat F_n^{(k)} = F_n^{(k)}\,\Theta(t_n - t)$, with $t_n$ where
  $\int_0^{t_n} F_n^{(k)} = 1$. (The paper prints $\Theta(t - t_n)$, which would keep the
  density only after $t_n$ and contradicts its own definition of $t_n$.)
"""

from __future__ import annotations

import numpy as np


def cumulative(f, h):
    """Cumulative trapezoid integral along the last axis, starting at 0."""
    out = np.zeros_like(f)
    out[..., 1:] = np.cumsum(0.5 * h * (f[..., 1:] + f[..., :-1]), axis=-1)
    return out


def trapezoid_weights(n, h):
    """Weights of the trapezoid rule on n grid points of step h."""
    w = np.full(n, h)
    w[0] = w[-1] = h / 2
    return w


def truncation(n1, K, order):
    if order == 1:
        return n1.copy()
    return n1 - K


def decoupling(n1, K, order, h, n1_marginal=None, I1=None):
    """Decoupling approximation; `n1_marginal` is n1(t) when `n1`/`K` are resolved by
    position (the exponent S(t) is always the marginal one); `I1` its integral from 0 (the
    trapezoid rule on the grid when not given). Returns (F, escape_rate)."""
    marg = n1 if n1_marginal is None else n1_marginal
    I1 = cumulative(marg, h) if I1 is None else I1
    if order == 1:
        return n1 * np.exp(-I1), n1
    if n1_marginal is None:
        G = K - n1 * I1
        S = I1 - cumulative(G, h)
        rate = n1 - G
        return rate * np.exp(-S), rate
    raise ValueError("use decoupling_joint for position-resolved second order")


def decoupling_joint(n1x, Kx, n1, K, h, I1=None):
    """Second-order decoupling resolved by position: F(x, t) = Sdot(x, t) exp(-S(t)) with
    Sdot(x, t) = n1(x, t) - [Kx(x, t) - n1(x, t) int_0^t n1] and S(t) the marginal one."""
    I1 = cumulative(n1, h) if I1 is None else I1
    G = K - n1 * I1
    S = I1 - cumulative(G, h)
    rate_x = n1x - (Kx - n1x * I1)
    return rate_x * np.exp(-S), rate_x


def normalise_truncation(F, h, integral=None):
    """Cut the density where its integral (`integral`, or the trapezoid rule on the grid)
    first reaches 1. Returns (F_hat, t_n index or None when the integral never reaches 1
    on the grid)."""
    I = cumulative(F, h) if integral is None else integral
    over = np.nonzero(I >= 1.0)[0]
    if over.size == 0:
        return F.copy(), None
    k = over[0]
    out = F.copy()
    out[k + 1 :] = 0.0
    return out, k
