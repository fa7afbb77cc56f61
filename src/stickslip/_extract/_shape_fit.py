r"""The slips' shape fits, compiled: a Levenberg-Marquardt per fit, the soft-L1 loss at
f_scale $2\sigma$ by iteratively reweighted least squares, over one slip
($y_0 - D\,S(\varphi, \kappa)$, five parameters) or two ($y_0 - D_a S_a - D_b S_b$, the
second `gap` after the first's stick, nine).

Each fit walks the samples of its own window once per evaluation (no padding to a
batch's longest window, no temporaries): the single slip's flat samples enter the normal
equations through four sums (before its release the model is $y_0$; after its stick
$y_0 - D$), its shape evaluated on the samples strictly inside the slip only. The rules
(damping, bounds, the stop) are `_lm_one`'s. Compiled by Numba on first use (some
seconds) and cached on disk (`_jit`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .._cpu import on_two_threads, usable_cores
from ._jit import call

_COS_PI, _SIN_PI = math.cos(math.pi), math.sin(math.pi)
_JIT = {"nogil": True, "error_model": "numpy"}  # (the callees: compiled into fit_windows)


@numba.njit(**_JIT)
def shape_point(phi, kappa):
    """The normalised drop S(phi, kappa) 0 -> 1 and its derivatives in phi and kappa at
    one phi (0 before the slip; past it those at phi = 1, d/dphi 0; a nan carried)."""
    if phi <= 0.0:
        return 0.0, 0.0, 0.0
    if phi >= 1.0:
        p, cos, sin = 1.0, _COS_PI, _SIN_PI
    else:
        p = phi
        cos, sin = math.cos(math.pi * p), math.sin(math.pi * p)
    decay = math.exp(-kappa * p)
    tail = math.exp(-kappa)
    full = 1.0 + tail
    inner = cos + kappa / math.pi * sin
    num = 1.0 - decay * inner
    d_phi = decay * sin * (math.pi + kappa * kappa / math.pi) / full if p < 1.0 else 0.0
    d_kappa = decay * (p * inner - sin / math.pi) / full + num * tail / (full * full)
    return num / full, d_phi, d_kappa


@numba.njit(**_JIT)
def _loss(r, sigma):
    """The IRLS weight of residual r and its soft-L1 loss at f_scale 2 sigma (scipy's
    least_squares' `soft_l1`, in units of sigma^2: chi^2-like)."""
    z = r / (2.0 * sigma)
    q = math.sqrt(1.0 + z * z)
    return 1.0 / q, 8.0 * (q - 1.0)


@numba.njit(**_JIT)
def _accumulate(A, grad, jac, w, r):
    """A += w jac jac^T (its upper triangle), grad += w r jac."""
    k = jac.size
    for a in range(k):
        wa = w * jac[a]
        if wa == 0.0:  # (most of a two-slip window's rows: flat beside one slip or both)
            continue
        grad[a] += wa * r
        for b in range(a, k):
            A[a, b] += wa * jac[b]


@numba.njit(**_JIT)
def _mirror(A):
    """A's lower triangle from its upper one."""
    for a in range(A.shape[0]):
        for b in range(a):
            A[a, b] = A[b, a]


@numba.njit(**_JIT)
def _zero(A, grad):
    for i in range(grad.size):
        grad[i] = 0.0
        for j in range(grad.size):
            A[i, j] = 0.0


# Along a slip the phase grows by 1/T a sample: cos(pi phi), sin(pi phi) and exp(-kappa
# phi) follow by rotation and by a constant factor (`_Walk`), not by three transcendental
# calls a sample (those were half a fit's time); they are evaluated afresh every this many
# samples, which bounds the recurrences' rounding (~1e-16 a step) far below the noise.
_RESYNC = 64


@numba.njit(**_JIT)
def _walk_start(phi, kappa, T):
    """The walk's state at `phi` (cos, sin, decay) and its per-sample factors."""
    return (math.cos(math.pi * phi), math.sin(math.pi * phi), math.exp(-kappa * phi),
            math.cos(math.pi / T), math.sin(math.pi / T), math.exp(-kappa / T))  # fmt: skip


@numba.njit(**_JIT)
def _shape_at(cos, sin, decay, phi, kappa, tail, full):
    """`shape_point`'s values at 0 < phi < 1 from cos(pi phi), sin(pi phi), exp(-kappa phi),
    exp(-kappa) (`tail`) and 1 + tail (`full`)."""
    inner = cos + kappa / math.pi * sin
    num = 1.0 - decay * inner
    d_phi = decay * sin * (math.pi + kappa * kappa / math.pi) / full
    d_kappa = decay * (phi * inner - sin / math.pi) / full + num * tail / (full * full)
    return num / full, d_phi, d_kappa


@numba.njit(**_JIT)
def _flat(y, lo, x0, x1, level, sigma, A, grad, after):
    """The samples x0 <= x < x1 where the model is the constant `level` (before the slip:
    the Jacobian's y0 column only; `after` it also D's): their sums into A and grad, and
    their cost."""
    cost = 0.0
    for x in range(x0, x1):
        r = level - y[lo + x]
        w, loss = _loss(r, sigma)
        cost += loss
        A[2, 2] += w
        grad[2] += w * r
        if after:
            A[2, 3] -= w
            A[3, 3] += w
            grad[3] -= w * r
    return cost


@numba.njit(**_JIT)
def _walked(phi, kappa, T, past, tail, full, walk, n):
    """`shape_point(phi, kappa)` of a slip of T samples walked sample by sample (`walk`:
    cos, sin and decay at the last sample inside it and their per-sample factors; `n`
    samples walked inside so far): the shape, its two derivatives and `n` after."""
    if phi >= 1.0:
        return past[0], past[1], past[2], n
    if phi <= 0.0 or not math.isfinite(phi):
        S, S_phi, S_kappa = shape_point(phi, kappa)
        return S, S_phi, S_kappa, n
    if n % _RESYNC == 0:
        walk[0], walk[1], walk[2], walk[3], walk[4], walk[5] = _walk_start(phi, kappa, T)
    else:
        cos, sin = walk[0], walk[1]
        walk[0], walk[1] = cos * walk[3] - sin * walk[4], sin * walk[3] + cos * walk[4]
        walk[2] *= walk[5]
    S, S_phi, S_kappa = _shape_at(walk[0], walk[1], walk[2], phi, kappa, tail, full)
    return S, S_phi, S_kappa, n + 1


@numba.njit(**_JIT)
def _normal_single(y, lo, hi, p, sigma, A, grad):
    """Fill A = J^T W J and grad = J^T W r of one slip at p on the window y[lo:hi] (local
    sample indices x = 0, 1, ...); its cost."""
    i0, T, y0, D, kappa = p[0], p[1], p[2], p[3], p[4]
    end = i0 + T
    n = hi - lo
    _zero(A, grad)
    if not (math.isfinite(i0) and math.isfinite(end)):
        return math.nan  # (no step is taken to such a point)
    jac = np.empty(5)
    # flat at x <= i0 and at x >= end, the shape strictly between
    a = min(max(math.floor(i0) + 1, 0), n)
    b = min(max(math.ceil(end), a), n)
    cost = _flat(y, lo, 0, a, y0, sigma, A, grad, False)
    tail = math.exp(-kappa)
    full = 1.0 + tail
    past = shape_point(1.0, kappa)  # (a phi rounded up to 1 inside the slip)
    walk = np.empty(6)
    n_walked = 0
    for x in range(a, b):
        phi = (x - i0) / T
        S, S_phi, S_kappa, n_walked = _walked(phi, kappa, T, past, tail, full, walk, n_walked)
        r = y0 - D * S - y[lo + x]
        w, loss = _loss(r, sigma)
        cost += loss
        jac[0] = D * S_phi / T
        jac[1] = jac[0] * phi
        jac[2] = 1.0
        jac[3] = -S
        jac[4] = -D * S_kappa
        _accumulate(A, grad, jac, w, r)
    cost += _flat(y, lo, b, n, y0 - D, sigma, A, grad, True)
    _mirror(A)
    return cost


@numba.njit(**_JIT)
def _normal_double(y, lo, hi, p, sigma, A, grad):
    """As `_normal_single` for two slips, parameters (i0a, Ta, Da, kappa_a, gap, Tb, Db,
    kappa_b, y0)."""
    i0a, ta, da, ka, gap, tb, db, kb, base = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]
    _zero(A, grad)
    cost = 0.0
    jac = np.empty(9)
    past_a, past_b = shape_point(1.0, ka), shape_point(1.0, kb)  # (the same past each slip)
    tail_a, tail_b = math.exp(-ka), math.exp(-kb)
    full_a, full_b = 1.0 + tail_a, 1.0 + tail_b
    # each slip's walk (`_walked`): its samples inside it are consecutive
    walk_a, walk_b = np.empty(6), np.empty(6)
    na = nb = 0  # samples walked inside each slip
    for x in range(hi - lo):
        pa = (x - i0a) / ta
        pb = (x - i0a - ta - gap) / tb
        sa, sa_phi, sa_k, na = _walked(pa, ka, ta, past_a, tail_a, full_a, walk_a, na)
        sb, sb_phi, sb_k, nb = _walked(pb, kb, tb, past_b, tail_b, full_b, walk_b, nb)
        r = base - da * sa - db * sb - y[lo + x]
        w, loss = _loss(r, sigma)
        cost += loss
        ja, jb = da * sa_phi / ta, db * sb_phi / tb
        jac[0] = ja + jb
        jac[1] = ja * pa + jb
        jac[2] = -sa
        jac[3] = -da * sa_k
        jac[4] = jb
        jac[5] = jb * pb
        jac[6] = -sb
        jac[7] = -db * sb_k
        jac[8] = 1.0
        _accumulate(A, grad, jac, w, r)
    _mirror(A)
    return cost


