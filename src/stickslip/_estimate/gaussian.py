r"""Level-crossing densities of a linear-Gaussian slip phase, in closed form.

The slip state obeys $dX = (AX + b)\,dt + B\,dW$ from $X(0) \sim N(m_0, P_0)$, so at any set
of times the state is Gaussian, with $m(t) = e^{At} m_0 + c(t)$ and
$P(t) = e^{At} P_0 e^{A^\top t} + \Sigma(t)$. The crossing variable is $v = g^\top X$ with
level $L$, its rate $a = h^\top X + \beta$ ($h = A^\top g$, $\beta = g^\top b$), and the
position $x = p^\top X$.

- Exact case ($g^\top B = 0$: no noise in $\dot v$, so $a = \dot v$ has finite variance):
  Rice's formulas are exact.
- Closure case (white noise in $\dot v$): $a$ is given an extra independent
  $N(0, \sigma_c^2)$ at each time, the paper's closure
  $a \mid x, v \sim N(\mu_a, \sigma_c^2)$ with $\sigma_c^2 = 2D$ (eqs. 10-12).

All functions take one Gaussian initial law; mixtures (random onsets) are weighted sums.
"""

from __future__ import annotations

import math

import equinox as eqx

from .._jax import jax, jnp
from .bvn import positive_part_mean, positive_product_mean

_LOG_TWO_PI = math.log(2.0 * math.pi)


class Crossing(eqx.Module):
    """The constants of a linear-Gaussian slip phase that the formulas need."""

    A: jax.Array
    b: jax.Array
    B: jax.Array
    g: jax.Array  # crossing functional
    p: jax.Array  # position functional
    level: jax.Array
    closure_var: jax.Array  # sigma_c^2 (0 in the exact case)

    @property
    def h(self):
        return self.A.T @ self.g

    @property
    def beta(self):
        return self.g @ self.b


def _condition(mean, cov, n_obs, obs):
    """Condition a Gaussian on its first `n_obs` components equal to `obs`.

    Works on correlation scale (the observed variances can differ by many orders at small
    times). Returns the log density of the observation and the conditional mean and
    covariance of the remaining components. The Cholesky factor of the observed block
    (n_obs <= 3 here) and the triangular solves are written out element by element: under
    `vmap` over millions of pairs, XLA's batched LAPACK calls on 2 x 2 matrices cost more
    than the rest of n2 together.
    """
    s = [jnp.sqrt(cov[i, i]) for i in range(n_obs)]
    R = [[cov[i, j] / (s[i] * s[j]) for j in range(n_obs)] for i in range(n_obs)]
    L = [[None] * n_obs for _ in range(n_obs)]
    for i in range(n_obs):
        for j in range(i):
            L[i][j] = (R[i][j] - sum(L[i][k] * L[j][k] for k in range(j))) / L[j][j]
        L[i][i] = jnp.sqrt(R[i][i] - sum(L[i][k] * L[i][k] for k in range(i)))

    def solve(b):  # L^{-1} b, b a list of n_obs entries (scalars or rows)
        out = []
        for i in range(n_obs):
            out.append((b[i] - sum(L[i][k] * out[k] for k in range(i))) / L[i][i])
        return out

    z = solve([(obs[i] - mean[i]) / s[i] for i in range(n_obs)])
    K = solve([cov[n_obs:, i] / s[i] for i in range(n_obs)])  # rows (rest,)
    logdet = 2.0 * sum(jnp.log(L[i][i]) + jnp.log(s[i]) for i in range(n_obs))
    logp = -0.5 * sum(zi * zi for zi in z) - 0.5 * logdet - 0.5 * n_obs * _LOG_TWO_PI
    cmean = mean[n_obs:] + sum(K[i] * z[i] for i in range(n_obs))
    ccov = cov[n_obs:, n_obs:] - sum(jnp.outer(K[i], K[i]) for i in range(n_obs))
    return logp, cmean, ccov


def n1(cr: Crossing, m, P):
    """Upcrossing density of v through the level at the time of the moments (m, P):
    p_v(L) E[a^+ | v = L] (eq. 13)."""
    g, h = cr.g, cr.h
    mean = jnp.stack([g @ m, h @ m + cr.beta])
    Pg, Ph = P @ g, P @ h
    cov = jnp.array([[g @ Pg, g @ Ph], [g @ Ph, h @ Ph + cr.closure_var]])
    ok = cov[0, 0] > 0
    cov = jnp.where(ok, cov, jnp.eye(2))
    logp, mu, var = _condition(mean, cov, 1, jnp.array([cr.level]))
    value = jnp.exp(logp) * positive_part_mean(mu[0], jnp.sqrt(jnp.maximum(var[0, 0], 0.0)))
    return jnp.where(ok, value, 0.0)


