"""The recorded slips laid out as time series (`cycles._traces`), compiled (Numba): each
recording solve's states copied straight to their rows, where numpy joined the solves,
gathered every row's states with a mixed fancy index and scattered them again (6 ms of a
fit's point of ~110 ms)."""

from __future__ import annotations

import numba
import numpy as np

from .._extract._jit import call


@numba.njit(cache=True, nogil=True)
def _place(ys, first, rows, steps, at, states):
    """The states after steps first + 1 .. first + len(ys) (`ys[i, :, j]`, slot j holding
    row rows[j]) into `states[at[row] + step]`, for the steps each row has."""
    length, d, _ = ys.shape
    for j in range(rows.size):
        r = rows[j]
        last = min(steps[r], first + length)
        for k in range(first + 1, last + 1):
            for q in range(d):
                states[at[r] + k, q] = ys[k - first - 1, q, j]


def place(ys, first: int, rows, steps, at, states) -> None:
    """`_place` (the arrays made contiguous and of the kernel's types)."""
    call(_place, np.ascontiguousarray(ys, float), int(first),
         *(np.ascontiguousarray(x, np.int64) for x in (rows, steps, at)), states)  # fmt: skip