@numba.njit(**_JIT)
def _normal(double, y, lo, hi, p, sigma, A, grad):
    if double:
        return _normal_double(y, lo, hi, p, sigma, A, grad)
    return _normal_single(y, lo, hi, p, sigma, A, grad)


@numba.njit(**_JIT)
def _solve(M, g, out):
    """out = M^-1 g by Gaussian elimination with partial pivoting (M and g overwritten);
    0 where M is singular (LAPACK's solve raises there, and the pseudo-inverse of the only
    singular damped matrix, all zeros but the held parameters' ones, gives 0 for them)."""
    k = g.size
    for c in range(k):
        pivot = c
        for i in range(c + 1, k):
            if abs(M[i, c]) > abs(M[pivot, c]):
                pivot = i
        if M[pivot, c] == 0.0:
            for i in range(k):
                out[i] = 0.0
            return
        if pivot != c:
            for j in range(k):
                M[c, j], M[pivot, j] = M[pivot, j], M[c, j]
            g[c], g[pivot] = g[pivot], g[c]
        for i in range(c + 1, k):
            f = M[i, c] / M[c, c]
            for j in range(c, k):
                M[i, j] -= f * M[c, j]
            g[i] -= f * g[c]
    for i in range(k - 1, -1, -1):
        total = g[i]
        for j in range(i + 1, k):
            total -= M[i, j] * out[j]
        out[i] = total / M[i, i]


