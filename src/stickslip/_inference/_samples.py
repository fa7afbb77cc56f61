"""The forward measurement's per-sample work, compiled (Numba), one pass over a trace's
samples where numpy took several: the keyed uniforms (`measurement._hashed`: splitmix64
of each sample's key, ten numpy passes and 6 ms a fit's point) and the cut grid's far
samples (`measurement.cut_grid`: a binary search and a dozen temporaries a sample)."""

from __future__ import annotations

import numba
import numpy as np

from .._extract._jit import call

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)  # splitmix64's increment
_M1, _M2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)


@numba.njit(nogil=True)
def _mix(z):
    """splitmix64's finaliser (products wrap around: modulo 2**64)."""
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@numba.njit(cache=True, nogil=True)
def _uniforms(head, cycle, offset):
    """Per sample, the uniform on (0, 1) from the top 53 bits of
    mix(mix(head + cycle * golden) + offset * golden) (`cycle`, `offset`: the keys' bits)."""
    out = np.empty(cycle.size)
    for i in range(cycle.size):
        key = _mix(head + cycle[i] * _GOLDEN)
        bits = _mix(key + offset[i] * _GOLDEN)
        out[i] = (float(bits >> _S11) + 0.5) * 2.0**-53
    return out


def uniforms(head: int, cycle: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """`_uniforms` of integer arrays (a negative offset wraps modulo 2**64, as numpy's
    cast to uint64 does)."""
    keys = [np.ascontiguousarray(x, np.int64).view(np.uint64) for x in (cycle, offset)]
    return call(_uniforms, np.uint64(head), *keys)


@numba.njit(cache=True, nogil=True)
def _far(index, release, stick, reach):
    """Whether each kept sample (`index`, increasing) lies further than `reach` from every
    slip [release, stick] (in samples; the releases increasing)."""
    out = np.empty(index.size, np.bool_)
    j = -1  # the last slip released at or before the sample
    n = release.size
    for i in range(index.size):
        x = index[i]
        while j + 1 < n and release[j + 1] <= x:
            j += 1
        distance = np.inf
        if j >= 0:
            if x <= stick[j]:
                distance = 0.0
            else:
                distance = x - stick[j]
        if j + 1 < n:
            distance = min(distance, release[j + 1] - x)
        out[i] = distance > reach
    return out


def far_samples(index, release, stick, reach: float) -> np.ndarray:
    """`_far` of a cut grid's kept samples."""
    floats = [np.ascontiguousarray(x, float) for x in (release, stick)]
    return call(_far, np.ascontiguousarray(index, np.int64), *floats, float(reach))
