"""The passes of `measurement._gapped_filtfilt`, compiled (Numba): an IIR filter run
forwards and then backwards over the kept stretches of a trace, the gaps between them in
closed form in the eigenbasis of the filter's state-space matrix. One call per trace in
place of two `lfilter` calls and some small matrix products per stretch."""

from __future__ import annotations

import numba
import numpy as np

from .._extract._jit import call


@numba.njit(nogil=True)
def _lfilter(b, a, x, lo, hi, y, z, backwards):
    """scipy's `lfilter(b, a, x[lo:hi], zi=z)` (transposed direct form II, a[0] = 1) into
    y[lo:hi], z carried out; with `backwards`, of x[lo:hi] reversed, written back in place
    (y[hi - 1] first)."""
    order = a.size - 1
    for m in range(hi - lo):
        n = hi - 1 - m if backwards else lo + m
        xn = x[n]
        yn = b[0] * xn + z[0]
        for i in range(order - 1):
            z[i] = b[i + 1] * xn + z[i + 1] - a[i + 1] * yn
        z[order - 1] = b[order] * xn - a[order] * yn
        y[n] = yn


@numba.njit(nogil=True)
def _free(V, Vi, lam, G, d, out):
    """out = Re(V diag(lam^G) Vi d): the state's distance d from the steady state after G
    samples of free decay."""
    k = d.size
    w = np.empty(k, np.complex128)
    for i in range(k):
        s = 0j
        for j in range(k):
            s += Vi[i, j] * d[j]
        w[i] = lam[i] ** G * s
    for i in range(k):
        s = 0j
        for j in range(k):
            s += V[i, j] * w[j]
        out[i] = s.real


@numba.njit(cache=True, nogil=True)
def _passes(b, a, values, starts, gaps, unit, lam, V, Vi, K):
    n, k, count = values.size, unit.size, starts.size
    bounds = np.empty(count + 1, np.int64)
    bounds[:count] = starts
    bounds[count] = n
    y = np.empty(n)
    z = unit * values[0]
    level = np.empty(count)
    entering = np.empty((count, k))
    decayed = np.empty(k)
    for p in range(count):
        lo, hi = bounds[p], bounds[p + 1]
        c = values[lo - 1] if p else values[0]
        level[p] = c
        for i in range(k):
            entering[p, i] = z[i] - unit[i] * c
        _free(V, Vi, lam, gaps[p], entering[p], decayed)
        for i in range(k):
            z[i] = unit[i] * c + decayed[i]
        _lfilter(b, a, values, lo, hi, y, z, False)
    out = np.empty(n)
    z = unit * y[n - 1]
    u = np.empty(k, np.complex128)
    w = np.empty(k, np.complex128)
    for p in range(count - 1, -1, -1):
        lo, hi = bounds[p], bounds[p + 1]
        _lfilter(b, a, y, lo, hi, out, z, True)
        c, G = level[p], gaps[p]
        for i in range(k):
            z[i] -= unit[i] * c
        _free(V, Vi, lam, G, z, decayed)
        # the backward pass through the forward pass's free ringing, e0 M^m d over the
        # gap: sum_m M^m B e0 M^m d, a geometric sum per pair of eigenvalues
        for i in range(k):
            s = 0j
            for j in range(k):
                s += Vi[i, j] * entering[p, j]
            u[i] = s
        for i in range(k):
            s = 0j
            for j in range(k):
                pair = lam[i] * lam[j]
                ring = (1 - pair**G) / (1 - pair) if abs(1 - pair) > 0 else complex(G)
                s += K[i, j] * u[j] * ring
            w[i] = s
        for i in range(k):
            s = 0j
            for j in range(k):
                s += V[i, j] * w[j]
            z[i] = unit[i] * c + decayed[i] + s.real
    return out


def passes(b, a, values, starts, gaps, unit, lam, V, Vi, K):
    """The gapped forward-backward filter's output (see `measurement._gapped_filtfilt`)."""
    real = [np.ascontiguousarray(x, float) for x in (b, a, values)]
    index = [np.ascontiguousarray(x, np.int64) for x in (starts, gaps)]
    basis = [np.ascontiguousarray(x, complex) for x in (lam, V, Vi, K)]
    return call(_passes, *real, *index, np.ascontiguousarray(unit, float), *basis)