@numba.njit(**_JIT)
def _lm_one(double, y, lo, hi, p, lower, upper, sigma, gain_tol, max_iter, A):
    """One fit on y[lo:hi] from p (overwritten with the estimate; A with J^T W J there):
    whether it converged and its cost.

    Levenberg-Marquardt on the reweighted normal equations: the step solves
    (J^T W J + lam diag) step = -J^T W r, diag the matrix's own diagonal (at least 1e-12
    of its largest entry); lam starts at 1e-3, is divided by 3 after a step that lowers
    the cost and multiplied by 4 after one that does not (the step is then not taken);
    a parameter on its bound is held there while the gradient pushes it out, and steps
    are clipped into the bounds. Converged: a step that gains less than `gain_tol` in
    chi^2 (or 1e-8 of the cost), or lam past 1e10 (no step at any damping gains)."""
    k = p.size
    grad = np.empty(k)
    A_t, grad_t = np.empty((k, k)), np.empty(k)
    M, g = np.empty((k, k)), np.empty(k)
    trial = np.empty(k)
    held = np.zeros(k, np.bool_)
    step = np.empty(k)
    cost = _normal(double, y, lo, hi, p, sigma, A, grad)
    lam = 1e-3
    done = False
    for _ in range(max_iter):
        # a parameter on its bound is held there while the gradient pushes it out
        for i in range(k):
            held[i] = (p[i] <= lower[i] and grad[i] > 0) or (p[i] >= upper[i] and grad[i] < 0)
        scale = 0.0
        for i in range(k):
            g[i] = 0.0 if held[i] else grad[i]
            for j in range(k):
                M[i, j] = 0.0 if (held[i] or held[j]) else A[i, j]
            if held[i]:
                M[i, i] = 1.0
            for j in range(k):
                scale = max(scale, abs(M[i, j]))
        for i in range(k):
            M[i, i] += lam * max(M[i, i], 1e-12 * scale)
        _solve(M, g, step)
        for i in range(k):
            trial[i] = min(max(p[i] - step[i], lower[i]), upper[i])
        cost_t = _normal(double, y, lo, hi, trial, sigma, A_t, grad_t)
        better = math.isfinite(cost_t) and cost_t < cost
        if better:
            gain = cost - cost_t
            for i in range(k):
                p[i] = trial[i]
                grad[i] = grad_t[i]
                for j in range(k):
                    A[i, j] = A_t[i, j]
            cost = cost_t
            lam = max(lam / 3.0, 1e-9)
            if gain <= max(1e-8 * cost, gain_tol):
                done = True
        else:
            lam *= 4.0
        if lam > 1e10:
            done = True
        if done:
            break
    return done, cost


