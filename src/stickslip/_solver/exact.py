"""Exact Gaussian transitions for linear slip phases."""

from __future__ import annotations

import diffrax
import equinox as eqx
import numpy as np

from .._jax import jax, jnp
from .._linear import propagators, propagators_host
from .base import AbstractSlipSolver

# Above this state dimension the transition uses a matrix product; below it, an unrolled sum
# whose rounding does not depend on the number of paths (chunk-size independence).
_UNROLL_MAX_DIM = 8


def transition(A, b, B, h):
    r"""Mean map and covariance of $dX = (AX + b)dt + B\,dW$ over a time `h`.

    Returns `(Phi, c, Sigma)` with $X(h) \sim \mathcal N(\Phi X(0) + c, \Sigma)$:
    $\Phi = e^{Ah}$, $c = \int_0^h e^{As} b\,ds$ and
    $\Sigma = \int_0^h e^{As} B B^\top e^{A^\top s} ds$ (see `stickslip._linear`).
    """
    Phi, _, c, Sigma = propagators(A, b, B, h)
    return Phi, c, Sigma


def _scaled(Sigma, xp):
    """Scale covariances (`(..., d, d)`) to correlation matrices; components without noise
    get scale 1."""
    s = xp.sqrt(xp.maximum(xp.diagonal(Sigma, axis1=-2, axis2=-1), 0.0))
    s = xp.where(s > 0, s, 1.0)
    return s, Sigma / (s[..., :, None] * s[..., None, :])


def psd_factor(Sigma, xp=jnp):
    """`L` with `L @ L.T == Sigma` for a covariance that may be singular or badly scaled
    (e.g. the position variance of a 3-state slip is ~h^5): factor the correlation matrix by
    its eigen-decomposition and scale back, which keeps small variances accurate. Works on
    stacks `(..., d, d)`; `xp` is `jax.numpy` or `numpy`.

    The factor of the correlation matrix is its symmetric square root `V sqrt(W) V^T`: unique
    and continuous in `Sigma`, unlike `V sqrt(W)`, whose columns' signs (and, for close
    eigenvalues, rotation) are arbitrary and flipped under a 1e-12 change of the model, which
    re-mapped the keyed normals and made results jump with the parameters."""
    s, R = _scaled(Sigma, xp)
    w, V = xp.linalg.eigh(R)
    root = (V * xp.sqrt(xp.maximum(w, 0.0))[..., None, :]) @ xp.swapaxes(V, -1, -2)
    return s[..., :, None] * root


def psd_pinv(Sigma, xp=jnp):
    """Pseudo-inverse of a covariance through its correlation matrix (see `psd_factor`)."""
    s, R = _scaled(Sigma, xp)
    # Correlations of a few-state slip are well conditioned; 1e-12 only drops true null
    # directions (components that no noise reaches).
    Rp = xp.linalg.pinv(R, rtol=1e-12)
    return Rp / (s[..., :, None] * s[..., None, :])


def apply(M, X):
    """`M @ X` for a batch of states `(d, n)`, with a fixed summation order when small."""
    d = M.shape[1]
    if d > _UNROLL_MAX_DIM:
        return M @ X
    acc = M[:, 0:1] * X[0:1]
    for j in range(1, d):
        acc = acc + M[:, j : j + 1] * X[j : j + 1]
    return acc


class ExactGaussian(AbstractSlipSolver):
    r"""Exact transition of a linear-Gaussian slip phase over a step of length `h`:
    $X_{k+1} = \Phi X_k + c + L z_k$, $\Phi = e^{Ah}$, $LL^\top = \Sigma(h)$.

    No discretisation error at the grid points, so the step can be large; only the stick
    detection and localisation depend on it. The transition needs a `d`-dimensional Gaussian
    per step (the stochastic convolution $\int_0^h e^{A(h-s)}B\,dW(s)$ is not a function of
    the Brownian increment alone), so the control is a `d`-column noise source.

    The solver is built for one step length (the transition is computed once, outside the
    compiled loop: it is the costliest part of compiling the loop) and must be used with
    steps of that length.

    Inside a step the interpolant is the Gaussian bridge mean
    $E[X(t_k + s) \mid X_k, X_{k+1}]$, evaluated at `nodes + 1` sub-nodes: it is the exact
    flow when there is no noise ($D = 0$), which makes the stick time exact to rounding.

    **Arguments:** `A`, `b`, `B` (see `LinearGaussian`), `h` (the step length), `nodes`
    (interpolation sub-steps per step), `bridge` (optional: the bridge coefficients of the
    exact stick detector, `stickslip._simulate.bridge.BridgeTables`, for the same step),
    `host` (compute the tables in NumPy, outside any trace: no compilation; the simulator
    builds its solver this way once per run).
    """

    A: jax.Array
    b: jax.Array
    Phi: jax.Array
    c: jax.Array
    L: jax.Array
    node_Phi: jax.Array
    node_c: jax.Array
    node_G: jax.Array
    node_dG: jax.Array
    bridge: eqx.Module | None
    nodes: int = eqx.field(static=True)

    def __init__(self, A, b, B, h, nodes: int = 8, bridge=None, host: bool = False):
        M = nodes
        xp = np if host else jnp
        self.bridge = bridge
        s = h * xp.arange(M + 1) / M
        if host:
            A, b, B = (np.asarray(x, dtype=np.float64) for x in (A, b, B))
            Phi, _, c, Sig = propagators_host(A, b, B, s)
        else:
            Phi, c, Sig = jax.vmap(lambda t: transition(A, b, B, t))(s)
        self.A, self.b, self.nodes = A, b, nodes
        self.Phi, self.c = Phi[M], c[M][:, None]
        # Scaled to take the control's increments N(0, h) rather than unit normals.
        self.L = psd_factor(Sig[M], xp) / xp.sqrt(h)
        # Bridge mean at the sub-nodes: E[X(s_j) | X_k, X_{k+1}] = Phi_j X_k + c_j + G_j r,
        # with r = X_{k+1} - Phi X_k - c, and its time derivative. Phi(h - s_j) is node M - j.
        Sp = psd_pinv(Sig[M], xp)
        PhiT_rev = xp.swapaxes(Phi[::-1], 1, 2)
        dSig = A @ Sig + Sig @ A.T + B @ B.T
        self.node_Phi, self.node_c = Phi, c
        self.node_G = Sig @ PhiT_rev @ Sp
        self.node_dG = (dSig @ PhiT_rev - Sig @ PhiT_rev @ A.T) @ Sp

    def noise_dim(self, model):
        return self.A.shape[0]

    def step_control(self, terms, t0, t1):
        return terms.contr(t0, t1)[1]  # the Brownian increments alone

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        X, rest = y0
        dw, carried = self.control(terms, t0, t1, solver_state)
        y1 = (apply(self.Phi, X) + self.c + apply(self.L, dw), rest)
        return y1, None, dict(y0=y0, y1=y1), carried, diffrax.RESULTS.successful

    def dense_nodes(self, model, y0, y1, h):
        M = self.nodes
        res = y1 - apply(self.Phi, y0) - self.c  # (d, n)
        per_node = jax.vmap(apply, in_axes=(0, None))
        flow = per_node(self.node_Phi, y0) + self.node_c[:, :, None]
        values = flow + per_node(self.node_G, res)
        slopes = (
            jax.vmap(apply, in_axes=(None, 0))(self.A, flow)
            + self.b[:, None]
            + per_node(self.node_dG, res)
        )
        values = values.at[0].set(y0).at[M].set(y1)
        return values, slopes
