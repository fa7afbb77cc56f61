"""Checks shared by the trace readers: every bad value is a `ParameterError` naming it."""

from __future__ import annotations

import bisect
import math

import numpy as np

from .._errors import ParameterError

OWNER = "extract_cycles"


def as_series(name: str, value, *, required: bool = False) -> np.ndarray | None:
    """`value` as a finite 1-D float array (None stays None unless `required`)."""
    if value is None:
        if required:
            raise ParameterError(OWNER, name, "is required: give an array of sample values")
        return None
    if isinstance(value, (str, bytes)):
        raise ParameterError(OWNER, name, "must be an array of real numbers, not a string")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise ParameterError(OWNER, name, "must be an array of real numbers") from None
    if raw.dtype.kind not in "biuf":
        if raw.dtype.kind != "O":
            kind = {"U": "strings", "S": "bytes", "c": "complex numbers"}.get(
                raw.dtype.kind, f"dtype {raw.dtype}"
            )
            raise ParameterError(OWNER, name, f"must be an array of real numbers (got {kind})")
        if any(isinstance(v, (str, bytes)) for v in raw.ravel()):
            raise ParameterError(OWNER, name, "must be an array of real numbers (got strings)")
    try:
        a = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(OWNER, name, "must be an array of real numbers") from None
    if a.ndim != 1:
        raise ParameterError(OWNER, name, f"must be 1-D (got shape {a.shape})")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise ParameterError(
            OWNER, name, f"must be finite: {bad.size} NaN/inf value(s), the first at index "
            f"{bad[0]}",
        )  # fmt: skip
    return a


def check_times(t: np.ndarray, *, minimum: int = 3) -> None:
    if t.size < minimum:
        raise ParameterError(OWNER, "t", f"needs at least {minimum} samples (got {t.size})")
    step = np.diff(t)
    bad = np.flatnonzero(~(step > 0))
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            OWNER, "t", f"must be strictly increasing: t[{k + 1}] = {t[k + 1]!r} follows "
            f"t[{k}] = {t[k]!r} ({bad.size} such step(s))",
        )  # fmt: skip


def check_length(name: str, a: np.ndarray | None, n: int) -> None:
    if a is not None and a.size != n:
        raise ParameterError(OWNER, name, f"must have the length of t ({n}), got {a.size}")


def power_of_two(scale: float) -> float:
    """The power of 2 nearest above `scale` (> 0): dividing by it is exact, so a trace
    and the same trace times 2**k give the same cycles bit for bit."""
    if not scale > 0 or not np.isfinite(scale):
        return 1.0
    return float(np.ldexp(1.0, int(np.frexp(scale)[1])))


def runs(flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) indices of each run of True (run-length encoding, no Python loop)."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.diff(padded)
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1


# Arrays at least this long take `median`'s bracketed selection; shorter ones np.median.
_BRACKET_FROM = 1 << 16
_BRACKET_SAMPLE = 4096  # values drawn to bracket the middle ones
_BRACKET_HALF = 160  # sample ranks either side of the middle: ~5 sd of its rank


def median(a: np.ndarray) -> float:
    """`float(np.median(a))` of a 1-d array, the same number, 2-3x faster on the millions of
    samples of a force trace (np.median partitions a copy of the whole array; an extraction
    takes seven such medians). The middle values are bracketed by two values of a sample
    of the array, those between the brackets (~8 %) selected, and the middle ones found
    among them; where the brackets miss (rarely: they lie ~5 sd of the sample's rank from
    the middle), or the array holds a nan, np.median itself."""
    n = a.size
    if n < _BRACKET_FROM:
        return float(np.median(a))
    sample = np.sort(a[np.random.default_rng(n).integers(0, n, _BRACKET_SAMPLE)])
    mid = _BRACKET_SAMPLE // 2
    lo, hi = sample[mid - _BRACKET_HALF], sample[mid + _BRACKET_HALF - 1]
    below, above = np.count_nonzero(a < lo), np.count_nonzero(a > hi)
    between = a[(a >= lo) & (a <= hi)]  # (a nan is in none of the three: counted out)
    r0, r1 = (n - 1) // 2 - below, n // 2 - below  # the middle ranks, among `between`
    if below + between.size + above != n or r0 < 0 or r1 >= between.size:
        return float(np.median(a))
    part = np.partition(between, [r0, r1] if r1 > r0 else r0)
    return float(np.mean(part[r0 : r1 + 1]))  # (np.median's own mean of the middle values)


def weighted_median(a: np.ndarray, far=None, weight: float = 1.0) -> float:
    """`median(a)`, or with `far` (a mask of `a`) the median where each of those values
    counts `weight` (>= 1) times, the others once: the lowest value of `a[far]` at which the
    counted values up to it reach half the total (or the plain median where no value is
    far). It stands for a trace whose far samples are `weight` times as many (`_force.Cut`):
    a value of `a[far]` at a resolution of one in their number.

    The rank r of that value among `a[far]` is the smallest whose count (the near values
    up to it, plus `weight` (r + 1)) reaches half, a count that grows with r: from the
    middle rank, the next rank is the one the near values' count at the last value leaves
    (they are a minority: it moves little), or the middle of the ranks still open where
    that one is not (the guesses alone could alternate between two ranks, 20 times over on
    a fit's trace); `a[far]` is partitioned in place between the ranks already taken, so
    each selection after the first sorts only the stretch between its neighbours."""
    if far is None:
        return median(a)
    outer, inner = a[far], a[~far]
    if outer.size == 0:
        return median(a)
    half = 0.5 * (inner.size + weight * outer.size)
    taken = [-1, outer.size]  # ranks at which `outer` is partitioned, and the two ends

    def value(r: int) -> float:
        i = bisect.bisect_left(taken, r)
        if taken[i] != r:
            lo, hi = taken[i - 1] + 1, taken[i]
            outer[lo:hi].partition(r - lo)  # (in place: a view)
            taken.insert(i, r)
        return float(outer[r])

    low, high = -1, outer.size - 1  # counts below half at low (or none), reaching it at high
    r = (outer.size - 1) // 2
    while True:
        below = np.count_nonzero(inner <= value(r))
        if below + weight * (r + 1) >= half:
            high = r
        else:
            low = r
        if high - low <= 1:
            return value(high)
        r = math.ceil((half - below) / weight) - 1
        if not low < r < high:
            r = (low + high) // 2