@numba.njit(cache=True, **_JIT)
def _fit_windows(double, y, lo, length, p0, lower, upper, sigma, gain_tol, max_iter):
    """Fit each row of p0 on y[lo : lo + length] (local sample indices 0, 1, ...): the
    estimates, whether each converged, its cost (`_loss` units) and J^T W J there."""
    n, k = p0.shape
    p = p0.copy()
    ok = np.zeros(n, np.bool_)
    cost = np.empty(n)
    normal = np.empty((n, k, k))
    for i in range(n):
        hi = min(lo[i] + length[i], y.size)
        ok[i], cost[i] = _lm_one(double, y, lo[i], hi, p[i], lower[i], upper[i], sigma,
                                 gain_tol, max_iter, normal[i])  # fmt: skip
    return p, ok, cost, normal


def fit_windows(double, y, lo, length, p0, lower, upper, sigma, gain_tol, max_iter=100):
    """Fit each row of p0 (the single slip's five parameters, or with `double` the two
    slips' nine) on y[lo : lo + length], in local sample indices 0, 1, ... of its window,
    within [lower, upper]: the estimates, whether each converged, its cost (the soft-L1
    loss in units of sigma^2) and the covariance pinv(J^T W J) sigma^2."""
    ints = [np.ascontiguousarray(a, dtype=np.int64) for a in (lo, length)]
    floats = [np.ascontiguousarray(a, dtype=float) for a in (y, p0, lower, upper)]
    head, tail = (bool(double), floats[0]), (float(sigma), float(gain_tol), int(max_iter))
    rows = [*ints, *floats[1:]]  # (one row a fit)
    if len(p0) < _SPLIT_FROM or not _fit_windows.signatures or usable_cores() < 2:
        p, ok, cost, normal = call(_fit_windows, *head, *rows, *tail)
    else:
        # every other fit in a second thread (the kernel holds no lock): each fit is its
        # own, the same numbers whichever thread runs it
        halves = [[np.ascontiguousarray(a[i::2]) for a in rows] for i in (0, 1)]
        out = on_two_threads(lambda i: _fit_windows(*head, *halves[i], *tail), 2)
        p, ok, cost, normal = (np.empty((len(p0), *a.shape[1:]), a.dtype) for a in out[0])
        for i in (0, 1):
            for whole, part in zip((p, ok, cost, normal), out[i], strict=True):
                whole[i::2] = part
    return p, ok, cost, _pinv(normal) * sigma**2


def _pinv(A: np.ndarray) -> np.ndarray:
    """np.linalg.pinv of a stack of symmetric matrices (J^T W J), by their eigenvectors:
    the same cut (1e-15 of the largest |eigenvalue|, which are the singular values), half
    the time of the SVD's (2 ms a point of a fit)."""
    lam, V = np.linalg.eigh(A)
    keep = np.abs(lam) > 1e-15 * np.abs(lam).max(axis=-1, keepdims=True)
    inverse = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    return (V * inverse[..., None, :]) @ np.swapaxes(V, -1, -2)


# Fits at least this many are shared between two threads (`fit_windows`: a thread's start
# is ~0.1 ms; a fit takes ~0.03 ms, a two-slip one ~0.3 ms).
_SPLIT_FROM = 32
