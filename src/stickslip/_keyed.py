"""A simulated trace's samples and noise keyed by cycle, not by sample: common random
numbers through the measurement, shared by the kinds of trace (`stickslip.trace_kinds`)."""

from __future__ import annotations

import numpy as np

# The noise's own stream, far from the simulator's (which derives its keys from `seed` by
# JAX's threefry): common random numbers across parameter values, independent of the paths.
NOISE_STREAM = 0x6D656173
# ... and the sampling phases' (`keyed_grid`).
_PHASE_STREAM = 0x70686173
# Common random numbers through the measurement (`keyed_grid`, position and velocity
# traces): each cycle's sampling phase and noise are keyed by the cycle, not by the sample.
# On one uniform grid the phase at a release is the sum of all earlier periods over h, so a
# parameter step of 2 % moved every later cycle against the grid and drew it fresh noise:
# the log-likelihood jumped by 6-10 units between neighbouring points (measured, 320 cycles,
# benchmarks' measured case) against a curvature of a few units over the design's step.
# The grid is re-anchored at each cycle's release (its keyed phase) in the middle of the
# stick before it, where the trace is a straight line; a stick of fewer than this many
# sampling intervals is not cut (the extraction decides there, on a handful of samples),
# and the phase then runs on from the cycle before.
_REPHASE_INTERVALS = 10
# The noise of a sample is read from one pool of standard normals at the cycle's keyed
# offset plus the sample's index from its release (a cycle spans some 50 samples: two
# cycles of ~10^4 share a stretch of the pool, identical noise, rarely).
_NOISE_POOL = 2**20


def keyed_grid(release, slip, stick, end, h, seed, path):
    """Sampling times of one path's trace on `[0, end]` and their standard normal noise,
    both keyed by cycle: the samples of cycle c lie at `release[c] + (phase[c] + j) h`,
    `phase[c]` uniform from the cycle's key, from the middle of the stick before it to the
    middle of its own (sticks of `_REPHASE_INTERVALS` intervals or more: across shorter ones
    the grid runs on), and sample j's noise is `pool[offset[c] + j]`. Where the grid is
    re-anchored, the sample closer than `h` to the one before is dropped, so that one
    interval in such a stick is between h and 2h (`extract_cycles` takes the times as
    given; along a stick the velocity is exact whatever the interval). A cycle's phase and
    noise therefore stay the same when a parameter change moves the cycles before it."""
    n = release.size
    phase = np.random.default_rng([seed, _PHASE_STREAM, path]).random(n)
    offset = np.random.default_rng([seed, NOISE_STREAM, path, 1]).integers(0, _NOISE_POOL, n)
    anchors, starts = segments(release, slip, stick, end, h)
    stops = np.r_[starts[1:], end]
    origin = release[anchors] + phase[anchors] * h
    j0 = np.ceil((starts - origin) / h).astype(np.int64)
    j1 = np.ceil((stops - origin) / h).astype(np.int64)
    j1[-1] = np.floor((end - origin[-1]) / h).astype(np.int64) + 1  # `end` itself may be a sample
    counts = np.maximum(j1 - j0, 0)
    segment = np.repeat(np.arange(anchors.size), counts)
    first = np.cumsum(counts) - counts
    j = np.arange(segment.size) - np.repeat(first, counts) + np.repeat(j0, counts)
    grid = origin[segment] + j * h
    gap = np.diff(grid)
    keep = np.r_[True, gap >= h * (1 - 1e-9)]
    index = (offset[anchors][segment] + j) % _NOISE_POOL
    noise = noise_pool(seed)[index]
    return grid[keep], noise[keep]


def segments(release, slip, stick, end, h):
    """The stretches of a path's trace on `[0, end]` that are keyed by one cycle: `(anchors,
    starts)`, the cycle each belongs to and its start, the middle of the stick before that
    cycle (sticks of `_REPHASE_INTERVALS` intervals or more; across shorter ones the
    stretch runs on, keyed by the cycle before)."""
    stuck = release + slip
    cut = np.isfinite(stuck) & np.isfinite(stick) & (stick >= _REPHASE_INTERVALS * h)
    anchors = np.r_[0, np.flatnonzero(cut[:-1]) + 1]
    starts = np.r_[0.0, (stuck + 0.5 * stick)[anchors[1:] - 1]]
    keep = starts < end
    return anchors[keep], starts[keep]


_POOLS: dict[int, np.ndarray] = {}


def noise_pool(seed: int) -> np.ndarray:
    """`_NOISE_POOL` standard normals of `seed`'s noise stream (kept for the last few seeds:
    a fit evaluates ~100 points with one seed)."""
    if seed not in _POOLS:
        while len(_POOLS) >= 4:
            _POOLS.pop(next(iter(_POOLS)))
        rng = np.random.default_rng([seed, NOISE_STREAM, 2**32 - 1])
        _POOLS[seed] = rng.standard_normal(_NOISE_POOL)
    return _POOLS[seed]
