r"""Propagators of a linear SDE $dX = (AX + b)\,dt + B\,dW$.

Over a lag $\tau$: $X(\tau) = \Phi X(0) + c + \xi$ with $\Phi = e^{A\tau}$,
$\Phi_1 = \int_0^\tau e^{As}ds$, $c = \Phi_1 b$ and $\xi \sim N(0, \Sigma)$,
$\Sigma = \int_0^\tau e^{As}BB^\top e^{A^\top s}ds$.

The lag is first split into $2^s$ pieces with $\|A\tau/2^s\|_1 \le 1/2$. On one piece the
three matrices are Taylor series with positive, fast-falling terms (order 20: truncation
error about $0.5^{21}/21! \approx 10^{-26}$):
$\Phi = \sum_k (A\tau)^k/k!$, $\Phi_1 = \sum_k \tau^{k+1}A^k/(k+1)!$,
$\Sigma = \sum_k \tau^{k+1}\Omega_k/(k+1)!$ with $\Omega_0 = BB^\top$,
$\Omega_k = A\Omega_{k-1} + \Omega_{k-1}A^\top$. The $s$ doublings are exact and well
conditioned: $\Phi(2t) = \Phi(t)^2$, $\Phi_1(2t) = \Phi_1(t) + \Phi(t)\Phi_1(t)$,
$\Sigma(2t) = \Sigma(t) + \Phi(t)\Sigma(t)\Phi(t)^\top$.

Two things this avoids, both measured here. Van Loan's block exponential holds
$e^{-A\tau}$, which grows like $e^{|\lambda|\tau}$ for a strongly damped mode, so that
$\Sigma = \Phi E_{12}$ cancels catastrophically (at $\tau = 2.5$ with a friction-noise time
0.1 the terms are $e^{25}$ times the result: SciPy's answer was wrong in every digit).
And `jax.scipy.linalg.expm` under `vmap` hung XLA's CPU runtime on repeated calls.
"""

from __future__ import annotations

import numpy as np

from ._jax import jax, jnp

_MAX_DOUBLINGS = 48  # enough for |A tau| up to 1e14
_ORDER = 20


def _taylor(A, B, tau, xp=jnp):
    """Phi, Phi1, Sigma over a lag with |A tau| <= 1/2 (see the module docstring). `tau`
    may be a stack of lags shaped `(n, 1, 1)`; `xp` is `jax.numpy` or `numpy`."""
    d = A.shape[0]
    At = A * tau
    term = xp.eye(d)  # (A tau)^k / k!
    Phi = xp.eye(d)
    Phi1 = xp.eye(d) * tau
    Om = B @ B.T  # Omega_k
    coef = tau  # tau^(k+1) / (k+1)!
    Sig = Om * coef
    for k in range(1, _ORDER + 1):
        term = term @ At / k
        Phi = Phi + term
        Phi1 = Phi1 + term * (tau / (k + 1))
        Om = A @ Om + Om @ A.T
        coef = coef * tau / (k + 1)
        Sig = Sig + Om * coef
    return Phi, Phi1, 0.5 * (Sig + xp.swapaxes(Sig, -1, -2))


def propagators(A, b, B, tau):
    r"""$(\Phi, \Phi_1, c, \Sigma)$ over the lag `tau` (see the module docstring)."""
    norm = jnp.max(jnp.sum(jnp.abs(A), axis=0)) * jnp.abs(tau)
    s = jnp.ceil(jnp.log2(jnp.maximum(norm, 1e-300) / 0.5))
    s = jnp.clip(s, 0, _MAX_DOUBLINGS).astype(jnp.int32)
    Phi, Phi1, Sig = _taylor(A, B, tau / 2.0**s)

    def double(i, carry):
        Phi, Phi1, Sig = carry
        doubled = (Phi @ Phi, Phi1 + Phi @ Phi1, Sig + Phi @ Sig @ Phi.T)
        return jax.tree_util.tree_map(lambda new, old: jnp.where(i < s, new, old), doubled, carry)

    # A fixed trip count with masked steps keeps vmapped lags in one loop.
    Phi, Phi1, Sig = jax.lax.fori_loop(0, _MAX_DOUBLINGS, double, (Phi, Phi1, Sig))
    return Phi, Phi1, Phi1 @ b, 0.5 * (Sig + Sig.T)


