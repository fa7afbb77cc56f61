"""The host scheduler's buffer ladder: the sizes a chunk's paths are stepped in (each size
one compilation), the sizes that stand in for others, padding and repacking."""

from __future__ import annotations

import numpy as np

from .. import _compile

MIN_BUFFER = 128  # smallest buffer; below it a step costs the same whatever the size


# Buffer sizes: powers of two from FINE_BUFFER up, where a step's cost follows the size; below
# it, where fixed costs dominate a step, only MIN_BUFFER * 8**k (128, 1024): each size is a
# compilation of the loop (about 1.5 s cold on 2 cores), a few extra steps at a larger size
# cost milliseconds (measured per step: 48 us at 128, 228 us at 1024, 495 us at 4096).
FINE_BUFFER = 8192


DEFAULT_CHUNK = 2**20  # about 100 bytes of state per path: 100 MB


def repack(a, keep, pad, value):
    """The columns `keep` of `a`, followed by `pad` columns of `value` (gathered straight
    into the new array: one copy)."""
    out = np.empty(a.shape[:-1] + (keep.size + pad,), a.dtype)
    np.take(a, keep, axis=-1, out=out[..., : keep.size], mode="clip")
    out[..., keep.size :] = value
    return out


def cols(a, idx):
    """`a[..., idx]` for an index array or a slice `idx` (`np.take`: 5x faster than fancy
    indexing of the columns of a `(d, n)` state)."""
    return a[..., idx] if isinstance(idx, slice) else np.take(a, idx, axis=-1)


def set_cols(a, idx, values):
    """`a[:, idx] = values` for a `(d, n)` state, row by row (1.3x faster)."""
    for row, v in zip(a, values, strict=True):
        row[idx] = v


def next_pow2(n: int) -> int:
    return 1 << max(0, (int(n) - 1).bit_length())


def buffer_size(n: int) -> int:
    """The smallest buffer size (see `FINE_BUFFER`) that holds `n` paths."""
    size = max(MIN_BUFFER, next_pow2(n))
    if size < FINE_BUFFER:
        size = MIN_BUFFER
        while size < n:
            size *= 8
    return size


def padded_size(n: int) -> int:
    """The size that per-path helper calls (onset states, stick times) of `n` paths run on:
    the buffer size that holds them (up to a chunk; above it, whole chunks), so that runs of
    any number of paths share the executables of a few sizes (each new size was a
    compilation of ~0.3 s on a cold cache, or a load from disk)."""
    return buffer_size(n) if n <= DEFAULT_CHUNK else -(-n // DEFAULT_CHUNK) * DEFAULT_CHUNK


def pad_paths(x, size: int):
    """`x` with its last axis (paths) padded to `size` by repeating its first path."""
    n = x.shape[-1]
    if n == size:
        return x
    if n == 0:
        return np.zeros(x.shape[:-1] + (size,), x.dtype)
    return np.concatenate([x, np.repeat(x[..., :1], size - n, axis=-1)], axis=-1)


def stand_in(shape, dtype=np.float64):
    """A read-only array of zeros of this shape (no memory: a stand-in argument whose shape
    and dtype are all a compiled call's key looks at)."""
    return np.broadcast_to(np.zeros((), dtype), shape)


def stand_in_size(ready, want: int, most: int, smaller: bool = False, ladder=None):
    """The size that stands in for `want` (`_compile.STAND_IN`) among those for which
    `ready(size)` is true: the smallest above it, up to `STAND_IN` times it or `most`
    (padded); with `smaller`, else the largest down to `1 / STAND_IN` of it (in more calls);
    `None` if none. `ladder`: the caller's sizes, as the functions `(larger, smaller)` of
    a size (default: the buffer sizes, `larger_buffer` and `smaller_buffer`)."""
    larger, lower = ladder or (larger_buffer, smaller_buffer)
    size, top = want, min(_compile.STAND_IN * want, most)
    while size < top:
        size = min(larger(size), top)
        if ready(size):
            return size
    size = lower(want) if smaller else 0
    while size and size * _compile.STAND_IN >= want:
        if ready(size):
            return size
        size = lower(size)
    return None


def larger_buffer(size: int) -> int:
    """The next buffer size above `size` (see `smaller_buffer`)."""
    return size * 2 if size >= FINE_BUFFER else size * 8


def smaller_buffer(size: int) -> int:
    """The next buffer size below `size` (0 below the smallest)."""
    if size <= MIN_BUFFER:
        return 0
    return size // 2 if size > FINE_BUFFER else max(MIN_BUFFER, size // 8)
