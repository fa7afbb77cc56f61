"""The running median of an odd number of samples, edges padded by the nearest sample:
`scipy.ndimage.median_filter(y, size, mode="nearest")`'s values, compiled (Numba, cached
on disk: `_jit`) and without Python's lock held.

Why not SciPy's: its rank filter holds the interpreter's lock (two threads each
despiking a trace of a fit's point took as long as one after the other) and sorts each
window afresh; here the window is kept sorted as it slides, one sample leaving and one
entering (a shift of at most `size` values a sample).
"""

from __future__ import annotations

import numba
import numpy as np

from ._jit import call


@numba.njit(cache=True, nogil=True)
def _running_median(y, size):
    n = y.size
    half = size // 2
    out = np.empty(n)
    window = np.empty(size)
    for j in range(size):  # the first window: y[0] for the indices before 0
        window[j] = y[min(max(j - half, 0), n - 1)]
    window.sort()
    out[0] = window[half]
    for i in range(1, n):
        leaving = y[min(max(i - 1 - half, 0), n - 1)]
        entering = y[min(i + half, n - 1)]
        j = 0
        while window[j] != leaving:  # (present: it entered `size` samples ago)
            j += 1
        # the entering value takes the leaving one's place, then moves to its rank
        while j > 0 and window[j - 1] > entering:
            window[j] = window[j - 1]
            j -= 1
        while j < size - 1 and window[j + 1] < entering:
            window[j] = window[j + 1]
            j += 1
        window[j] = entering
        out[i] = window[half]
    return out


def running_median(y: np.ndarray, size: int) -> np.ndarray:
    """The median of the `size` (odd) samples centred on each of `y`'s (finite values,
    1-D), the edges padded by repeating the first and last sample; SciPy's filter where
    `y` holds a value that is not finite (no order to keep there)."""
    y = np.ascontiguousarray(y, dtype=float)
    if size % 2 != 1 or size < 1:
        raise ValueError(f"running_median: size must be odd and positive (got {size})")
    if y.size == 0 or not np.all(np.isfinite(y)):
        from scipy.ndimage import median_filter

        return median_filter(y, size=size, mode="nearest")
    return call(_running_median, y, int(size))
