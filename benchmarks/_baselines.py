"""NumPy baselines for the Langevin model with OU friction noise (no JAX, no stickslip).

Both use grid monitoring and linear interpolation of the stick time, the classic convention
(the paper's simulations, the reference data).
"""

from __future__ import annotations

import os
import time

import numpy as np
import scipy.linalg

# The benchmarks that time stickslip against these baselines time compiled code: every
# buffer size compiled where first met, not left to the background compiler
# (`stickslip._compile.policy`; the first call is timed by cold_start.py).
os.environ.setdefault("STICKSLIP_COMPILE", "eager")


def _matrices(omega0, zeta, D, tau):
    A = np.array([[0.0, 1.0, 0.0], [-(omega0**2), -zeta, 1.0], [0.0, 0.0, -1.0 / tau]])
    B = np.array([[0.0], [0.0], [np.sqrt(2 * D) / tau]])
    return A, B


def exact_dropping(n_paths, dt, t_max, seed, **params):
    """Exact Gaussian stepping of (x, v, eta); finished paths are dropped from the arrays.
    Returns `(slip_time, path_steps)`."""
    T, _, steps = exact_dropping_cycles(n_paths, dt, t_max, seed, **params)
    return T, steps


def exact_dropping_cycles(n_paths, dt, t_max, seed, *, omega0, zeta, D, v_b, x0, tau):
    """`exact_dropping` that also returns the slip distance: `(slip_time, slip_distance,
    path_steps)`, the stick position by the same linear interpolation as the time."""
    A, B = _matrices(omega0, zeta, D, tau)
    M = np.block([[-A, B @ B.T], [np.zeros((3, 3)), A.T]]) * dt
    E = scipy.linalg.expm(M)
    Phi = E[3:, 3:].T
    S = Phi @ E[:3, 3:]
    L = np.linalg.cholesky(0.5 * (S + S.T))
    PhiT, LT = Phi.T, L.T
    rng = np.random.default_rng(seed)
    X = np.tile([x0, v_b, 0.0], (n_paths, 1))
    T = np.full(n_paths, np.nan)
    d = np.full(n_paths, np.nan)
    idx = np.arange(n_paths)
    k = 0
    steps = 0
    while idx.size and k * dt < t_max:
        Xn = X @ PhiT + rng.standard_normal((idx.size, 3)) @ LT
        steps += idx.size
        k += 1
        hit = Xn[:, 1] >= v_b
        if hit.any():
            v0, v1 = X[hit, 1], Xn[hit, 1]
            f = (v_b - v0) / (v1 - v0)
            T[idx[hit]] = (k - 1 + f) * dt
            d[idx[hit]] = x0 - (X[hit, 0] + f * (Xn[hit, 0] - X[hit, 0]))
            keep = ~hit
            X, idx = Xn[keep], idx[keep]
        else:
            X = Xn
    return T, d, steps


def euler_dropping(n_paths, dt, t_max, seed, *, omega0, zeta, D, v_b, x0, tau):
    """Euler-Maruyama of (x, v, eta); finished paths are dropped from the arrays (the fair
    baseline: the work is that of the slipping paths, as in the simulator). Returns
    `(slip_time, path_steps)`."""
    rng = np.random.default_rng(seed)
    x = np.full(n_paths, float(x0))
    v = np.full(n_paths, float(v_b))
    e = np.zeros(n_paths)
    T = np.full(n_paths, np.nan)
    idx = np.arange(n_paths)
    g = np.sqrt(2 * D * dt) / tau
    k = 0
    steps = 0
    while idx.size and k * dt < t_max:
        xn = x + v * dt
        vn = v + (-(omega0**2) * x - zeta * v + e) * dt
        en = e - e / tau * dt + g * rng.standard_normal(idx.size)
        steps += idx.size
        k += 1
        hit = vn >= v_b
        if hit.any():
            T[idx[hit]] = (k - 1 + (v_b - v[hit]) / (vn[hit] - v[hit])) * dt
            keep = ~hit
            x, v, e, idx = xn[keep], vn[keep], en[keep], idx[keep]
        else:
            x, v, e = xn, vn, en
    return T, steps


def timed(fn):
    """`(fn(), seconds it took)`."""
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start