def n1_joint(cr: Crossing, m, P, x):
    """Density of an upcrossing at position `x` (eq. 11): p(x, v = L) E[a^+ | x, v = L]."""
    g, h, p = cr.g, cr.h, cr.p
    U = jnp.stack([g, p, h])
    mean = U @ m + jnp.array([0.0, 0.0, cr.beta])
    cov = U @ P @ U.T + jnp.diag(jnp.array([0.0, 0.0, cr.closure_var]))
    ok = (cov[0, 0] > 0) & (cov[1, 1] > 0)
    cov = jnp.where(ok, cov, jnp.eye(3))
    logp, mu, var = _condition(mean, cov, 2, jnp.array([cr.level, x]))
    value = jnp.exp(logp) * positive_part_mean(mu[0], jnp.sqrt(jnp.maximum(var[0, 0], 0.0)))
    return jnp.where(ok, value, 0.0)


def _pair(cr: Crossing, m1, P1, Phi, Phi1, c, Sig, tau, with_position):
    """Mean and covariance of (v1, w, [x2,] a1, a2) for upcrossings at t1 and t2 = t1 + tau,
    with w = (v2 - v1) / tau: on (v1, w) the covariance stays well conditioned as tau -> 0,
    where (v1, v2) becomes singular. v2 - v1 = g^T [Phi1 (A X1 + b) + xi] exactly."""
    g, h, p, A, b = cr.g, cr.h, cr.p, cr.A, cr.b
    rows_U = [g, (A.T @ (Phi1.T @ g)) / tau]
    rows_V = [jnp.zeros_like(g), g / tau]
    const = [0.0, (g @ (Phi1 @ b)) / tau]
    if with_position:
        rows_U.append(Phi.T @ p)
        rows_V.append(p)
        const.append(p @ c)
    rows_U += [h, Phi.T @ h]
    rows_V += [jnp.zeros_like(h), h]
    const += [cr.beta, h @ c + cr.beta]
    U, V = jnp.stack(rows_U), jnp.stack(rows_V)
    mean = U @ m1 + jnp.stack([jnp.asarray(k, float) for k in const])
    n = U.shape[0]
    extra = jnp.zeros(n).at[n - 2 :].set(cr.closure_var)
    cov = U @ P1 @ U.T + V @ Sig @ V.T + jnp.diag(extra)
    return mean, cov


def n2(cr: Crossing, m1, P1, Phi, Phi1, c, Sig, tau):
    """Joint density of upcrossings at t1 and t1 + tau (tau > 0), from the moments (m1, P1)
    at t1 and the propagators over tau: p(v1 = L, v2 = L) E[a1^+ a2^+ | v1 = v2 = L]."""
    pre, mu, (s1, s2, rho) = n2_parts(cr, m1, P1, Phi, Phi1, c, Sig, tau)
    return pre * positive_product_mean(mu[0], mu[1], s1, s2, rho)


def n2_parts(cr: Crossing, m1, P1, Phi, Phi1, c, Sig, tau):
    """`n2` up to its last factor: the density p(v1 = L, v2 = L) (0 where undefined), the
    conditional means of (a1, a2) and their standard deviations and correlation, so that
    n2 = density * E[a1^+ a2^+] (`positive_product_mean`)."""
    mean, cov = _pair(cr, m1, P1, Phi, Phi1, c, Sig, tau, False)
    ok = (cov[0, 0] > 0) & (cov[1, 1] > 0)
    cov = jnp.where(ok, cov, jnp.eye(4))
    logp, mu, var = _condition(mean, cov, 2, jnp.array([cr.level, 0.0]))
    return jnp.where(ok, jnp.exp(logp) / tau, 0.0), mu, _spread(var)


def n2_joint(cr: Crossing, m1, P1, Phi, Phi1, c, Sig, tau, x):
    """Joint density of an upcrossing at t1 (anywhere) and one at t1 + tau at position x."""
    pre, mu, (s1, s2, rho) = n2_joint_parts(cr, m1, P1, Phi, Phi1, c, Sig, tau, x)
    return pre * positive_product_mean(mu[0], mu[1], s1, s2, rho)


def n2_joint_parts(cr: Crossing, m1, P1, Phi, Phi1, c, Sig, tau, x):
    """`n2_joint` as `n2_parts` gives `n2`."""
    mean, cov = _pair(cr, m1, P1, Phi, Phi1, c, Sig, tau, True)
    ok = (cov[0, 0] > 0) & (cov[1, 1] > 0) & (cov[2, 2] > 0)
    cov = jnp.where(ok, cov, jnp.eye(5))
    logp, mu, var = _condition(mean, cov, 3, jnp.array([cr.level, 0.0, x]))
    return jnp.where(ok, jnp.exp(logp) / tau, 0.0), mu, _spread(var)


def _spread(var):
    """Standard deviations and correlation of a 2 x 2 covariance (floored at 1e-300)."""
    s1 = jnp.sqrt(jnp.maximum(var[0, 0], 1e-300))
    s2 = jnp.sqrt(jnp.maximum(var[1, 1], 1e-300))
    return s1, s2, var[0, 1] / (s1 * s2)
