"""Numba-compiled kernels' first call: compiled, or loaded from the disk cache beside the
kernel's source (or in `NUMBA_CACHE_DIR`); a cache file that cannot be read (truncated by
a full disk, written by another version) is emptied and the kernel compiled again, with a
warning, never an error."""

from __future__ import annotations

import warnings


def call(kernel, *args):
    """`kernel(*args)` for a `numba.njit(cache=True)` dispatcher."""
    if not kernel.signatures:  # the first call in this process
        import numba

        try:
            kernel.compile(tuple(numba.typeof(a) for a in args))
        except Exception as error:  # loading a damaged cache file raised
            cache = getattr(kernel, "_cache", None)
            if cache is None or kernel.signatures:
                raise
            warnings.warn(f"{kernel.__name__}: its compiled code cached on disk could not be "
                          f"read ({type(error).__name__}: {error}); compiling it again",
                          RuntimeWarning, stacklevel=3)  # fmt: skip
            cache.flush()
    return kernel(*args)