def propagators_host(A, b, B, tau):
    """`propagators` in NumPy, for an array of lags `tau` at once: each of the four results
    has the shape of `tau` in front. The same series and doublings, with no compilation
    (the simulator builds its step tables with it once per run)."""
    A, b, B = (np.asarray(x, dtype=np.float64) for x in (A, b, B))
    tau = np.asarray(tau, dtype=np.float64)
    t = tau.reshape(-1, 1, 1)
    norm = np.max(np.sum(np.abs(A), axis=0)) * np.abs(t)
    s = np.ceil(np.log2(np.maximum(norm, 1e-300) / 0.5))
    s = np.clip(s, 0, _MAX_DOUBLINGS).astype(np.int64)
    Phi, Phi1, Sig = _taylor(A, B, t / 2.0**s, xp=np)
    T = lambda M: np.swapaxes(M, -1, -2)
    for i in range(int(s.max(initial=0))):
        doubled = (Phi @ Phi, Phi1 + Phi @ Phi1, Sig + Phi @ Sig @ T(Phi))
        Phi, Phi1, Sig = (
            np.where(i < s, new, old) for new, old in zip(doubled, (Phi, Phi1, Sig), strict=True)
        )
    out = (Phi, Phi1, Phi1 @ b, 0.5 * (Sig + T(Sig)))
    return tuple(x.reshape(tau.shape + x.shape[1:]) for x in out)


def propagators_many(A, b, B, tau):
    """`propagators_host` for many lags at once, faster: the series' matrices do not depend on
    the lag (A^k and Omega_k), so each of Phi, Phi1 and Sigma on the pieces is one product of
    a (lags x order) table of coefficients with them; the doublings then touch only the lags
    that need them. The same series and doublings, summed in another order: equal to
    `propagators_host` to rounding, not to the bit (the simulator, whose host-built tables
    must equal its traced ones, uses `propagators_host`; the estimator uses this)."""
    A, b, B = (np.asarray(x, dtype=np.float64) for x in (A, b, B))
    tau = np.asarray(tau, dtype=np.float64)
    t = tau.reshape(-1)
    d = A.shape[0]
    norm = np.max(np.sum(np.abs(A), axis=0)) * np.abs(t)
    s = np.ceil(np.log2(np.maximum(norm, 1e-300) / 0.5))
    s = np.clip(s, 0, _MAX_DOUBLINGS).astype(np.int64)
    u = t / 2.0**s
    powers, omegas = [np.eye(d)], [B @ B.T]
    for _ in range(_ORDER):
        powers.append(powers[-1] @ A)
        omegas.append(A @ omegas[-1] + omegas[-1] @ A.T)
    # u^k / k! and u^(k+1) / (k+1)!, k = 0.._ORDER
    k = np.arange(1, _ORDER + 2)
    rising = np.cumprod(u[:, None] / k[None, :], axis=1)
    plain = np.concatenate([np.ones((t.size, 1)), rising[:, :-1]], axis=1)
    flat = lambda mats: np.stack(mats).reshape(_ORDER + 1, d * d)
    Phi = (plain @ flat(powers)).reshape(-1, d, d)
    Phi1 = (rising @ flat(powers)).reshape(-1, d, d)
    Sig = (rising @ flat(omegas)).reshape(-1, d, d)
    Sig = 0.5 * (Sig + np.swapaxes(Sig, -1, -2))
    T = lambda M: np.swapaxes(M, -1, -2)
    order = np.argsort(-s, kind="stable")  # the lags doubled i times or more: a prefix
    Phi, Phi1, Sig, s = Phi[order], Phi1[order], Sig[order], s[order]
    for i in range(int(s.max(initial=0))):
        m = int(np.searchsorted(-s, -i, side="left"))  # s > i on [0, m)
        F, F1, S = Phi[:m], Phi1[:m], Sig[:m]
        Phi[:m], Phi1[:m], Sig[:m] = F @ F, F1 + F @ F1, S + F @ S @ T(F)
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    out = (Phi[back], Phi1[back], Phi1[back] @ b, 0.5 * (Sig[back] + T(Sig[back])))
    return tuple(x.reshape(tau.shape + x.shape[1:]) for x in out)


def stationary(A, b, B):
    """Stationary mean and covariance for a stable A: A m + b = 0, A P + P A^T + B B^T = 0."""
    d = A.shape[0]
    m = -jnp.linalg.solve(A, b)
    # The Lyapunov equation as a linear system: (I kron A + A kron I) vec(P) = -vec(B B^T).
    K = jnp.kron(jnp.eye(d), A) + jnp.kron(A, jnp.eye(d))
    P = jnp.linalg.solve(K, -(B @ B.T).reshape(-1)).reshape(d, d)
    return m, 0.5 * (P + P.T)
